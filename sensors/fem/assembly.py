"""Vectorized assembly of linear-elastic stiffness K and consistent mass M on tetrahedra.

Degrees of freedom are node-major: dof ``3 * node + component`` (x, y, z). Elements:

* ``p1``: 4-node linear tets (constant strain; they lock in bending - kept for comparison).
* ``p2``: 10-node quadratic tets in VTK node order (see :data:`sensors.mesh.tets.P2_EDGES`),
  isoparametric, so mid-edge nodes moved onto a curved surface give curved elements.

Quadrature: stiffness with the 4-point degree-2 rule (exact for straight P2; the 14-point
rule on curved elements), mass with a 14-point degree-5 rule (the P2 mass integrand is
degree 4).
"""

from __future__ import annotations

import dataclasses
import functools
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext

import numpy as np

from ..materials.solids import Material
from ..mesh.tets import MeshError, P2_EDGES

__all__ = ["ASSEMBLY_THREADS", "NodeBlocks", "assemble", "assemble_blocks", "assembled_csr", "shape_functions",
           "shape_gradients_ref", "QUADRATURE"]

_A2 = (5.0 - 5.0**0.5) / 20.0


def _perm_points(groups):
    pts, wts = [], []
    for kind, a, b, w in groups:
        if kind == "s31":
            bary = [[a, a, a, b], [a, a, b, a], [a, b, a, a], [b, a, a, a]]
        else:  # "s22"
            bary = [[a, a, b, b], [a, b, a, b], [a, b, b, a], [b, a, a, b], [b, a, b, a], [b, b, a, a]]
        pts += [p[1:] for p in bary]
        wts += [w] * len(bary)
    return np.array(pts), np.array(wts)


#: name -> (points in reference coordinates (q, 3), weights (q,) summing to 1/6)
QUADRATURE = {
    "deg1": (np.array([[0.25, 0.25, 0.25]]), np.array([1.0 / 6.0])),
    "deg2": _perm_points([("s31", _A2, 1 - 3 * _A2, 1.0 / 24.0)]),
    # Positive-weight 14-point rule exact to degree 5 (Walkington / Keast).
    "deg5": _perm_points([
        ("s31", 0.0927352503108912264, 1 - 3 * 0.0927352503108912264, 0.01224884051939365826),
        ("s31", 0.310885919263300610, 1 - 3 * 0.310885919263300610, 0.01878132095300264180),
        ("s22", 0.454496295874350351, 0.0455037041256496494, 0.007091003462846911),
    ]),
}


def _bary(xi: np.ndarray) -> np.ndarray:
    xi = np.atleast_2d(xi)
    return np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1)


def shape_functions(bary: np.ndarray, element: str) -> np.ndarray:
    """Shape functions at barycentric coordinates (n, 4) -> (n, 4) for P1 or (n, 10) for P2."""
    L = np.atleast_2d(bary)
    if element == "p1":
        return L.copy()
    corner = L * (2.0 * L - 1.0)
    edge = 4.0 * L[:, P2_EDGES[:, 0]] * L[:, P2_EDGES[:, 1]]
    return np.concatenate([corner, edge], axis=1)


def shape_gradients_ref(xi: np.ndarray, element: str) -> np.ndarray:
    """Derivatives of the shape functions w.r.t. reference coordinates: (q, n_nodes, 3)."""
    L = _bary(xi)
    dL = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = len(L)
    if element == "p1":
        return np.broadcast_to(dL, (q, 4, 3)).copy()
    corner = (4.0 * L - 1.0)[:, :, None] * dL[None]
    a, b = P2_EDGES[:, 0], P2_EDGES[:, 1]
    edge = 4.0 * (L[:, b, None] * dL[a][None] + L[:, a, None] * dL[b][None])
    return np.concatenate([corner, edge], axis=1)


def _jacobian(coords: np.ndarray, dN: np.ndarray):
    """coords (m, n, 3), dN (q, n, 3) -> J (m, q, 3, 3), its cofactor matrix C^T (adjugate:
    J^-1 = adj / det) and det J (m, q), checked positive. The 3 x 3 inverses in closed form
    (2.4x faster than batched LAPACK on the mug's 19k elements)."""
    J = np.matmul(coords.transpose(0, 2, 1)[:, None], dN[None])  # J[i, k] = d x_i / d xi_k
    a, b, c = J[..., 0, 0], J[..., 0, 1], J[..., 0, 2]
    d, e, f = J[..., 1, 0], J[..., 1, 1], J[..., 1, 2]
    g, h, i = J[..., 2, 0], J[..., 2, 1], J[..., 2, 2]
    adj = np.empty_like(J)
    adj[..., 0, 0], adj[..., 0, 1], adj[..., 0, 2] = e * i - f * h, c * h - b * i, b * f - c * e
    adj[..., 1, 0], adj[..., 1, 1], adj[..., 1, 2] = f * g - d * i, a * i - c * g, c * d - a * f
    adj[..., 2, 0], adj[..., 2, 1], adj[..., 2, 2] = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * adj[..., 0, 0] + b * adj[..., 1, 0] + c * adj[..., 2, 0]
    if np.any(det <= 0):
        bad = int((det <= 0).any(axis=1).sum())
        raise MeshError(f"{bad} elements have a non-positive Jacobian (inverted, degenerate, or curved "
                        "P2 elements too thin for their curvature: refine the mesh)")
    return adj, det


def _jacobians(coords: np.ndarray, dN: np.ndarray):
    """coords (m, n, 3), dN (q, n, 3) -> physical gradients (m, q, n, 3) and det J (m, q)."""
    adj, det = _jacobian(coords, dN)
    G = np.matmul(dN[None], adj)  # G[a, i] = sum_k dN[a, k] (J^-1)[k, i]
    G /= det[:, :, None, None]
    return G, det


def _block_pattern(tets: np.ndarray, n_nodes: int):
    """Node-pair sparsity pattern: (indptr, indices, slot, n_blocks, mirror) with slot
    (m, n_el, n_el) -> block and mirror[b] the block of the transposed node pair."""
    m, n_el = tets.shape
    rows = np.repeat(tets, n_el, axis=1).ravel()
    cols = np.tile(tets, (1, n_el)).ravel()
    key = rows * n_nodes + cols
    uniq, slot = np.unique(key, return_inverse=True)
    r, c = np.divmod(uniq, n_nodes)
    indptr = np.searchsorted(r, np.arange(n_nodes + 1))
    slot = slot.reshape(m, n_el, n_el)
    # Slot (e, a, b) holds node pair (i, j), slot (e, b, a) the pair (j, i): the mirror of every
    # block by one scatter (a search of each transposed key cost 4x more).
    mirror = np.empty(len(uniq), dtype=slot.dtype)
    mirror[slot] = slot.transpose(0, 2, 1)
    return indptr, c, slot, len(uniq), mirror


#: Threads of one assembly: the sparsity pattern beside the element integrals, then the node
#: blocks' symmetrization in halves (each part computed as by one thread: K and M are bit for
#: bit the same for one thread or two, whatever the load).
ASSEMBLY_THREADS = 2


@dataclasses.dataclass(frozen=True)
class NodeBlocks:
    """K and M in 3 x 3 node blocks, as assembled (node-level CSR pattern, sorted, symmetric).

    Attributes:
        stiffness: (n_blocks, 3, 3) K's block of each node pair [N/m].
        mass: (n_blocks,) M's block of each node pair, a multiple of the 3 x 3 identity [kg].
        indices, indptr: Node-level CSR pattern: row a's blocks are ``indptr[a]:indptr[a + 1]``,
            their columns ``indices[...]``.
        n_nodes: Number of nodes (3 n_nodes dofs, node-major).
        analysis: Future of the solver's analysis of the pattern, started as soon as the
            pattern was known (``assemble_blocks(analyze=True)``; None: none started).
    """

    stiffness: np.ndarray
    mass: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    n_nodes: int
    analysis: Future | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return (3 * self.n_nodes, 3 * self.n_nodes)

    def stiffness_csr(self) -> "scipy.sparse.csr_matrix":
        """K as CSR (exact zeros dropped, indices sorted)."""
        import scipy.sparse

        K = scipy.sparse.bsr_matrix((self.stiffness, self.indices, self.indptr), shape=self.shape).tocsr()
        K.eliminate_zeros()
        K.sort_indices()
        return K

    def mass_csr(self) -> "scipy.sparse.csr_matrix":
        """M as CSR (the identity's zeros never stored)."""
        return _block_identity_csr(self.mass, self.indices, self.indptr, self.shape)

    @functools.cached_property
    def _node_mass(self):
        """M's node-level matrix (n_nodes square, one entry per node block), zeros not stored
        as in :meth:`mass_csr`."""
        import scipy.sparse

        Mn = scipy.sparse.csr_matrix((self.mass, self.indices, self.indptr), shape=(self.n_nodes, self.n_nodes))
        if not np.all(self.mass):
            Mn.eliminate_zeros()
        return Mn

    def mass_product(self, X: np.ndarray) -> np.ndarray:
        """M @ X for an (3 n_nodes, k) block, bit for bit ``mass_csr() @ X`` (each row's entries
        summed in the same order): the node-level matrix times X viewed as (n_nodes, 3 k),
        a third of the index reads (mug, k = 3: 12 -> 5 ms)."""
        k = X.shape[1]
        product = self._node_mass @ np.ascontiguousarray(X).reshape(self.n_nodes, 3 * k)
        return product.reshape(3 * self.n_nodes, k)

    def shifted(self, sigma: float) -> "scipy.sparse.bsr_matrix":
        """K - sigma M as 3 x 3 BSR, straight from the blocks: the entries of
        ``K_csr - sigma * M_csr`` bit for bit, in the node blocks that hold a nonzero (as
        ``tobsr`` of that CSR gives them, a zero inside such a block stored as +0.0), without
        the CSR round trip (mug: 0.15-0.2 s)."""
        import scipy.sparse

        data = self.stiffness.copy()
        scaled = sigma * self.mass  # as scipy scales M's entries before the subtraction
        for i in range(3):
            data[:, i, i] -= scaled
        data += 0.0  # -0.0 -> +0.0: the CSR path drops it and the block gets +0.0
        indices, indptr = self.indices, self.indptr
        nonzero = np.any(data.reshape(len(data), 9) != 0.0, axis=1)
        if not nonzero.all():  # a block that cancelled exactly is not stored, as in the CSR path
            rows = np.repeat(np.arange(self.n_nodes), np.diff(indptr))
            data, indices = data[nonzero], indices[nonzero]
            indptr = np.zeros_like(self.indptr)
            np.cumsum(np.bincount(rows[nonzero], minlength=self.n_nodes), out=indptr[1:])
        A = scipy.sparse.bsr_matrix((data, indices, indptr), shape=self.shape)
        A.has_sorted_indices = True
        return A

    def factorize_shifted(self, sigma: float, solver: str | None = None):
        """The factorization of K - sigma M (:func:`sensors.fem.direct_solver.factorize`) from the
        blocks: PARDISO takes them as they are, SuperLU the same CSR as ``K - sigma M``."""
        from .direct_solver import factorize

        A = self.shifted(sigma)
        analysis = None
        if self.analysis is not None and self.analysis.exception() is None:  # waits for it
            analysis = self.analysis.result()  # used once; a second call analyses afresh
        return factorize(A, solver, analysis=analysis)


def assemble(nodes_m: np.ndarray, tets: np.ndarray, material: Material, element: str = "p2",
             chunk: int = 20000) -> tuple[scipy.sparse.csr_matrix, scipy.sparse.csr_matrix]:
    """Global stiffness K [N/m] and consistent mass M [kg] as CSR matrices (3 n_nodes square).

    Args:
        nodes_m: (n, 3) node coordinates [m].
        tets: (m, 4) for ``p1`` or (m, 10) for ``p2`` (VTK order).
        material: Isotropic material (E, nu, density).
        chunk: Elements per vectorized batch (bounds the temporary memory).
    """
    return assembled_csr(assemble_blocks(nodes_m, tets, material, element, chunk))


def assembled_csr(blocks: NodeBlocks, threads: int = ASSEMBLY_THREADS):
    """(K, M) of :func:`assemble_blocks`' result as CSR, the two built at once on two threads."""
    with _helper(threads) as pool:
        K = _submit(pool, blocks.stiffness_csr)
        M = blocks.mass_csr()
        return K.result(), M


def _helper(threads: int):
    """The helper thread of a two-thread step, or a context holding None for one thread."""
    if threads not in (1, 2):
        raise ValueError(f"threads must be 1 or 2, got {threads!r}")
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix="assembly") if threads == 2 else nullcontext()


def _submit(pool, fn, *args) -> Future:
    """``fn(*args)`` in the helper thread, or at once in this one when there is none."""
    if pool is not None:
        return pool.submit(fn, *args)
    done = Future()
    done.set_result(fn(*args))
    return done


def assemble_blocks(nodes_m: np.ndarray, tets: np.ndarray, material: Material, element: str = "p2",
                    chunk: int = 20000, threads: int = ASSEMBLY_THREADS, analyze: bool = False) -> NodeBlocks:
    """K and M in node blocks (:class:`NodeBlocks`); arguments as :func:`assemble`.

    On two threads (NumPy and SciPy release the GIL in each step) the sparsity pattern is found
    in one while the element integrals run in the other, and the blocks are symmetrized in two
    halves. Each step is the same as on one thread (``threads=1``) and every sum keeps its order,
    so the blocks are bit for bit the same on one thread or two, whatever the load (mug, 99k
    dof: 0.95 -> 0.6 CPU s on the caller's thread).

    ``analyze``: start the default solver's analysis of the pattern
    (:func:`sensors.fem.direct_solver.analyze_pattern`) in a thread of its own as soon as the
    pattern is known, while the element integrals are still summed; ``factorize_shifted``
    uses it (mug: PARDISO's 0.5 CPU s analysis off the build's path)."""
    import scipy.sparse  # ~0.1 s to import: only a model build needs it

    element = element.lower()
    n_el = {"p1": 4, "p2": 10}.get(element)
    if n_el is None:
        raise ValueError(f"element must be 'p1' or 'p2', got {element!r}")
    tets = np.asarray(tets, dtype=np.int64)
    if tets.ndim != 2 or tets.shape[1] != n_el:
        raise ValueError(f"{element} needs tets of shape (m, {n_el}), got {tets.shape}")
    nodes_m = np.asarray(nodes_m, dtype=np.float64)
    n_nodes = len(nodes_m)
    lam, mu, rho = material.lame_lambda_pa, material.shear_modulus_pa, material.density_kg_m3
    k_rule, m_rule = ("deg1", "deg2") if element == "p1" else ("deg2", "deg5")
    xm, wm = QUADRATURE[m_rule]
    dNm = shape_gradients_ref(xm, element)
    Nm = shape_functions(_bary(xm), element)  # (q, n)
    NN = np.einsum("qa,qb->qab", Nm, Nm).reshape(len(wm), -1)
    with _helper(threads) as pool:
        pattern = _submit(pool, _block_pattern, tets, n_nodes)
        analysis = _analysis_after(pattern) if analyze else None
        curved = np.zeros(len(tets), dtype=bool)
        if element == "p2":
            # Curved (isoparametric) elements need more than the 4-point rule: under-integrating
            # them made thin-walled tube ring modes 1-2% too soft.
            corners = nodes_m[tets[:, P2_EDGES]]  # (m, 6, 2, 3)
            mids = nodes_m[tets[:, 4:]]
            dev = np.abs(mids - corners.mean(axis=2)).max(axis=(1, 2))
            size = np.abs(corners[:, :, 1] - corners[:, :, 0]).max(axis=(1, 2))
            curved = dev > 1e-9 * size
        batches = []
        for flag, rule in ((False, k_rule), (True, "deg5")):
            idx = np.flatnonzero(curved == flag)
            for start in range(0, len(idx), chunk):
                batches.append((idx[start:start + chunk], rule, flag))
        pending = []
        sums = _BlockSums(pattern)
        for sel, rule, is_curved in batches:
            xk, wk = QUADRATURE[rule]
            dNk = shape_gradients_ref(xk, element)
            ne = len(sel)
            X = nodes_m[tets[sel]]
            G, det = _jacobians(X, dNk)
            q = G.shape[1]
            Gf = G.reshape(ne, q, 3 * n_el)
            wGf = Gf * (det * wk)[:, :, None]
            # A[a i, b j] = sum_q w|J| G_ai G_bj; K[a i, b j] = lam A[ai,bj] + mu A[aj,bi] + mu d_ij tr_k A[ak,bk].
            # K is linear in A: only A is summed into node blocks, and the Lame combination is
            # taken per node block at the end, not per element entry (3x less time than forming
            # each element's K). Laid out as (element, a, b) slots of 3 x 3 entries.
            A = np.matmul(wGf.transpose(0, 2, 1), Gf).reshape(ne, n_el, 3, n_el, 3)
            A = A.transpose(0, 1, 3, 2, 4).reshape(ne * n_el * n_el, 9)
            # The mass needs only det J: the stiffness's when the rules coincide, and constant over
            # a straight element (its first point's).
            if rule == m_rule:
                detm = det
            elif not is_curved:
                detm = np.broadcast_to(det[:, :1], (ne, len(wm)))
            else:
                detm = _jacobian(X, dNm)[1]
            Me = rho * ((detm * wm) @ NN)  # (ne, n_el * n_el)
            pending.append((sel, A, Me.ravel()))
            if pattern.done():  # batches wait only as long as the pattern (memory: 7 kB per element)
                sums.add(pending)
        sums.add(pending)  # the rest (and the zero blocks of a mesh without elements)
        indptr, indices, slot, nnzb, mirror = pattern.result()
        a_blocks, m_blocks = sums.a_blocks, sums.m_blocks
        # Symmetrize exactly (round-off in the element sums breaks it at 1e-16 relative): entry
        # (a, b) of block (i, j) is mirrored by entry (b, a) of block (j, i). Blockwise, so the
        # two halves of the blocks run in the two threads.
        ab = a_blocks.reshape(-1, 3, 3)
        kb = np.empty_like(ab)
        half = nnzb // 2
        first = _submit(pool, _lame_blocks, ab, mirror, kb, slice(0, half), lam, mu)
        _lame_blocks(ab, mirror, kb, slice(half, nnzb), lam, mu)
        first.result()
    mb = (m_blocks + np.take(m_blocks, mirror)) * 0.5
    return NodeBlocks(kb, mb, indices, indptr, n_nodes, analysis)


def _analysis_after(pattern: Future) -> Future:
    """The default solver's analysis of ``pattern``'s node blocks, in a thread of its own that
    starts once the pattern is there (it outlives the assembly: the factorization waits for it)."""
    from .direct_solver import analyze_pattern

    def analyze():
        indptr, indices, _, _, _ = pattern.result()
        return analyze_pattern(indptr, indices)

    runner = ThreadPoolExecutor(max_workers=1, thread_name_prefix="analysis")
    try:
        return runner.submit(analyze)
    finally:
        runner.shutdown(wait=False)


class _BlockSums:
    """The element integrals summed into node blocks batch by batch, in batch order."""

    def __init__(self, pattern):
        self._pattern = pattern
        self.a_blocks = self.m_blocks = None

    def add(self, pending: list) -> None:
        """Sum the batches in ``pending`` (emptied) into the blocks (waits for the pattern)."""
        import scipy.sparse

        if not pending and self.a_blocks is not None:
            return
        _, _, slot, nnzb, _ = self._pattern.result()
        if self.a_blocks is None:
            self.a_blocks = np.zeros((nnzb, 9))  # sum over elements of A, per node block
            self.m_blocks = np.zeros(nnzb)
        while pending:
            sel, A, Me = pending.pop(0)
            s = slot[sel].ravel()
            # Each (element, a, b) slot's 3 x 3 entries added into its node block in one pass: the
            # product of a 0/1 scatter matrix (one entry per column, in CSC form) with the
            # (slot, 9) entries, 3x faster than one bincount per block entry.
            scatter = scipy.sparse.csc_matrix((np.ones(len(s)), s, np.arange(len(s) + 1)), shape=(nnzb, len(s)))
            self.a_blocks += scatter @ A
            self.m_blocks += np.bincount(s, weights=Me, minlength=nnzb)


def _lame_blocks(ab: np.ndarray, mirror: np.ndarray, out: np.ndarray, part: slice, lam: float, mu: float) -> None:
    """K's node blocks ``part`` into ``out`` from the summed A blocks ``ab``: A symmetrized
    with its mirror, then the Lame combination."""
    # The symmetric part of A taken first (block b and the transpose of its mirror; the sum is
    # the same either way round, so the two halves stay exact mirrors), then the Lame combination,
    # which keeps that symmetry exactly.
    sym = np.take(ab, mirror[part], axis=0)  # take: 2.5x faster than fancy indexing here
    sym += ab[part].transpose(0, 2, 1)
    sym *= 0.5
    a = sym.transpose(0, 2, 1)  # = (ab + ab[mirror]^T) / 2
    kb = out[part]
    np.multiply(lam, a, out=kb)
    kb += mu * a.transpose(0, 2, 1)
    trace = mu * (a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2])
    for i in range(3):
        kb[:, i, i] += trace


def _block_identity_csr(values: np.ndarray, indices: np.ndarray, indptr: np.ndarray, shape):
    """CSR of the matrix whose node block b is ``values[b]`` times the 3 x 3 identity (the
    consistent mass), laid out directly: row 3 a + i holds, for each block b of node row a, the
    entry at column 3 indices[b] + i (sorted, as the blocks are)."""
    import scipy.sparse

    n_rows = len(indptr) - 1
    length = np.diff(indptr)
    row = np.repeat(np.arange(n_rows), length)
    within = np.arange(len(values)) - indptr[row]
    out_indptr = np.zeros(3 * n_rows + 1, dtype=np.int64)
    out_indptr[1:] = np.cumsum(np.repeat(length, 3))
    data = np.empty(3 * len(values))
    cols = np.empty(3 * len(values), dtype=indices.dtype)
    for i in range(3):
        at = 3 * indptr[row] + i * length[row] + within
        data[at] = values
        cols[at] = 3 * indices + i
    M = scipy.sparse.csr_matrix((data, cols, out_indptr), shape=shape)
    M.has_sorted_indices = True
    if not np.all(values):
        M.eliminate_zeros()  # as the entries of the blocks off the identity's diagonal
    return M
