"""The low-rank complex-mode path against LAPACK's dense eigen-decomposition of the same
state matrix (an independent solver), on FEM models with repeated mode pairs."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from sensors import MATERIALS, Contact, ModalModel
from sensors.synthesis.low_rank_modes import low_rank_modes


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
    # every dense eigenvalue found with its multiplicity: sorted by frequency, one to one
    got, want = lam[np.argsort(lam.imag)], ref[np.argsort(ref.imag)]
    assert np.all(np.abs(got - want) <= 1e-11 * np.abs(want))
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


def test_uncoupled_and_exactly_repeated_modes():
    """Modes the contacts do not touch keep their closed-form pairs; an exactly repeated pair
    either resolves correctly or falls back (None), never returns wrong modes."""
    w = 2 * np.pi * np.array([1000.0, 2000.0, 2000.0, 3000.0, 4000.0])
    Q = np.array([[0.0, 1.0, 0.5, 0.0, 2.0], [0.0, 0.3, -1.0, 0.0, 0.1]])
    out = low_rank_modes(w, np.full(5, 3.0), Q)
    if out is not None:
        _check_against_dense(w, np.full(5, 3.0), Q)
    assert low_rank_modes(w, np.full(5, 3.0), np.zeros((2, 5))) is not None
    _check_against_dense(w, np.full(5, 3.0), np.zeros((2, 5)))


def test_exactly_repeated_modes_without_mutual_coupling():
    """Two modes at exactly the same frequency that the contacts touch but do not couple to
    each other (orthogonal columns of Q), while both couple to the rest: the start has no
    finite second-order term between them; the result is right or left to the dense path."""
    w = 2 * np.pi * np.array([1000.0, 2000.0, 2000.0, 3000.0, 4000.0])
    Q = np.array([[0.5, 1.0, 0.0, 0.3, 2.0], [0.2, 0.0, 1.0, -0.4, 0.1], [1.0, 0.1, 0.0, 0.2, 0.3]])
    assert Q[:, 1] @ Q[:, 2] == 0.0
    if low_rank_modes(w, np.full(5, 3.0), Q) is not None:
        _check_against_dense(w, np.full(5, 3.0), Q)


def test_synthesis_response_equals_the_dense_path():
    """ModalSystem.build takes the low-rank path for a grasp; passing the same C_m as a
    matrix forces LAPACK's dense eig: the microphone responses agree to rounding."""
    from sensors import ModalSystem, modal_damping_matrix

    model = ModalModel.tube(0.2, 0.0125, 0.0105, MATERIALS["aluminium"], progress=False)
    ro = 0.0125
    contacts = [Contact([0.02, 0.0, ro], [0, 0, 1], 40.0, 0.5), Contact([0.02, 0.0, -ro], [0, 0, -1], 40.0, 0.5),
                Contact([0.09, ro, 0.0], [0, 1, 0], 3.0, 0.4)]
    geom = ([0.02, 0.0, ro], [0, 0, 1], [0.02, 0.0, -ro], [0, 0, -1])
    fast = ModalSystem.build(model, 44100, *geom, contacts, contact_model="damping")  # C_m of the free modes
    dense = ModalSystem.build(model, 44100, *geom, contacts, damping=modal_damping_matrix(model, contacts))
    u = np.random.default_rng(0).standard_normal(22050)
    yf, yd = fast.response(u), dense.response(u)
    assert np.max(np.abs(yf - yd)) <= 1e-9 * np.max(np.abs(yd))
    x0 = dense.final_state(u)
    np.testing.assert_allclose(fast.final_state(u), x0, atol=1e-9 * np.abs(x0).max())
