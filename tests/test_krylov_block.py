"""The Krylov block of the eigen-solve: the small block taken for a sparse band gives the modes of
the full block, and a repeated eigenvalue with more copies than the small block holds is found
whole (the solve goes back to the full block)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse

from sensors import MATERIALS
from sensors.fem import SOLVERS, assemble, available_solvers, solve_modes
from sensors.fem import eigen
from sensors.fem.beam_theory import TUBE
from sensors.mesh import quadratic_mesh, tube_mesh


def _known_spectrum_problem(frequencies_hz, n_nodes=500, seed=0):
    """Sparse K, M and nodes of a free body whose elastic eigenfrequencies are exactly
    ``frequencies_hz`` (plus six rigid-body modes at 0): K = M Phi Lambda Phi^T M with Phi an
    M-orthonormal basis whose first six columns span the rigid-body modes."""
    rng = np.random.default_rng(seed)
    nodes = rng.uniform(-0.05, 0.05, (n_nodes, 3))
    n = 3 * n_nodes
    assert len(frequencies_hz) == n - 6
    mass = rng.uniform(0.5, 2.0, n) * 1e-3
    root = np.sqrt(mass)
    # Orthonormal Q whose first columns span M^(1/2) R; Phi = M^(-1/2) Q is M-orthonormal.
    start = np.hstack([root[:, None] * eigen.rigid_body_modes(nodes), rng.standard_normal((n, n - 6))])
    Q, _ = np.linalg.qr(start)
    lam = np.concatenate([np.zeros(6), (2 * math.pi * np.asarray(frequencies_hz)) ** 2])
    MPhi = root[:, None] * Q  # M Phi = M^(1/2) Q
    K = (MPhi * lam) @ MPhi.T
    K = 0.5 * (K + K.T)
    return scipy.sparse.csr_matrix(K), scipy.sparse.diags(mass).tocsr(), nodes


def test_a_repeated_eigenvalue_with_more_copies_than_the_small_block_is_found_whole():
    band_hz = 1000.0
    # Two modes below the shift (at 707 Hz): the small block is taken. Five copies of 800 Hz.
    in_band = [200.0, 300.0] + [800.0] * 5 + [900.0]
    above = np.geomspace(1500.0, 5e4, 1494 - len(in_band))
    K, M, nodes = _known_spectrum_problem(np.concatenate([in_band, above]))
    info = {}
    lam, U = solve_modes(K, M, nodes, band_hz, info=info)
    f = np.sqrt(lam) / (2 * math.pi)
    assert len(f) == len(in_band)
    np.testing.assert_allclose(f, in_band, rtol=1e-9)
    assert info["block"] == eigen.FULL_BLOCK  # the small block saw a run of copies as long as itself


@pytest.mark.parametrize("solver", SOLVERS)
def test_the_small_block_gives_the_modes_of_the_full_block(solver, monkeypatch):
    if solver not in available_solvers():
        pytest.skip(f"{solver} is not installed")
    nodes, tets = quadratic_mesh(tube_mesh(**TUBE))
    K, M = assemble(nodes, tets, MATERIALS["aluminium"], "p2")
    band_hz = 9000.0  # a sparse band of the tube: pairs of repeated modes, few below the shift
    small = {}
    lam_small, U_small = solve_modes(K, M, nodes, band_hz, solver=solver, info=small)
    assert small["block"] == eigen.SPARSE_BAND_BLOCK
    monkeypatch.setattr(eigen, "SPARSE_BAND_BELOW", -1)  # every band takes the full block
    full = {}
    lam_full, U_full = solve_modes(K, M, nodes, band_hz, solver=solver, info=full)
    assert full["block"] == eigen.FULL_BLOCK
    assert len(lam_small) == len(lam_full) >= 4
    np.testing.assert_allclose(np.sqrt(lam_small), np.sqrt(lam_full), rtol=1e-9)
    # Each small-block mode lies in the span of the full block's modes of its eigenvalue.
    for i in range(len(lam_small)):
        same = np.abs(lam_full / lam_small[i] - 1) < 1e-6
        u = U_small[:, i]
        coeff = U_full[:, same].T @ (M @ u)
        np.testing.assert_allclose(np.linalg.norm(coeff), 1.0, atol=1e-5)
