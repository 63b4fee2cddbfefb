"""Assembly in node blocks on two threads (sensors.fem.assembly.assemble_blocks) and the blocks
handed to the factorization without CSR (NodeBlocks.shifted / factorize_shifted).

The stiffness and mass are checked against an independent element-by-element assembly (the
textbook B^T D B with a dense 6 x 6 elasticity matrix, and N^T N for the mass); the two-thread
assembly against the one-thread one bit for bit; the blocks' K - sigma M against the CSR
difference bit for bit, and the modes solved from either the same bit for bit on both solvers."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse

from sensors import MATERIALS
from sensors.fem import SOLVERS, available_solvers, solve_modes
from sensors.fem.assembly import (QUADRATURE, assemble, assemble_blocks, assembled_csr, shape_functions,
                                  shape_gradients_ref)
from sensors.fem.beam_theory import TUBE
from sensors.mesh import quadratic_mesh, tube_mesh

BAND_HZ = 22050.0


@pytest.fixture(scope="module")
def tube():
    """The default tube: curved P2 elements (the 14-point rule) beside straight ones."""
    nodes, tets = quadratic_mesh(tube_mesh(**TUBE))
    return nodes, tets, MATERIALS["aluminium"]


def _elementwise(nodes, tets, material):
    """K and M by the textbook element loop: B^T D B at the 14-point rule on every element (exact
    for straight and curved P2 to the rule's degree), N^T N rho at the same rule."""
    lam, mu, rho = material.lame_lambda_pa, material.shear_modulus_pa, material.density_kg_m3
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    x, w = QUADRATURE["deg5"]
    dN = shape_gradients_ref(x, "p2")
    bary = np.concatenate([1 - x.sum(axis=1, keepdims=True), x], axis=1)
    N = shape_functions(bary, "p2")
    n = 3 * len(nodes)
    rows, cols, kv, mv = [], [], [], []
    for t in tets:
        X = nodes[t]
        Ke, Me = np.zeros((30, 30)), np.zeros((10, 10))
        for q in range(len(w)):
            J = X.T @ dN[q]
            G = dN[q] @ np.linalg.inv(J)  # (10, 3) physical gradients
            B = np.zeros((6, 30))
            for a in range(10):
                gx, gy, gz = G[a]
                B[:, 3 * a:3 * a + 3] = [[gx, 0, 0], [0, gy, 0], [0, 0, gz], [gy, gx, 0], [0, gz, gy], [gz, 0, gx]]
            dv = w[q] * np.linalg.det(J)
            Ke += dv * B.T @ D @ B
            Me += dv * rho * np.outer(N[q], N[q])
        dofs = (3 * t[:, None] + np.arange(3)).ravel()
        rows.append(np.repeat(dofs, 30))
        cols.append(np.tile(dofs, 30))
        kv.append(Ke.ravel())
        mv.append(np.kron(Me, np.eye(3)).ravel())
    r, c = np.concatenate(rows), np.concatenate(cols)
    K = scipy.sparse.coo_matrix((np.concatenate(kv), (r, c)), shape=(n, n)).tocsr()
    M = scipy.sparse.coo_matrix((np.concatenate(mv), (r, c)), shape=(n, n)).tocsr()
    return K, M


def test_node_blocks_match_an_element_by_element_assembly():
    """A small curved tube (every element at the 14-point rule in the reference; the assembly
    uses the 4-point rule on straight elements, exact there for the degree-2 integrand)."""
    nodes, tets = quadratic_mesh(tube_mesh(**{**TUBE, "length_m": 0.05}, resolution=0.5))
    material = MATERIALS["steel"]
    K_ref, M_ref = _elementwise(nodes, tets, material)
    K, M = assemble(nodes, tets, material, "p2")
    for A, ref in ((K, K_ref), (M, M_ref)):
        assert abs(A - ref).max() <= 1e-10 * abs(ref).max()
        assert (A - A.T).count_nonzero() == 0  # exactly symmetric


def _bits(A):
    A = A.tocsr() if not isinstance(A, scipy.sparse.bsr_matrix) else A
    return [np.asarray(a).tobytes() for a in (A.data, A.indices, A.indptr)]


def test_two_threads_assemble_the_same_bits_as_one(tube):
    nodes, tets, material = tube
    # Default batches, and small ones: several batches of straight and of curved elements,
    # summed in order whether the pattern was ready after the first or only after the last.
    for chunk in (20000, 700):
        one = assemble_blocks(nodes, tets, material, "p2", chunk=chunk, threads=1)
        two = assemble_blocks(nodes, tets, material, "p2", chunk=chunk, threads=2)
        for a, b in ((one.stiffness, two.stiffness), (one.mass, two.mass), (one.indices, two.indices),
                     (one.indptr, two.indptr)):
            assert a.tobytes() == b.tobytes()
    K1, M1 = assembled_csr(one, threads=1)
    K2, M2 = assembled_csr(one, threads=2)
    assert _bits(K1) == _bits(K2) and _bits(M1) == _bits(M2)
    K, M = assemble(nodes, tets, material, "p2", chunk=700)
    assert _bits(K1) == _bits(K) and _bits(M1) == _bits(M)


def test_shifted_blocks_are_the_csr_difference_bit_for_bit(tube):
    nodes, tets, material = tube
    blocks = assemble_blocks(nodes, tets, material, "p2")
    K, M = assembled_csr(blocks)
    sigma = 0.5 * (2 * math.pi * BAND_HZ) ** 2
    A = blocks.shifted(sigma)
    assert isinstance(A, scipy.sparse.bsr_matrix) and A.blocksize == (3, 3)
    ref = (K - sigma * M).tobsr(blocksize=(3, 3))
    ref.sort_indices()
    assert _bits(A) == [np.asarray(a).tobytes() for a in (ref.data, ref.indices, ref.indptr)]
    # SuperLU's input: the CSR difference's entries, its exact zeros dropped.
    csr = A.tocsr()
    csr.eliminate_zeros()
    assert _bits(csr) == _bits(K - sigma * M)


def test_node_level_mass_product_is_the_csr_product_bit_for_bit(tube):
    nodes, tets, material = tube
    blocks = assemble_blocks(nodes, tets, material, "p2")
    M = blocks.mass_csr()
    rng = np.random.default_rng(5)
    for k, order in ((3, "F"), (6, "C"), (1, "C")):
        X = np.asarray(rng.standard_normal((M.shape[0], k)), order=order)
        product = blocks.mass_product(X)
        assert product.shape == (M.shape[0], k) and product.tobytes() == (M @ X).tobytes()


@pytest.mark.parametrize("solver", SOLVERS)
def test_modes_from_the_blocks_are_those_from_csr_bit_for_bit(tube, solver):
    if solver not in available_solvers():
        pytest.skip("MKL PARDISO exists for x86-64 only (tests/test_direct_solver.py requires it there)")
    nodes, tets, material = tube
    blocks = assemble_blocks(nodes, tets, material, "p2")
    K, M = assembled_csr(blocks)
    info_csr, info_blocks = {}, {}
    lam, U = solve_modes(K, M, nodes, BAND_HZ, solver=solver, info=info_csr)
    lam_b, U_b = solve_modes(K, M, nodes, BAND_HZ, solver=solver, info=info_blocks,
                             factorize_shifted=blocks.factorize_shifted, mass_product=blocks.mass_product)
    assert info_blocks["solver"] == solver and info_blocks["solves"] == info_csr["solves"]
    assert np.array_equal(lam, lam_b) and np.array_equal(U, U_b)


def test_the_solver_preload_loads_the_default_solver_in_the_background():
    code = ("import sys\n"
            "from sensors.fem import direct_solver, pardiso\n"
            "thread = direct_solver.preload_in_background()\n"
            "assert direct_solver.preload_in_background() is None  # once per process\n"
            "thread.join()\n"
            "assert 'scipy.linalg' in sys.modules\n"
            "if direct_solver.default_solver() == 'pardiso':\n"
            "    assert pardiso.LIBRARY and pardiso.LIBRARY[0] is not None\n"
            "else:\n"
            "    assert 'scipy.sparse.linalg' in sys.modules\n"
            "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_pardiso_analysed_before_the_values_gives_the_same_factor_bit_for_bit(tube):
    """PARDISO's analysis of the bare pattern (started by the assembly as soon as the pattern is
    known) and a numerical factorization later: the same solves, bit for bit, as analysing and
    factorizing at once; a matrix of another pattern is analysed afresh."""
    if "pardiso" not in available_solvers():
        pytest.skip("MKL PARDISO exists for x86-64 only (tests/test_direct_solver.py requires it there)")
    from sensors.fem.direct_solver import analyze_pattern, factorize

    nodes, tets, material = tube
    sigma = 0.5 * (2 * math.pi * BAND_HZ) ** 2
    plain = assemble_blocks(nodes, tets, material, "p2")
    ahead = assemble_blocks(nodes, tets, material, "p2", analyze=True)
    B = np.random.default_rng(4).standard_normal((3 * len(nodes), 3))
    reference = factorize(plain.shifted(sigma), "pardiso")
    fact = ahead.factorize_shifted(sigma, "pardiso")
    assert fact.analysed_before and not reference.analysed_before
    assert fact.n_negative == reference.n_negative and fact.factor_mb == reference.factor_mb
    assert fact.solve(B).tobytes() == reference.solve(B).tobytes()
    assert not ahead.factorize_shifted(sigma, "pardiso").analysed_before  # used once
    # Another pattern (the tube's halves uncoupled): not this analysis.
    other = analyze_pattern(plain.indptr, plain.indices, "pardiso")
    K = plain.stiffness_csr()
    half = 3 * (len(nodes) // 2)
    A = (K - sigma * plain.mass_csr()).tolil()
    A[:half, half:] = 0
    A[half:, :half] = 0
    A = A.tocsr()
    A.eliminate_zeros()
    assert not factorize(A, "pardiso", analysis=other).analysed_before
