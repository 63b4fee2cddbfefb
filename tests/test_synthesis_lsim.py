"""Against a continuous-time state-space simulation with linear input interpolation
(scipy.signal.lsim): relative error <= 1e-6, coupled contact damping, contact switches."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensors.modal.contact import Contact
from sensors.modal.damping import modal_damping_matrix
from sensors.synthesis.modal_system import ModalSystem, modal_response
from synthesis_fakes import BoxModel, box_points, grasp, lsim_reference

FS = 44100


def rel_err(y, ref):
    return np.max(np.abs(y - ref)) / np.max(np.abs(ref))


@pytest.fixture(scope="module")
def box():
    m = BoxModel(np.linspace(700, 15000, 16), "wood", seed=4)
    dp, dn, mp, mn = grasp(m)
    cs = [Contact(dp, dn, 40.0, 0.5), Contact(mp, mn, 40.0, 0.8),
          Contact([0.1, 0.0, 0.003], [1, 0, 0], 8.0, 1.2), Contact([-0.03, 0.0, -0.01], [0, 0, -1], 2.0, 0.1)]
    return m, (dp, dn, mp, mn), cs


@pytest.mark.parametrize("output", ["displacement", "velocity", "acceleration"])
def test_exact_matches_lsim(box, output):
    m, g, cs = box
    u = np.random.default_rng(0).normal(size=3000)
    u[0] = 0.7  # nonzero first sample exercises the start-up term
    y = modal_response(m, u, FS, *g, cs, output=output)
    ref, _ = lsim_reference(m, modal_damping_matrix(m, cs), u, FS, *g, output=output)
    assert rel_err(y, ref) <= 1e-6


def test_diagonal_matches_lsim_of_diagonal_damping(box):
    m, g, cs = box
    u = np.random.default_rng(1).normal(size=3000)
    y = modal_response(m, u, FS, *g, cs, method="diagonal")
    C = modal_damping_matrix(m, cs)
    ref_d, _ = lsim_reference(m, np.diag(np.diag(C)), u, FS, *g)
    ref_x, _ = lsim_reference(m, C, u, FS, *g)
    assert rel_err(y, ref_d) <= 1e-6
    assert rel_err(y, ref_x) > 1e-5  # coupling neglected: measurably different


def test_zoh_matches_lsim_zoh(box):
    m, g, cs = box
    u = np.random.default_rng(2).normal(size=2000)
    y = modal_response(m, u, FS, *g, cs, hold="zoh")
    ref, _ = lsim_reference(m, modal_damping_matrix(m, cs), u, FS, *g, interp=False)
    assert rel_err(y, ref) <= 1e-6


def test_contact_switches_carry_state(box):
    m, g, cs = box
    u = np.random.default_rng(3).normal(size=4000)
    sched = [(0.0, cs), (0.021, cs[:2]), (0.05, []), (0.07, cs[1:])]
    y = modal_response(m, u, FS, *g, sched)
    starts = [int(round(t * FS)) for t, _ in sched] + [len(u)]
    ref = np.zeros(len(u))
    x = None
    for i, (_, c) in enumerate(sched):
        s, e = starts[i], starts[i + 1]
        ee = min(e + 1, len(u))
        yy, xx = lsim_reference(m, modal_damping_matrix(m, c), u[s:ee], FS, *g, x0=x)
        ref[s:e] = yy[: e - s]
        x = xx[-1]
    assert rel_err(y, ref) <= 1e-6
    # the state really matters: restarting from rest at each switch is visibly different
    fresh = np.concatenate([modal_response(m, u[s:e], FS, *g, c)
                            for (_, c), s, e in zip(sched, starts, starts[1:])])
    assert rel_err(fresh, ref) > 1e-2


def test_ill_conditioned_falls_back_and_stays_exact(box):
    """Two modes at critical damping with identical frequency: defective eigenvalues."""
    m, g, cs = box
    w = m.angular_frequencies_rad_s
    C = modal_damping_matrix(m, cs)
    C[0, 0] = 2 * w[0]
    C[0, 1:] = C[1:, 0] = 0.0
    sysm = ModalSystem.build(m, FS, *g, damping=C)
    assert "dense" in sysm.methods_used
    u = np.random.default_rng(4).normal(size=2000)
    ref, _ = lsim_reference(m, C, u, FS, *g)
    assert rel_err(sysm.response(u), ref) <= 1e-6


def _bar_model():
    sensors = pytest.importorskip("sensors")
    if not hasattr(sensors, "ModalModel"):
        try:
            from sensors.modal.model import ModalModel
        except ImportError:
            pytest.skip("sensors.ModalModel not available yet")
        return ModalModel
    return sensors.ModalModel


@pytest.mark.parametrize("material", ["aluminium", "wood"])
def test_real_bar_with_contacts_matches_lsim(material):
    """The FEM bar (P2 tets): 200 x 20 x 20 mm, all modes up to Nyquist, antipodal grasp at
    x = 40 mm with 40 N fingers plus five table contacts under the bar."""
    ModalModel = _bar_model()
    model = ModalModel.bar(0.2, 0.02, 0.02, material, cache=False, progress=False)
    h = 0.01
    dp, dn = np.array([0.04, h, 0.0]), np.array([0.0, 1.0, 0.0])
    mp, mn = np.array([0.04, -h, 0.0]), np.array([0.0, -1.0, 0.0])
    cs = [Contact(dp, dn, 40.0, 0.8), Contact(mp, mn, 40.0, 0.8)]
    cs += [Contact([x, 0.0, -h], [0, 0, -1], 1.5, 0.4) for x in np.linspace(-0.09, 0.09, 5)]
    C = modal_damping_matrix(model, cs)
    assert np.abs(C - np.diag(np.diag(C))).max() > 1e-3 * np.abs(np.diag(C)).max()  # really coupled
    rng = np.random.default_rng(5)
    u = rng.normal(size=4410)
    u[0] = 0.3
    keep = model.frequencies_hz < FS / 2
    assert keep.sum() >= 10
    for output in ("displacement", "acceleration"):
        # the paper's damping-only contacts: the reference is C on the free modes (springs:
        # tests/test_contact_stiffness.py)
        y = modal_response(model, u, FS, dp, dn, mp, mn, cs, output=output, contact_model="damping")
        sub = _Sub(model, keep)
        ref, _ = lsim_reference(sub, C[np.ix_(keep, keep)], u, FS, dp, dn, mp, mn, output=output)
        assert rel_err(y, ref) <= 1e-6
    # contact switch on the real bar: lifted off the table half way
    sched = [(0.0, cs), (0.05, cs[:2])]
    y = modal_response(model, u, FS, dp, dn, mp, mn, sched, contact_model="damping")
    n1 = int(round(0.05 * FS))
    sub = _Sub(model, keep)
    y1, x1 = lsim_reference(sub, C[np.ix_(keep, keep)], u[: n1 + 1], FS, dp, dn, mp, mn)
    C2 = modal_damping_matrix(model, cs[:2])[np.ix_(keep, keep)]
    y2, _ = lsim_reference(sub, C2, u[n1:], FS, dp, dn, mp, mn, x0=x1[-1])
    assert rel_err(y, np.concatenate([y1[:n1], y2])) <= 1e-6


class _Sub:
    """The modes of ``model`` below Nyquist (what the synthesis keeps by default)."""

    def __init__(self, model, keep):
        self.m, self.keep = model, keep
        self.angular_frequencies_rad_s = model.angular_frequencies_rad_s[keep]

    def mode_shapes_at(self, p):
        return self.m.mode_shapes_at(p)[..., self.keep]


@settings(max_examples=10, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**31 - 1), n_switch=st.integers(1, 5),
       method=st.sampled_from(["exact", "diagonal"]), output=st.sampled_from(["displacement", "velocity"]))
def test_random_contact_schedules_match_piecewise_lsim(seed, n_switch, method, output):
    rng = np.random.default_rng(seed)
    m = BoxModel(np.sort(rng.uniform(500, 15000, 8)), "abs", seed=seed)
    g = grasp(m)
    n = 2500
    starts = np.concatenate([[0], np.sort(rng.choice(np.arange(50, n - 50), n_switch, replace=False))])
    sets = []
    for _ in starts:
        pts, nrm = box_points(m, int(rng.integers(0, 6)), rng)
        sets.append([Contact(p, q, rng.uniform(0, 200), rng.uniform(0, 1.5)) for p, q in zip(pts, nrm)])
    u = rng.normal(size=n)
    y = modal_response(m, u, FS, *g, [(s / FS, c) for s, c in zip(starts, sets)], method=method, output=output)
    bounds = list(starts) + [n]
    ref = np.zeros(n)
    x = None
    for i, c in enumerate(sets):
        s, e = bounds[i], bounds[i + 1]
        C = modal_damping_matrix(m, c)
        if method == "diagonal":
            C = np.diag(np.diag(C))
        yy, xx = lsim_reference(m, C, u[s:min(e + 1, n)], FS, *g, output=output, x0=x)
        ref[s:e] = yy[: e - s]
        x = xx[-1]
    assert rel_err(y, ref) <= 1e-6
