"""The low-rank complex-mode path against LAPACK's dense eigen-decomposition of the same
state matrix (an independent solver), on FEM models with repeated mode pairs."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from sensors import MATERIALS, Contact, ModalModel
from sensors.low_rank_modes import low_rank_modes


def _state_matrix(w, d, Q):
    r = w.size
    A = np.zeros((2 * r, 2 * r))
    A[:r, r:] = np.diag(w)
    A[r:, :r] = -np.diag(w)
    A[r:, r:] = -(np.diag(d) + Q.T @ Q)
    return A


def _factor(model, contacts):
    """Q with gamma G = Q^T Q, written out from the definition of G (Zheng & James 2011)."""
    rows = []
    for c in contacts:
        U = model.mode_shapes_at([c.position_m])[0]              # (3, r)
        n = np.asarray(c.normal, float)
        rows.append(np.sqrt(c.force_n * c.friction) * U)
        rows.append(np.sqrt(c.force_n * (1 - c.friction)) * (n @ U)[None])
    return np.sqrt(model.material.gamma) * np.vstack(rows)


def _check_against_dense(w, d, Q):
    out = low_rank_modes(w, d, Q)
    assert out is not None
    lam, V, W = out
    A = _state_matrix(w, d, Q)
    ref = sla.eigvals(A)
    ref = ref[ref.imag > 0]
    assert lam.size == ref.size == w.size
    # every dense eigenvalue found, none twice: match one to one
    err = np.abs(np.sort_complex(lam)[:, None] - np.sort_complex(ref)[None, :]).min(axis=1)
    assert np.all(err <= 1e-11 * np.abs(lam))
    dist = np.abs(lam[:, None] - ref[None, :])
    assert len(set(dist.argmin(axis=1).tolist())) == lam.size
    assert np.linalg.norm(A @ V - V * lam) <= 1e-11 * np.linalg.norm(A)
    np.testing.assert_allclose(W @ V, np.eye(lam.size), atol=1e-9)


@pytest.mark.parametrize("material", ["abs", "aluminium", "steel", "wood"])
def test_bar_grasp_with_table_contacts_matches_dense(material):
    model = ModalModel.bar(0.2, 0.02, 0.02, MATERIALS[material], progress=False)
    contacts = [Contact([0.03, 0.01, 0.0], [0, 1, 0], 40.0, 0.8), Contact([0.03, -0.01, 0.0], [0, -1, 0], 40.0, 0.8),
                Contact([0.09, 0.0, -0.01], [0, 0, -1], 1.5, 0.5), Contact([-0.09, 0.005, -0.01], [0, 0, -1], 1.5, 0.5)]
    w = model.angular_frequencies_rad_s
    m = model.material
    _check_against_dense(w, m.alpha + m.beta * w**2, _factor(model, contacts))


def test_tube_repeated_pairs_match_dense():
    """A tube's modes come in near-degenerate pairs that the contacts split: the hard case for
    any root finder started from the undamped modes."""
    model = ModalModel.tube(0.2, 0.0125, 0.0105, MATERIALS["aluminium"], progress=False)
    w = model.angular_frequencies_rad_s
    ro = 0.0125
    contacts = [Contact([0.0, 0.0, ro], [0, 0, 1], 40.0, 0.5), Contact([0.0, 0.0, -ro], [0, 0, -1], 40.0, 0.5)]
    m = model.material
    _check_against_dense(w, m.alpha + m.beta * w**2, _factor(model, contacts))


def test_random_clusters_match_dense():
    rng = np.random.default_rng(3)
    r = 120
    f = np.sort(rng.uniform(200, 15000, r // 2))
    f = np.sort(np.concatenate([f, f * (1 + 1e-6 * rng.standard_normal(f.size))]))  # nearly repeated pairs
    w = 2 * np.pi * f
    Q = rng.standard_normal((8, r)) * 0.8
    _check_against_dense(w, 4.0 + 3e-7 * w**2, Q)


def test_overdamped_mode_is_left_to_the_dense_path():
    w = np.array([10.0, 2000.0, 3000.0])
    assert low_rank_modes(w, np.array([50.0, 1.0, 1.0]), np.ones((1, 3))) is None
