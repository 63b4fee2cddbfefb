"""Modes of a mirror-symmetric body, solved per symmetry class, the classes side by side.

A mesh that mirrors onto itself across k coordinate planes through the origin
(``TetMesh.mirror_axes``) has K and M that commute with each mirror, so every mode is even or
odd under each of them: the 3 n dofs split exactly into 2^k classes (a sign per mirror),
orthogonal in K and M alike. A class's matrices need only the elements of one orthant (the
mesh's 1/2^k): with T the orthonormal basis of the class (each column spreads one dof of a node
in the orthant over that node's mirror images, with the class's signs),

    K_c = T^T K T = 2^k T^T K_o T = D K_o[S, S] D,

where K_o is assembled from the orthant's elements alone, S picks the dofs the class allows at
each orthant node (a node on a mirror plane carries, in an even class, no motion across it; in
an odd class, only that), and D = sqrt(2^k / orbit size) per node. Each class is a free-body
eigenproblem of its own (its share of the six rigid-body modes projected out), solved by
:func:`sensors.fem.eigen.solve_modes` with its own factorization in its own thread: on two
cores the one-thread factorizations and Krylov solves of the halves run at once, each a
fraction of the whole (bottle, 95k dof: four of about 24k). Each class's result depends on it
alone, so the modes are the same bit for bit whatever ran first.

The union of the classes' modes, sorted by eigenvalue (ties by class order), is the whole
problem's: each class's modes satisfy the whole problem to the same residual (T is
orthonormal and K T = T K_c), and the classes' band ends are raised until no cluster at the
band limit is cut between classes (as :func:`sensors.fem.eigen.solve_modes` never cuts one).
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import itertools
import math
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .assembly import assemble
from .eigen import EigenSolveError, band_cut, rigid_body_modes, solve_modes

__all__ = ["CORE_SLOTS", "MirrorClass", "MirrorSplit", "PAD_MIN_MIRRORS", "PaddedFactorization", "mirror_split", "solve_mirrored_modes", "THREADS"]

#: Worker threads for the classes (each runs one single-threaded factorization at a time).
THREADS = 2
#: A semaphore of cores that other work of this build holds too (``aas_gym.object_build``: CoACD
#: holds one of two while it runs), or None. With more classes than :data:`THREADS` each class
#: solve holds one while it runs: while CoACD runs the four classes of a two-mirror body take the
#: other core in turn instead of three threads sharing two cores, which left CoACD, the longer job,
#: finishing alone at the end. Two classes (one mirror: the mug) start at once and hold none
#: (see :func:`solve_mirrored_modes`).
CORE_SLOTS: contextvars.ContextVar = contextvars.ContextVar("mirror_core_slots", default=None)
#: PARDISO factorizes a class padded to node blocks (:class:`PaddedFactorization`) when the mesh
#: has at least this many mirrors, else the class's scalar CSR (the same modes to round-off).
#: Measured, K - sigma M of each class, one thread: with two mirrors (bottle, can, box, glass)
#: padding halves the factor and its time (bottle: 71-87 -> 47 MB, 0.40-0.49 -> 0.24-0.29 s per
#: class; in the cold build, beside CoACD, the classes' CPU 3.2 -> 2.4 s); with one (measured on a
#: mirror-split mug) it grew the factor (132 -> 148 MB) and cost
#: as much or more beside CoACD.
PAD_MIN_MIRRORS = 2
#: Nodes that mirror onto each other must agree to this, relative to the mesh's extent.
MATCH_RTOL = 1e-9


@dataclasses.dataclass(frozen=True)
class MirrorClass:
    """One symmetry class: its signs, its dofs in the orthant's numbering and its rigid modes.

    Attributes:
        signs: +1 (even) or -1 (odd) per mirror axis.
        dofs: (d,) indices into the orthant's 3 n_o dofs that the class allows.
        weights: (d,) the diagonal D: sqrt(2^k / orbit size) of each dof's node.
        rigid: indices (0-5: translations x, y, z, rotations about x, y, z) of the rigid-body
            modes in the class.
    """

    signs: tuple
    dofs: np.ndarray
    weights: np.ndarray
    rigid: tuple


@dataclasses.dataclass(frozen=True)
class MirrorSplit:
    """A mesh split by its mirrors (see the module docstring).

    Attributes:
        axes: The mirror axes (0 x, 1 y, 2 z).
        orthant_nodes: (n_o,) full node index of each orthant node (all mirror coordinates >= 0).
        images: (n_o, 2^k) full node index of each orthant node's image under each mirror
            combination (column g: the axes in bit mask g mirrored).
        orthant_elements: (e_o, nodes per element) the orthant's elements in orthant numbering.
        centre_m: (3,) a point on every mirror plane (the rigid-body rotations' centre).
        orbit: (n_o,) the number of distinct images of each orthant node (1, 2, ..., 2^k).
        n_nodes: Nodes of the whole mesh.
        classes: The 2^k :class:`MirrorClass` es.
    """

    axes: tuple
    orthant_nodes: np.ndarray
    images: np.ndarray
    orthant_elements: np.ndarray
    centre_m: np.ndarray
    orbit: np.ndarray
    n_nodes: int
    classes: tuple

    def assemble(self, nodes_m: np.ndarray, material, element: str = "p2"):
        """(K_o, M_o): stiffness and mass of the orthant's elements alone (3 n_o dofs); each class
        takes its part (:meth:`class_matrices`, in its own thread)."""
        return assemble(nodes_m[self.orthant_nodes], self.orthant_elements, material, element)

    def class_matrices(self, orthant_matrices, c: MirrorClass):
        """(K_c, M_c) = D A_o[S, S] D of the class ``c`` from :meth:`assemble`'s matrices."""
        out = []
        for A in orthant_matrices:
            sub = A[c.dofs][:, c.dofs].tocsr()
            rows = np.repeat(np.arange(sub.shape[0]), np.diff(sub.indptr))
            sub.data *= c.weights[rows] * c.weights[sub.indices]
            out.append(sub)
        return tuple(out)

    def weighted_node_mass(self, orthant_matrices):
        """M_o's node-level matrix m_ij (w_i w_j) (n_o square): M_o is a multiple of the 3 x 3
        identity in every node block and the weights D = w are one per node and the same in
        every class, so this one matrix serves every class's :meth:`class_mass_product`."""
        M_o = orthant_matrices[1]
        n_o = len(self.orthant_nodes)
        node = M_o[0::3][:, 0::3].tocsr()  # m_ij: every component's entries are the same
        node.sort_indices()
        w = np.sqrt(2.0 ** len(self.axes) / self.orbit)
        rows = np.repeat(np.arange(n_o), np.diff(node.indptr))
        node.data = node.data * (w[rows] * w[node.indices])
        return node

    def class_mass_product(self, node_mass, c: MirrorClass):
        """``X -> M_c @ X`` for (d, k) blocks, bit for bit the CSR product with
        :meth:`class_matrices`' M_c, at the node level (``node_mass``:
        :meth:`weighted_node_mass`): M_c's entries are those of the node-level matrix, computed
        as :meth:`class_matrices` computes them, and each row's sum runs over the same columns in
        the same order (a disallowed dof contributes an exact zero). The product reads a third
        of the indices (measured on the mug's classes, k = 3: the Krylov iteration's mass
        products 2.5x cheaper)."""
        n_o = len(self.orthant_nodes)
        dofs = c.dofs
        full = len(dofs) == 3 * n_o

        def product(X: np.ndarray) -> np.ndarray:
            k = X.shape[1]
            if full:
                Xf = np.ascontiguousarray(X)
            else:
                Xf = np.zeros((3 * n_o, k))
                Xf[dofs] = X
            Y = (node_mass @ Xf.reshape(n_o, 3 * k)).reshape(3 * n_o, k)
            return Y if full else Y[dofs]

        return product

    def rigid_modes(self, nodes_m: np.ndarray, c: MirrorClass) -> np.ndarray:
        """(d, r) the class's rigid-body modes in its coordinates (span only: T^T of the modes)."""
        R = rigid_body_modes(nodes_m[self.orthant_nodes], centre_m=self.centre_m)
        return R[c.dofs][:, list(c.rigid)] * np.sqrt(self.orbit[c.dofs // 3])[:, None]

    def expand(self, c: MirrorClass, V: np.ndarray) -> np.ndarray:
        """(3 n, r) the whole mesh's mode shapes T V of the class's (d, r) ``V``."""
        k = len(self.axes)
        n_o = len(self.orthant_nodes)
        full_o = np.zeros((3 * n_o, V.shape[1]))
        full_o[c.dofs] = V * (1.0 / np.sqrt(self.orbit[c.dofs // 3]))[:, None]
        full_o = full_o.reshape(n_o, 3, -1)
        U = np.zeros((self.n_nodes, 3, V.shape[1]))
        for g in range(2 ** k):  # every image gets its signs (a node on a plane is written twice, alike)
            sign = np.ones(3)
            for bit, a in enumerate(self.axes):
                if g >> bit & 1:
                    sign *= c.signs[bit]
                    sign[a] = -sign[a]
            U[self.images[:, g]] = full_o * sign[None, :, None]
        return U.reshape(3 * self.n_nodes, -1)


class PaddedFactorization:
    """A class's K_c - sigma M_c factorized at the orthant's full 3 n_o dofs, in 3 x 3 node blocks.

    A class's dof count is rarely a multiple of 3 (a node on a mirror plane keeps one or two
    components), so PARDISO got it as scalar CSR and found node blocks itself (variable block
    rows). Embedded at the orthant's dofs, each disallowed dof a decoupled diagonal entry, the
    matrix is node blocks again and PARDISO's analysis takes the node graph as given (where that
    pays: :data:`PAD_MIN_MIRRORS`). A right-hand side is zero at the padded dofs, so the
    solution is zero there and equals the class's solve up to the round-off of another (equally
    valid) elimination order; the padded dofs have positive pivots, so the inertia
    (``n_negative``) is the class's.
    """

    def __init__(self, fact, dofs: np.ndarray, n_full: int):
        self._f, self._dofs, self._n = fact, dofs, n_full
        self.name, self.exact_solves = fact.name, fact.exact_solves
        self.n_negative, self.factor_mb = fact.n_negative, fact.factor_mb
        self.factor_nnz = getattr(fact, "factor_nnz", None)

    @classmethod
    def shifted(cls, K, M, sigma: float, dofs: np.ndarray, n_full: int, solver: str):
        """The factorization of K - sigma M (class CSR matrices) padded to ``n_full`` dofs."""
        import scipy.sparse

        from .direct_solver import factorize

        A = scipy.sparse.csr_matrix(K - sigma * M)  # the entries solve_modes' own shift would hold
        A.sort_indices()
        pad = np.setdiff1d(np.arange(n_full), dofs, assume_unique=True)
        # A padded row's one entry goes before the class rows that follow it (np.insert keeps
        # the order of insertions at one index); dofs ascending: each row stays sorted.
        at = A.indptr[np.searchsorted(dofs, pad)]
        indices = np.insert(dofs[A.indices], at, pad)
        data = np.insert(A.data, at, float(np.median(np.abs(A.diagonal()))))  # decoupled, positive
        counts = np.ones(n_full, np.int64)
        counts[dofs] = np.diff(A.indptr)
        indptr = np.zeros(n_full + 1, np.int64)
        np.cumsum(counts, out=indptr[1:])
        full = scipy.sparse.csr_matrix((data, indices, indptr), shape=(n_full, n_full))
        full.has_sorted_indices = True
        return cls(factorize(full, solver), dofs, n_full)

    def solve(self, B: np.ndarray) -> np.ndarray:
        """(K_c - sigma M_c)^-1 B for a (d, k) block."""
        B = np.asarray(B, dtype=np.float64)
        full = np.zeros((self._n, B.shape[1]), order="F")
        full[self._dofs] = B
        return self._f.solve(full)[self._dofs]


def _translation_parity(c: int, a: int) -> int:
    """Sign of a translation along ``c`` under the mirror across axis ``a``'s plane."""
    return -1 if c == a else 1


def _rotation_parity(c: int, a: int) -> int:
    """Sign of a rotation about ``c`` under the mirror across axis ``a``'s plane (a rotation is
    an axial vector: the mirror keeps the rotation about its own normal and flips the others)."""
    return 1 if c == a else -1


def mirror_split(nodes_m: np.ndarray, elements: np.ndarray, axes) -> MirrorSplit | None:
    """The split of a mesh by the mirrors across the coordinate planes ``axes``, or None when
    the nodes or the elements do not mirror onto themselves (then solve the whole problem)."""
    from scipy.spatial import cKDTree

    from ..mesh.tets import row_codes

    axes = tuple(sorted(int(a) for a in axes))
    if not axes or len(set(axes)) != len(axes) or not all(0 <= a < 3 for a in axes):
        return None
    nodes_m = np.asarray(nodes_m, float)
    elements = np.asarray(elements)
    n = len(nodes_m)
    tol = MATCH_RTOL * max(float(np.abs(nodes_m).max()), 1e-300)
    tree = cKDTree(nodes_m)
    perms = []
    for a in axes:
        image = nodes_m.copy()
        image[:, a] = -image[:, a]
        dist, idx = tree.query(image)
        if not np.all(dist <= tol) or not np.array_equal(idx[idx], np.arange(n)):
            return None
        perms.append(idx)
    # The elements must mirror onto elements (corner sets), and none may straddle a plane.
    corners = np.sort(elements[:, :4], axis=1)
    codes = row_codes(corners)
    if codes is None:
        return None
    known = np.sort(codes)
    for p in perms:
        mirrored = row_codes(np.sort(p[elements[:, :4]], axis=1))
        if mirrored is None or not np.array_equal(np.sort(mirrored), known):
            return None
    inside = np.all(nodes_m[:, axes] >= -tol, axis=1)  # the closed orthant
    elem_inside = inside[elements].all(axis=1)
    if np.count_nonzero(elem_inside) * 2 ** len(axes) != len(elements):
        return None
    orthant_nodes = np.flatnonzero(inside)
    images = np.empty((len(orthant_nodes), 2 ** len(axes)), np.int64)
    for g in range(2 ** len(axes)):
        idx = orthant_nodes.copy()
        for bit in range(len(axes)):
            if g >> bit & 1:
                idx = perms[bit][idx]
        images[:, g] = idx
    renumber = np.full(n, -1, np.int64)
    renumber[orthant_nodes] = np.arange(len(orthant_nodes))
    orthant_elements = renumber[elements[elem_inside]]
    centre = nodes_m.mean(axis=0)
    centre[list(axes)] = 0.0
    on_plane = np.stack([images[:, 1 << bit] == orthant_nodes for bit in range(len(axes))], 1)  # (n_o, k)
    orbit = 2 ** (len(axes) - on_plane.sum(axis=1))
    classes = []
    for signs in itertools.product((1, -1), repeat=len(axes)):
        allowed = np.ones((len(orthant_nodes), 3), bool)
        for bit, a in enumerate(axes):
            for comp in range(3):
                # On the plane the mirror fixes the node: its dof survives only if the class's
                # sign times the component's own sign under the mirror is +1.
                if signs[bit] * _translation_parity(comp, a) != 1:
                    allowed[on_plane[:, bit], comp] = False
        dofs = np.flatnonzero(allowed.ravel())
        weights = np.sqrt(2.0 ** len(axes) / orbit[dofs // 3])
        rigid = tuple([c for c in range(3) if all(signs[b] == _translation_parity(c, a) for b, a in enumerate(axes))]
                      + [3 + c for c in range(3)
                         if all(signs[b] == _rotation_parity(c, a) for b, a in enumerate(axes))])
        classes.append(MirrorClass(tuple(signs), dofs, weights, rigid))
    return MirrorSplit(axes, orthant_nodes, images, orthant_elements, centre, orbit, n, tuple(classes))


def _merged_cut(lam: np.ndarray, lam_max: float, cluster_rtol: float) -> int:
    """Modes of the merged (ascending) set to keep: as the whole problem's solve keeps them."""
    n = band_cut(lam, lam_max, cluster_rtol)
    return len(lam) if n is None else n


def solve_mirrored_modes(split: MirrorSplit, nodes_m: np.ndarray, orthant_matrices, max_frequency_hz: float, *,
                         cluster_rtol: float = 2e-3, residual_tol: float = 1e-6, progress=None,
                         solver: str | None = None, info: dict | None = None):
    """The whole body's modes up to ``max_frequency_hz`` from its classes' problems.

    Args:
        split: :func:`mirror_split` of the mesh.
        orthant_matrices: (K_o, M_o) of the orthant's elements (:meth:`MirrorSplit.assemble`).
        Others as :func:`sensors.fem.eigen.solve_modes`.

    Returns:
        (lambdas (r,) ascending, U (3 n, r) with U^T M U = I), as ``solve_modes`` on the whole.
    """
    say = progress or (lambda msg: None)
    info = {} if info is None else info
    lam_max = (2.0 * math.pi * max_frequency_hz) ** 2
    bands = [lam_max] * len(split.classes)
    results: list = [None] * len(split.classes)
    infos: list = [{} for _ in split.classes]

    prepared: list = [None] * len(split.classes)  # (K_c, M_c, rigid modes) per class, made in its thread

    node_mass = split.weighted_node_mass(orthant_matrices)  # one for every class

    # Read here: the pool's threads do not inherit the caller's context. With no more classes than
    # threads (the mug's two) every class starts at once beside CoACD, three threads on two cores:
    # waiting for a slot ran them one after the other on one core (the mug: 0.7 s before the
    # classes + 2 x 1.9 s, where CoACD's 3.3 s left its core idle at the end).
    slots = CORE_SLOTS.get() if len(split.classes) > THREADS else None

    def solve(i):
        with slots if slots is not None else contextlib.nullcontext():
            return solve_class(i)

    def factorize_class(K, M, sigma, i, name):
        if name != "pardiso" or len(split.axes) < PAD_MIN_MIRRORS:  # SuperLU orders scalar rows anyway
            from .direct_solver import factorize

            return factorize(K - sigma * M, name)
        return PaddedFactorization.shifted(K, M, sigma, split.classes[i].dofs, 3 * len(split.orthant_nodes), name)

    def solve_class(i):
        cpu = time.thread_time()
        if prepared[i] is None:
            prepared[i] = (*split.class_matrices(orthant_matrices, split.classes[i]),
                           split.rigid_modes(nodes_m, split.classes[i]),
                           split.class_mass_product(node_mass, split.classes[i]))
        K, M, R, mass = prepared[i]
        infos[i] = {}
        f_hz = math.sqrt(bands[i]) / (2.0 * math.pi)
        result = solve_modes(K, M, None, f_hz, cluster_rtol=cluster_rtol, residual_tol=residual_tol, solver=solver,
                             rigid_modes=R, info=infos[i], mass_product=mass,
                             factorize_shifted=lambda sigma, name: factorize_class(K, M, sigma, i, name))
        infos[i]["cpu_s"] = time.thread_time() - cpu  # this class's own cost, whatever else runs
        return result

    todo = list(range(len(split.classes)))
    with ThreadPoolExecutor(max_workers=min(THREADS, len(todo)), thread_name_prefix="mirror") as pool:
        while todo:
            say(f"eigensolve: {len(todo)} symmetry classes")
            for i, result in zip(todo, pool.map(solve, todo)):  # in class order: deterministic
                results[i] = result
            lam = np.sort(np.concatenate([r[0] for r in results]))
            n = _merged_cut(lam, lam_max, cluster_rtol)
            lam_end = float(lam[n - 1]) if n else 0.0
            # A class whose band stopped short of the merged set's last cluster may hold one
            # more of its modes: raise its band past it and solve it again (rare).
            reach = lam_end * (1.0 + 2.0 * cluster_rtol)
            todo = [i for i, r in enumerate(results)
                    if bands[i] < reach and (len(r[0]) == 0 or r[0][-1] < lam_end)]
            for i in todo:
                bands[i] = reach * (1.0 + 1e-12)
    lam = np.concatenate([r[0] for r in results])
    owner = np.concatenate([np.full(len(r[0]), i) for i, r in enumerate(results)])
    order = np.lexsort((owner, lam))  # by eigenvalue, ties by class
    n = _merged_cut(lam[order], lam_max, cluster_rtol)
    order = order[:n]
    U = np.empty((3 * split.n_nodes, n))
    for i, (lam_i, V) in enumerate(results):
        cols = np.flatnonzero(owner[order] == i)
        if len(cols):
            # The class's own modes in order of eigenvalue: its first len(cols) ones.
            U[:, cols] = split.expand(split.classes[i], V[:, : len(cols)])
    if not np.all(np.isfinite(U)):
        raise EigenSolveError("eigenvectors contain non-finite values")
    # The classes ran side by side: the factorization's wall is the longest class's; solves and
    # blocks are listed per class ("8+8": two classes of 8 block solves).
    info.update(solver=infos[0].get("solver"), mirror_axes=split.axes,
                factor_mb=sum(d.get("factor_mb") or 0.0 for d in infos),
                factor_s=max(d.get("factor_s", 0.0) for d in infos),
                solves="+".join(str(d.get("solves", 0)) for d in infos),
                block="+".join(str(d.get("block", "-")) for d in infos),
                cpu_s=sum(d["cpu_s"] for d in infos),
                classes=[dict(d, signs=c.signs, dof=len(c.dofs)) for d, c in zip(infos, split.classes)])
    return lam[order], U
