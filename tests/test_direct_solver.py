"""The two sparse direct solvers behind the eigen-solve (MKL PARDISO and SciPy SuperLU): the
same modes from both, the inertia each reports against a dense eigensolve, solves against
SciPy's, and the choice between them.

On x86-64 the set-up installs MKL, so the PARDISO path is required there (a missing MKL fails
instead of skipping: CI must run both paths); elsewhere only the SuperLU path runs."""

from __future__ import annotations

import logging
import math
import platform

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from sensors import MATERIALS
from sensors.fem import SOLVERS, assemble, available_solvers, default_solver, factorize, solve_modes
from sensors.fem import direct_solver
from sensors.fem.beam_theory import BAR, TUBE
from sensors.fem.eigen import mode_residuals
from sensors.mesh import bar_mesh, quadratic_mesh, tube_mesh

X86_64 = platform.machine().lower() in ("x86_64", "amd64")
RESIDUAL_TOL = 1e-6  # solve_modes' default


def _needs_pardiso():
    if "pardiso" not in available_solvers():
        if X86_64:
            pytest.fail("MKL is missing on x86-64: `python3 tasks.py setup` installs it (pip install mkl)")
        pytest.skip("MKL PARDISO exists for x86-64 only")


def _problem(kind: str, material: str, resolution: float = 1.0):
    mesh = bar_mesh(**BAR, resolution=resolution) if kind == "bar" else tube_mesh(**TUBE, resolution=resolution)
    nodes, tets = quadratic_mesh(mesh)
    K, M = assemble(nodes, tets, MATERIALS[material], "p2")
    return K, M, nodes


@pytest.fixture(scope="module", params=[("bar", "abs", 22050.0), ("tube", "aluminium", 22050.0)],
                ids=["abs-bar", "aluminium-tube"])
def both_paths(request):
    """The default bar (46 modes) and tube (pairs of repeated modes) by both solvers."""
    _needs_pardiso()
    kind, material, band_hz = request.param
    K, M, nodes = _problem(kind, material)
    out = {}
    for solver in SOLVERS:
        info = {}
        lam, U = solve_modes(K, M, nodes, band_hz, solver=solver, info=info)
        assert info["solver"] == solver
        out[solver] = (lam, U)
    return K, M, out


def test_both_solvers_give_the_same_frequencies(both_paths):
    K, M, out = both_paths
    (lam_p, U_p), (lam_s, U_s) = out["pardiso"], out["superlu"]
    assert len(lam_p) == len(lam_s) > 10
    f_p, f_s = np.sqrt(lam_p), np.sqrt(lam_s)
    assert np.max(np.abs(f_p / f_s - 1)) <= RESIDUAL_TOL
    for lam, U in out.values():
        assert mode_residuals(K, M, lam, U).max() <= RESIDUAL_TOL


def test_both_solvers_give_the_same_mode_shapes(both_paths):
    """The two mode sets span the same subspace (the sets end at cluster boundaries, so a pair
    of repeated modes may be rotated inside it but never split): each SuperLU mode is in the
    span of the PARDISO modes to the residual tolerance."""
    K, M, out = both_paths
    (_, U_p), (_, U_s) = out["pardiso"], out["superlu"]
    C = U_p.T @ (M @ U_s)  # both sets are M-orthonormal
    outside = U_s - U_p @ C
    outside_norm = np.sqrt(np.einsum("ij,ij->j", outside, M @ outside))
    assert outside_norm.max() <= 10 * RESIDUAL_TOL


@pytest.mark.parametrize("solver", SOLVERS)
def test_inertia_counts_the_eigenvalues_below_the_shift(solver):
    """Sylvester: the negative pivots of K - sigma M count the eigenvalues of (K, M) below sigma,
    here against a dense generalized eigensolve of a small P2 bar (the six rigid-body modes
    included)."""
    if solver == "pardiso":
        _needs_pardiso()
    K, M, _ = _problem("bar", "abs", resolution=0.5)
    lam = scipy.linalg.eigh(K.toarray(), M.toarray(), eigvals_only=True)
    for f_hz in (3000.0, 15000.0, 40000.0):
        sigma = (2 * math.pi * f_hz) ** 2
        expected = int(np.count_nonzero(lam < sigma))
        assert expected >= 6
        fact = factorize(K - sigma * M, solver)
        assert fact.name == solver and fact.n_negative == expected


@pytest.mark.parametrize("solver", SOLVERS)
def test_solves_match_scipy(solver):
    if solver == "pardiso":
        _needs_pardiso()
    K, M, _ = _problem("bar", "steel", resolution=0.5)
    A = (K - (2 * math.pi * 9000.0) ** 2 * M).tocsc()
    rng = np.random.default_rng(1)
    B = rng.standard_normal((A.shape[0], 5))
    fact = factorize(A, solver)
    ref = scipy.sparse.linalg.spsolve(A, B)
    X = fact.solve(B)
    assert X.shape == B.shape
    np.testing.assert_allclose(X, ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())
    np.testing.assert_allclose(fact.solve(B[:, 2]), ref[:, 2], rtol=1e-8, atol=1e-8 * np.abs(ref).max())


@pytest.mark.parametrize("n", [299, 300])
def test_pardiso_scalar_and_node_block_input(n):
    """A size divisible by 3 goes to PARDISO in 3 x 3 blocks (BSR), any other size as scalar
    rows (CSR): both solve and count the inertia of an indefinite tridiagonal matrix exactly
    as a dense eigensolve does."""
    _needs_pardiso()
    from sensors.fem.pardiso import PardisoLDLT

    main = 2.0 + np.linspace(0.0, 1.0, n)
    A = scipy.sparse.diags([-np.ones(n - 1), main - 2.3, -np.ones(n - 1)], [-1, 0, 1], format="csr")
    fact = PardisoLDLT(A)
    assert fact.block == (3 if n % 3 == 0 else 1)
    dense = A.toarray()
    assert fact.n_negative == int((np.linalg.eigvalsh(dense) < 0).sum()) > 0
    B = np.random.default_rng(3).standard_normal((n, 2))
    np.testing.assert_allclose(fact.solve(B), np.linalg.solve(dense, B), rtol=1e-9, atol=1e-9)


def test_pardiso_is_the_same_bit_for_bit_whatever_mkl_threads_say():
    """PARDISO's factor depends on the number of threads MKL runs (and MKL runs fewer than
    asked on a loaded machine): the solver pins its calls to one, so a process-wide setting of
    two threads changes no bit (without the pin this fails wherever MKL gets two free cores)."""
    _needs_pardiso()
    from sensors.fem.pardiso import mkl_library

    K, M, _ = _problem("tube", "aluminium")
    A = (K - (2 * math.pi * 11000.0) ** 2 * M).tocsr()
    B = np.random.default_rng(2).standard_normal((A.shape[0], 3))
    lib = mkl_library()
    previous = lib.MKL_Get_Max_Threads()
    solutions = []
    try:
        for threads in (1, 2, 1):
            lib.MKL_Set_Num_Threads(threads)
            solutions.append(factorize(A, "pardiso").solve(B))
    finally:
        lib.MKL_Set_Num_Threads(previous)   # the worker's own setting for the tests after this one
    assert np.array_equal(solutions[0], solutions[1]) and np.array_equal(solutions[0], solutions[2])
    np.testing.assert_allclose(A @ solutions[0], B, atol=1e-9 * np.abs(B).max())


def test_environment_variable_forces_a_solver(monkeypatch):
    monkeypatch.setenv(direct_solver.SOLVER_ENV, "superlu")
    assert default_solver() == "superlu"
    monkeypatch.setenv(direct_solver.SOLVER_ENV, "umfpack")
    with pytest.raises(ValueError, match="AAS_GYM_SOLVER"):
        default_solver()


def test_without_mkl_the_scipy_path_is_chosen_with_one_line_on_the_fast_path(monkeypatch, caplog):
    from sensors.fem import pardiso

    monkeypatch.delenv(direct_solver.SOLVER_ENV, raising=False)
    monkeypatch.setattr(pardiso, "LIBRARY", [None])  # as on a machine without the mkl wheel
    monkeypatch.setattr(direct_solver, "HINT_SHOWN", [])
    with caplog.at_level(logging.WARNING, logger=direct_solver.__name__):
        assert default_solver() == "superlu"
        assert default_solver() == "superlu"
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "pip install mkl" in lines[0]
    assert available_solvers() == ("superlu",)


def test_default_is_pardiso_where_mkl_is_installed(monkeypatch):
    _needs_pardiso()
    monkeypatch.delenv(direct_solver.SOLVER_ENV, raising=False)
    assert default_solver() == "pardiso"


def test_superlu_path_builds_the_spoon():
    """SuperLU without pivoting leaves the spoon's solves 2e-10 off (PARDISO: 4e-12); K Z derived
    from them failed the final residual check (2 of 15 modes at 1.1e-6), so a machine without MKL
    could not build the spoon. The eigen-solve now forms K Z by a product for inexact solvers."""
    from sensors.objects import get_object

    solid = get_object("spoon").solid()
    nodes, tets = quadratic_mesh(solid.tet_mesh())
    K, M = assemble(nodes, tets, solid.material, "p2")
    lam, U = solve_modes(K, M, nodes, 10000.0, solver="superlu")
    assert mode_residuals(K, M, lam, U).max() <= RESIDUAL_TOL
    if "pardiso" in available_solvers():
        lam_p, _ = solve_modes(K, M, nodes, 10000.0, solver="pardiso")
        assert len(lam_p) == len(lam)
        assert np.max(np.abs(np.sqrt(lam_p / lam) - 1)) <= RESIDUAL_TOL
