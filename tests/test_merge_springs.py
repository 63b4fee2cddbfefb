"""merge_close_springs' fast path (FAST_MERGE: pairs settled by vectorized bounds, the lean
weighted mean) gives the reference's groups and bits."""

import numpy as np
import pytest

import importlib

sm = importlib.import_module("sensors.modal.spring_modes")


def _merge(springs, fast: bool, radius_m=sm.MERGE_RADIUS_M):
    saved = sm.FAST_MERGE
    sm.FAST_MERGE = fast
    try:
        return sm.merge_close_springs(springs, radius_m)
    finally:
        sm.FAST_MERGE = saved


def _unit(v):
    return v / np.linalg.norm(v)


def _springs(rng, n, spread_m, boundary=False):
    """n springs in a few patches; ``boundary``: partners placed at the merge radius and at a
    normal dot of 0.9 to rounding, where the bounds cannot decide and the exact test must."""
    out = []
    centres = rng.normal(size=(max(1, n // 5), 3)) * 0.03
    for i in range(n):
        c = centres[i % len(centres)]
        p = c + rng.normal(size=3) * spread_m
        nrm = _unit(np.array([0.0, 0.0, 1.0]) + rng.normal(size=3) * 0.2)
        if boundary and out and i % 2:
            q, m = out[-1][0], out[-1][1]
            d = _unit(rng.normal(size=3))
            p = q + d * sm.MERGE_RADIUS_M * (1 + rng.choice([-1, 0, 1]) * 1e-15)
            t = _unit(np.cross(m, _unit(rng.normal(size=3))))
            nrm = _unit(0.9 * m + np.sqrt(1 - 0.81) * t) if rng.random() < 0.5 else m
        kn = float(rng.uniform(1e5, 1e7))
        kt = float(rng.uniform(0, 1e7)) if rng.random() < 0.8 else 0.0
        out.append((p, nrm, kn, kt))
    return out


def _same(a, b):
    assert len(a) == len(b)
    for (p, n, kn, kt), (q, m, ln, lt) in zip(a, b):
        assert np.asarray(p).tobytes() == np.asarray(q).tobytes()
        assert np.asarray(n).tobytes() == np.asarray(m).tobytes()
        assert kn == ln and kt == lt


@pytest.mark.parametrize("seed", range(6))
def test_fast_merge_equals_the_reference(seed):
    rng = np.random.default_rng(seed)
    merged_any = 0
    for n, spread in [(2, 1e-3), (6, 1e-3), (20, 2e-3), (25, 1e-3), (40, 5e-4), (30, 1e-2)]:
        springs = _springs(rng, n, spread, boundary=bool(seed % 2))
        fast, ref = _merge(springs, True), _merge(springs, False)
        _same(fast, ref)
        merged_any += len(ref) < len(springs)
    assert merged_any     # groups of several springs were merged (the lean mean ran)


def test_one_large_group_and_the_radius_doubling():
    rng = np.random.default_rng(11)
    # 30 springs within 1 mm and facing alike: one group of 30 (the lean mean over many rows)
    c = np.array([0.01, 0.02, 0.0])
    springs = [(c + rng.normal(size=3) * 2e-4, _unit(np.array([0, 0, 1.0]) + rng.normal(size=3) * 0.01),
                float(rng.uniform(1e5, 1e6)), float(rng.uniform(1e5, 1e6))) for _ in range(30)]
    _same(_merge(springs, True), _merge(springs, False))
    assert len(_merge(springs, False)) < 5
    # 25 scattered springs with tangential stiffness: 75 directions, above the limit: radius doubled
    springs = _springs(rng, 25, 6e-3)
    springs = [(p, n, kn, max(kt, 1e5)) for p, n, kn, kt in springs]
    _same(_merge(springs, True), _merge(springs, False))


def test_boundary_pairs_need_the_exact_test(monkeypatch):
    """Pairs at the radius to rounding are in the bounds' margin: with the exact test removed the
    fast path would decide some of them otherwise (this test fails then)."""
    rng = np.random.default_rng(3)
    springs = _springs(rng, 40, 1e-3, boundary=True)
    ref = _merge(springs, False)
    _same(_merge(springs, True), ref)
    maybe, surely = sm._pair_bounds(springs, sm.MERGE_RADIUS_M)
    assert (maybe & ~surely).any()             # some pairs are left to the exact test
    monkeypatch.setattr(sm, "_exact_close", lambda a, b, r: True)
    with pytest.raises(AssertionError):
        _same(_merge(springs, True), ref)
