"""The springs of a contact set in the coupled modes (``sensors.modal.spring_modes``):
the stiffness as one product (``ONE_PRODUCT_STIFFNESS``) against the per-spring sum (eigenvalues
within 1e-13 of the largest: what a symmetric eigen-solve guarantees), and the
vectorized pre-pass of ``merge_close_springs`` (``VECTORIZED_MERGE``) against testing every
pair, with hand-made merges as the independent reference."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from sensors._infra.lru import clear_all

from sensors import Contact, ModalModel
from sensors.modal.spring_modes import merge_close_springs, spring_modes

import sensors.modal.spring_modes  # noqa: F401  (the module, not the function sensors.modal exports)

spring_module = sys.modules["sensors.modal.spring_modes"]
BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


def test_one_product_stiffness_matches_the_per_spring_sum(bar, monkeypatch):
    h = 0.0125
    contacts = [Contact([0.02, h, 0.0], [0, 1.0, 0], 8.0, 0.6), Contact([0.02, -h, 0.0], [0, -1.0, 0], 8.0, 0.6),
                Contact([-0.09, 0.0, -h], [0, 0, -1.0], 1.0, 0.0),           # normal spring only
                Contact([0.07, 0.012, 0.0], [0, 0.6, 0.8], 2.0, 0.3, normal_stiffness_n_per_m=1e7)]
    freqs = {}
    for flag in (False, True):
        monkeypatch.setattr(spring_module, "ONE_PRODUCT_STIFFNESS", flag)
        clear_all()
        modes = spring_modes(bar, contacts)
        freqs[flag] = modes.frequencies_hz
    # independent: the free Ritz stiffness plus each spring's W = k_n n n^T + k_t (I - n n^T)
    S = modes.ritz_at(np.array([p for p, _, _, _ in modes.springs]))
    K = modes.free_stiffness.copy()
    for (p, n, kn, kt), Sp in zip(modes.springs, S):
        W = kn * np.outer(n, n) + kt * (np.eye(3) - np.outer(n, n))
        K += np.einsum("ia,ij,jb->ab", Sp, W, Sp)
    lam = np.linalg.eigvalsh(0.5 * (K + K.T))
    ref = np.sqrt(lam[lam > (2 * np.pi) ** 2]) / (2 * np.pi)
    assert freqs[True].shape == freqs[False].shape == ref.shape
    # a symmetric eigen-solve is accurate to rounding of the largest eigenvalue (the stiff
    # springs' local modes), not of each: compare eigenvalues against that scale
    lam_fast, lam_ref = (2 * np.pi * freqs[True]) ** 2, (2 * np.pi * freqs[False]) ** 2
    scale = 1e-13 * lam_ref.max()
    assert np.abs(lam_fast - lam_ref).max() <= scale
    assert np.abs(lam_fast - (2 * np.pi * ref) ** 2).max() <= scale


def springs_near_the_limits(rng, n):
    """Clusters of springs with distances and normal angles on both sides of the merge limits
    (2 mm, cos = 0.9), some exactly at 2 mm."""
    out = []
    for _ in range(n):
        c = rng.uniform(-0.05, 0.05, 3)
        n0 = rng.normal(size=3)
        n0 /= np.linalg.norm(n0)
        for _ in range(rng.integers(1, 5)):
            d = rng.normal(size=3)
            d *= rng.choice([0.5e-3, 1.99e-3, 2e-3, 2.01e-3, 5e-3]) / np.linalg.norm(d)
            t = np.cross(n0, rng.normal(size=3))
            t /= np.linalg.norm(t)
            ang = rng.choice([0.1, np.arccos(0.9), 0.46, 1.0])
            m = np.cos(ang) * n0 + np.sin(ang) * t
            out.append((c + d, m / np.linalg.norm(m), float(rng.uniform(1e4, 1e7)), float(rng.uniform(0, 1e7))))
    return out


@pytest.mark.parametrize("seed", range(6))
def test_vectorized_merge_gives_the_same_groups(monkeypatch, seed):
    springs = springs_near_the_limits(np.random.default_rng(seed), 12)
    out = {}
    for flag in (False, True):
        monkeypatch.setattr(spring_module, "VECTORIZED_MERGE", flag)
        out[flag] = merge_close_springs(springs)
    assert len(out[True]) == len(out[False]) < len(springs)
    for a, b in zip(out[True], out[False]):
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2:] == b[2:]


@pytest.mark.parametrize("flag", [False, True])
def test_merge_by_hand(monkeypatch, flag):
    monkeypatch.setattr(spring_module, "VECTORIZED_MERGE", flag)
    z = np.array([0.0, 0.0, 1.0])
    tilted = np.array([0.0, np.sin(0.5), np.cos(0.5)])                 # cos 0.878 < 0.9: apart
    springs = [(np.array([0.0, 0.0, 0.0]), z, 1e6, 0.0),
               (np.array([0.0015, 0.0, 0.0]), z, 3e6, 0.0),             # 1.5 mm, same normal: merged
               (np.array([0.0, 0.001, 0.0]), tilted, 1e6, 0.0),
               (np.array([0.0025, 0.0, 0.0]), z, 1e6, 0.0)]             # 2.5 mm from the first: apart
    merged = merge_close_springs(springs)
    assert len(merged) == 3
    p, n, kn, kt = merged[0]
    assert np.allclose(p, [0.0015 * 3 / 4, 0.0, 0.0], rtol=0, atol=1e-15) and np.array_equal(n, z)
    assert (kn, kt) == (4e6, 0.0)
    assert merged[1][1] is tilted and np.array_equal(merged[2][0], [0.0025, 0.0, 0.0])
