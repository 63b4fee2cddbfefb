"""The rigid-body modes and the static correction at contact points of a free object's FEM model.

A spring at a contact point changes the object's modes in two ways that its truncated elastic
modes U cannot express: it turns the six rigid-body motions into suspension modes, and it
bends the object locally near the point (the residual flexibility of every mode above the
band).  Without the rigid-body modes a grounded spring of 1e7 N/m on the 200 mm aluminium bar
is -11 % off the true frequency shift, with them but without a static correction +9.5 %
(issue 26).  A Rayleigh-Ritz basis [R, U, Psi] fixes both:

- R: the six rigid-body modes (translations, rotations about the centroid), mass-normalised;
- Psi: attachment (residual-flexibility) modes, one per constrained direction d at a contact
  point p: the static response x = (K + sigma M)^-1 f to the consistent load f = N(p)^T d of
  a unit force, with the load's rigid-body part removed first (inertia relief, so that the
  free body's singular K is no problem) and then made M-orthogonal to R and U and
  M-orthonormal among themselves.  The shift sigma = 1e-3 w_1^2 only regularises: what x
  contains of the modes above the band changes by sigma / w_k^2 < 1e-3, and the basis is a
  span, not a set of amplitudes (Craig & Bampton / MacNeal's residual flexibility; R. R.
  Craig Jr. and A. J. Kurdila, *Fundamentals of Structural Dynamics*, 2006, ch. 17-18).

The reduced mass matrix of [R, U, Psi] is the identity and its stiffness
blockdiag(0, diag(w^2), Psi^T K Psi) (plus the rounding-level coupling Psi^T K U, kept).

Cost: one sparse factorization of K + sigma M per model (kept in an LRU,
``CACHE_SIZES["modal.flexibility"]``: the same time and memory as one shift of the model's own
eigen-solve), then per contact set one triangular solve per direction and O(n_dof r a) for the
orthogonalization (``benchmarks/contact_stiffness.py``).  Nothing is added to the model file:
storing the correction for every possible contact point would be the full flexibility matrix.

Unit loads reused (the default): the projected solve is linear in the load, and the load of a
point is a combination of unit loads at the nodes of its element (the shape functions times
the direction).  So each node's three projected unit-load solves P (K + sigma M)^-1 e_(3n+j)
are solved once and kept (side by side in a :class:`UnitLoadStore` per model,
``CACHE_SIZES["modal.unit_loads"]`` nodes, least recently used giving up its slot), and a
contact set's attachment vectors are their combination (one sparse product: each vector uses
the 30 columns of its element's nodes) minus the inertia relief's (also solved once);
Psi^T K Psi follows from the solves without K and Psi^T K U from per-node rows kept with
them (see ``attachment_modes``), and M Psi is kept with the vectors for state transfers.
The same span as the direct solve, summed in another order: the reduced stiffness agrees to
rounding (eigenvalues within 1e-8 relative, 1.5e-9 measured on the 200 mm wood bar; the span
within 1e-9: ``tests/test_unit_load_reuse.py``); ``reuse_unit_loads=False`` (or
:data:`REUSE_UNIT_LOADS`) is the direct solve, the reference.  Random grasps of the same
object touch the same few elements over and over, so after a few contact sets a new one
needs no solve at all: 36 -> 12 ms per contact set of GraspPosition-v0's wood bar.

Node-pair products (the default, :data:`GRAM_PRODUCTS`): the store also keeps Y_i^T M Y_j
between its nodes (and Y_i^T M relief), made once when a node comes in.  A contact set's
X = Y C - relief B then has X^T M X, X^T K X, X^T K U, its values at points and its products
with another set's vectors (a state transfer) as small dense algebra on C, B and those blocks:
nothing n_dof-sized per contact set, Psi (n_dof x a) formed only when someone asks for it
(:class:`AttachmentBasis`).  ``GRAM_PRODUCTS = False`` forms Psi explicitly (the reference;
``tests/test_gram_products.py``: 1e-9 relative).
"""

from __future__ import annotations

import contextlib

import numpy as np

from .._infra.cache import default_cache_dir
from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from ..fem.assembly import shape_functions
from ..fem.direct_solver import factorize
from ..fem.eigen import rigid_body_modes
from . import unit_load_files
from .basis import check_points_m

__all__ = ["GRAM_PRODUCTS", "KEEP_NODE_ROWS", "NODE_SET_BLOCKS", "MAX_ATTACHMENT_VECTORS", "MIN_PROJECTED_COLUMNS", "MIN_SOLVE_COLUMNS", "SOLVE_COLUMN_BLOCK", "REUSE_UNIT_LOADS", "SINGLE_ELASTIC_PROJECTION", "AttachmentBasis", "reference_paths", "ContactFlexibility", "UnitLoadStore",
           "RitzGeometry", "contact_flexibility", "located_once", "nodal_at"]

#: The most attachment vectors (constrained directions, up to 3 per contact) one contact set
#: may add: 20 contacts with normal and tangential springs.  Each costs one solve with the
#: model's factorization and a column of the reduced eigenproblem; the limit keeps a mistaken
#: contact list (every mesh vertex of a MuJoCo contact patch) from building a basis of
#: thousands of columns.  Raise it here when a scene really needs more.
MAX_ATTACHMENT_VECTORS = 60
#: Whether attachment modes combine kept unit-load solves (True, fast) or solve each contact
#: set's loads directly (False: the reference path, e.g. for a benchmark's error column).
#: Read at each call; ``sensors.modal.spring_modes`` keys its cache on it.
REUSE_UNIT_LOADS = True
#: Whether an attachment basis from kept unit-load solves stays implicit (True, fast): its
#: reduced matrices and state transfers come from the store's node-pair products Y_i^T M Y_j
#: and Psi is formed (n_dof x a) only when asked for; False: Psi formed explicitly (the
#: reference).  Read at each call; the attachment-basis and spring-mode caches key on it.
GRAM_PRODUCTS = True
#: Whether a kept unit-load solve is made M-orthogonal to the kept elastic modes U in one pass
#: once its rigid-body part is removed (twice) (True, fast), or R and U both twice as every
#: other projection here (False, the reference).  The rigid part of (K + sigma M)^-1 e is about
#: 1/sigma, ~1e3 times the result: removing it leaves rounding that a second, cheap (6 column)
#: pass removes; the elastic part is of the result's own size (0.8-0.9 of it on the paper's
#: objects), so one pass leaves it at rounding (|U^T M Y| 1e-15 of |Y|, 1e-18 with two; Y within
#: 5e-14 of the reference).  It halves the reads of the n_dof x r mode matrices, which cost as
#: much as the solve itself for a node or two at a time (24 of 55 ms per node at 22k dof and
#: 102 modes).  Read when a node is solved: ``clear_all()`` after changing it.
SINGLE_ELASTIC_PROJECTION = True
#: The fewest columns a call of :meth:`UnitLoadStore.columns` solves, and projects (zero
#: columns pad a call for fewer nodes).  A node's solve must be the same bytes whichever call
#: solved it (how many nodes a call solves depends on what the store held), and narrow calls
#: round otherwise: MKL's PARDISO solves 3 right-hand sides (one node) on another path than 4
#: or more (2e-15 of the solve), and the projection's BLAS products of 3-6 columns differ from
#: 9 or more; after the projection (whose rigid part cancels ~1e3 times the result) a kept
#: solve differed by 1.5e-12 (aluminium tube).  From these widths on, each column's bytes are its own whatever its
#: neighbours (measured to 192 solve and 48 projected columns; ``tests/test_unit_load_batches.py``).
#: The padding costs a one-node call one more solve column: 1.22x its solve (16.1 -> 19.7 ms,
#: aluminium tube, 22k dof), 1.08x on the wood bar.
MIN_SOLVE_COLUMNS = 4
MIN_PROJECTED_COLUMNS = 9
#: A solve call's width is a multiple of this: on AVX2 machines (AMD EPYC, measured) PARDISO
#: takes right-hand sides in blocks of 4 and rounds the columns of a last, partial block
#: otherwise, so a node's columns changed with their place in the call (the wood bar: the
#: node in columns 4-5 of a 6-wide call, 6-8 of a 9-wide one); in whole blocks they did not.
#: 8 covers blocks of 4 and 8.
SOLVE_COLUMN_BLOCK = 8
#: Whether the kept solves' rows at kept nodes are also kept in a small dense block array
#: (:meth:`UnitLoadStore.rows`, True, fast) or gathered from the n_dof-long columns each time
#: (False, the reference).  A contact set's attachment vectors at its loaded nodes and its
#: springs' element nodes are such rows; gathered from ``Y`` (tens of MB, column-major) nearly
#: every value is a cache miss, from the block array a few kB are read.  The same values
#: (copies): the same products, bit for bit (``tests/test_unit_load_rows.py``).  Read at each call.
KEEP_NODE_ROWS = True
#: Whether the blocks of the store that a contact set's attachment basis gathers by its nodes
#: alone (Y^T M Y between them, Y^T M relief, Y^T K U, Y and the relief at their dofs) are kept
#: per node set (True, fast) or gathered anew for every contact set (False, the reference).
#: Randomized episodes of one object put their contacts at new points of the same few elements
#: (GraspPosition-v0: 1,803 contact sets on 28 node sets): only the shape-function weights C
#: change.  An entry is used only while every slot it read holds the same solve (slot
#: versions), and the store is still asked for the columns (recency, evicted nodes solved
#: again), so the values are the gathered ones: the same products, bit for bit
#: (``tests/test_node_set_blocks.py``).  The load pattern of a set of elements (its distinct
#: nodes, where each weight goes in C) is kept the same way.  Read at each call.
NODE_SET_BLOCKS = True


@contextlib.contextmanager
def reference_paths(reuse_unit_loads: bool = False, gram_products: bool = False):
    """Within the block, :data:`REUSE_UNIT_LOADS` and :data:`GRAM_PRODUCTS` as given (default:
    both reference paths); the earlier values come back after it, also on an error."""
    global REUSE_UNIT_LOADS, GRAM_PRODUCTS
    saved = REUSE_UNIT_LOADS, GRAM_PRODUCTS
    REUSE_UNIT_LOADS, GRAM_PRODUCTS = bool(reuse_unit_loads), bool(gram_products)
    try:
        yield
    finally:
        REUSE_UNIT_LOADS, GRAM_PRODUCTS = saved


# The regularising shift of K, relative to the first elastic eigenvalue (see the docstring).
_SHIFT = 1e-3
# Attachment vectors whose M-norm after orthogonalisation is below this fraction of the
# largest are (numerically) in the span of the others and dropped.
_DEPENDENT = 1e-10
# Shape-function weights below this are rounding (a point on a vertex, edge or face has exact
# zeros there; a contact point moved by a rigid motion lands ~1e-13 m off its face, a weight
# of ~1e-11): the reused path leaves those nodes out (a load change below 1e-9 relative).
_NEGLIGIBLE_WEIGHT = 1e-9

_CACHE: LRU = LRU(CACHE_SIZES["modal.flexibility"])


def nodal_at(model, nodal: np.ndarray, points_m) -> np.ndarray:
    """A nodal field (n_nodes, 3, k) of ``model``'s mesh at points (n, 3): (n, 3, k),
    interpolated with the element shape functions as ``ModalModel.mode_shapes_at``."""
    p = check_points_m(points_m)
    tet, bary = model.locator.locate(p)
    N = shape_functions(bary, model.element)
    return np.einsum("pa,paxr->pxr", N, nodal[model.elements[tet]])


class ContactFlexibility:
    """A free ``ModalModel``'s matrices for the static correction: K, M, the factorization of
    K + sigma M and the mass-normalised rigid-body modes (built once per model)."""

    def __deepcopy__(self, memo):
        # A per-model cache around a factorization (ctypes handles cannot be copied): an env's
        # deep copy shares it, as it shares the model.
        return self

    def __init__(self, model) -> None:
        self.model = model
        K, M = model.assemble_matrices()
        self.K, self.M = K.tocsr(), M.tocsr()
        n_nodes = len(model.nodes_m)
        self.centroid_m = model.nodes_m.mean(axis=0)
        R0 = rigid_body_modes(model.nodes_m)
        G = R0.T @ (self.M @ R0)
        d, Q = np.linalg.eigh(0.5 * (G + G.T))
        self.rigid_transform = Q / np.sqrt(d)            # R = R0 @ rigid_transform, R^T M R = I
        self.R = R0 @ self.rigid_transform
        self.U = model.mode_matrix()
        self.MR, self.MU = self.M @ self.R, self.M @ self.U
        self.KU = self.K @ self.U
        lam1 = float(model.eigenvalues[0]) if model.n_modes else 1.0
        self.sigma = _SHIFT * lam1                       # the regularising shift [rad^2/s^2]
        self.factor = factorize((self.K + self.sigma * self.M).tocsc())
        self.n_dof = 3 * n_nodes
        # P (K + sigma M)^-1 M R: what the inertia relief subtracts from every unit-load solve
        self.relief = self._projected(np.asarray(self.factor.solve(self.MR)).reshape(self.n_dof, -1))
        self.relief_ku = self.relief.T @ self.KU                   # its Y^T K U rows (6, r)
        self.mass_relief = self.M @ self.relief
        self.relief_gram = self.relief.T @ self.mass_relief        # relief^T M relief (6, 6)
        self.unit_loads = UnitLoadStore(self)
        self._bases: LRU = LRU(CACHE_SIZES["modal.attachment_bases"])
        self._patterns: LRU = LRU(CACHE_SIZES["modal.node_set_blocks"])    # NODE_SET_BLOCKS

    def _projected(self, X: np.ndarray, elastic_passes: int = 2) -> np.ndarray:
        """``X`` made M-orthogonal to the rigid-body and kept elastic modes (in place): each
        removed twice (M-orthogonal to rounding), or with ``elastic_passes=1`` the elastic
        modes once, after the rigid-body modes' two passes."""
        for i in range(2):
            X -= self.R @ (self.MR.T @ X)
            if elastic_passes == 2 or i == 1:
                X -= self.U @ (self.MU.T @ X)
        return X

    def unit_load_projected(self, X: np.ndarray) -> np.ndarray:
        """``X`` (unit-load solves) projected as :meth:`_projected` does, with one elastic pass
        under :data:`SINGLE_ELASTIC_PROJECTION`."""
        return self._projected(X, 1 if SINGLE_ELASTIC_PROJECTION else 2)

    def geometry(self) -> "RitzGeometry":
        """What the coupled modes keep of this (the mesh model, rigid-body modes and M): not
        the factorization, K or the mode matrices, which only the construction needs."""
        return RitzGeometry(self.model, self.centroid_m, self.rigid_transform, self.M)

    def rigid_at(self, points_m) -> np.ndarray:
        """The mass-normalised rigid-body modes at points (n, 3): (n, 3, 6)."""
        p = np.atleast_2d(np.asarray(points_m, float)) - self.centroid_m
        x, y, z = p.T
        R0 = np.zeros((len(p), 3, 6))
        R0[:, 0, 0] = R0[:, 1, 1] = R0[:, 2, 2] = 1.0
        R0[:, 1, 3], R0[:, 2, 3] = -z, y
        R0[:, 0, 4], R0[:, 2, 4] = z, -x
        R0[:, 0, 5], R0[:, 1, 5] = -y, x
        return R0 @ self.rigid_transform

    def attachment_modes(self, points_m: np.ndarray, directions: np.ndarray, reuse_unit_loads: bool | None = None):
        """``(Psi, K_psi, K_psi_u)``: attachment modes (n_dof, a) for unit forces at
        ``points_m`` (a, 3) along ``directions`` (a, 3), M-orthonormal and M-orthogonal to
        the rigid-body and kept elastic modes; their stiffness Psi^T K Psi and the coupling
        Psi^T K U (rounding level).  ValueError beyond :data:`MAX_ATTACHMENT_VECTORS`.
        ``reuse_unit_loads``: combine the kept unit-load solves (module docstring); False:
        solve the contact set's loads directly (the reference); None: :data:`REUSE_UNIT_LOADS`."""
        return self._attachment(points_m, directions, reuse_unit_loads)[:3]

    def _attachment(self, points_m, directions, reuse_unit_loads):
        """:meth:`attachment_modes` and M Psi (None where it was not made on the way)."""
        a = len(points_m)
        if a > MAX_ATTACHMENT_VECTORS:
            raise ValueError(
                f"{a} constrained contact directions need {a} attachment vectors (about {a * self.n_dof * 8 / 1e6:.0f} MB "
                f"and a {6 + self.U.shape[1] + a}-column eigenproblem per contact set); the limit is "
                f"{MAX_ATTACHMENT_VECTORS} (20 contacts with normal and tangential springs): merge contact points "
                "or raise sensors.modal.static_correction.MAX_ATTACHMENT_VECTORS")
        if a == 0:
            return np.zeros((self.n_dof, 0)), np.zeros((0, 0)), np.zeros((0, self.U.shape[1])), np.zeros((self.n_dof, 0))
        model = self.model
        p = check_points_m(points_m)
        tet, bary = model.locator.locate(p)
        N = shape_functions(bary, model.element)                     # (a, n_el)
        nodes = model.elements[tet]                                  # (a, n_el)
        cols = np.arange(a)
        reuse = REUSE_UNIT_LOADS if reuse_unit_loads is None else reuse_unit_loads
        comb = self._combination(N, nodes, directions) if reuse else None
        reuse = comb is not None
        if reuse:
            distinct, C, B, dofs = comb
            X, MX = self.combined(distinct, C, B)
            XKU = C.T @ self.unit_loads.KU[self.unit_loads.columns(distinct)] - B.T @ self.relief_ku
        else:
            F = np.zeros((self.n_dof, a))
            for j in range(3):
                np.add.at(F, (3 * nodes + j, np.broadcast_to(cols[:, None], nodes.shape)), N * directions[:, j:j + 1])
            F -= self.MR @ (self.R.T @ F)                            # inertia relief: no rigid-body load
            X = self._projected(np.asarray(self.factor.solve(F)).reshape(self.n_dof, a))
            MX = self.M @ X
        G = X.T @ MX
        d, Q = np.linalg.eigh(0.5 * (G + G.T))
        keep = d > _DEPENDENT * max(float(d.max()), 1e-300)
        T = Q[:, keep] / np.sqrt(d[keep])
        Psi = X @ T
        if reuse:
            # X^T K X without K: (K + sigma M) X_raw = F_rel, X = X_raw minus its R and U parts,
            # K R = 0, K U = M U diag(w^2) and X M-orthogonal to R and U give
            # X^T K X = X^T F - sigma X^T M X, and X^T F is X at the loaded dofs times C.
            S = X[dofs].T @ C
            Kpsi = T.T @ (0.5 * (S + S.T) - self.sigma * G) @ T
            return Psi, 0.5 * (Kpsi + Kpsi.T), T.T @ XKU, MX @ T
        Kpsi = Psi.T @ (self.K @ Psi)
        return Psi, 0.5 * (Kpsi + Kpsi.T), Psi.T @ self.KU, None

    def _combination(self, N, nodes, directions):
        """``(distinct nodes, C (3 s, a), B (6, a), dofs (3 s,))``: the loads of a contact set
        as unit loads at its distinct nodes (C) and the relief's share R^T C (B); None when
        the set has more nodes than the store keeps (then solve directly)."""
        # Shape functions below _NEGLIGIBLE_WEIGHT are a point on a vertex or face seen from
        # the element's other nodes (rounding of its barycentric coordinates).
        used = np.abs(N) > _NEGLIGIBLE_WEIGHT
        if NODE_SET_BLOCKS:
            pattern = self._patterns.get_or_build((nodes.shape, nodes.tobytes(), used.tobytes()),
                                                  lambda: _LoadPattern(nodes, used, self.R))
            if pattern.distinct.size > self.unit_loads.capacity:
                return None
            C = pattern.loads(N, directions)
            return pattern.distinct, C, pattern.R_dofs.T @ C, pattern.dofs
        distinct, index = np.unique(nodes[used], return_inverse=True)
        if distinct.size > self.unit_loads.capacity:
            return None
        a = len(nodes)
        C = np.zeros((3 * distinct.size, a))
        cols_used = np.broadcast_to(np.arange(a)[:, None], nodes.shape)[used]
        for j in range(3):
            np.add.at(C, (3 * index + j, cols_used), (N * directions[:, j:j + 1])[used])
        dofs = (3 * distinct[:, None] + np.arange(3)).ravel()
        return distinct, C, self.R[dofs].T @ C, dofs

    def combined(self, nodes, C, B):
        """``(X, M X)`` (n_dof, a): the attachment vectors Y C - relief B of kept unit-load
        solves at ``nodes`` (solved now where not kept), formed explicitly."""
        store = self.unit_loads
        columns = store.columns(nodes)
        # one sparse product over the store's columns (30 of its rows per vector), no copy
        i, c = np.nonzero(C)
        from scipy.sparse import csr_matrix  # deferred: `import sensors` loads no SciPy sparse

        Ct = csr_matrix((C[i, c], (c, columns[i])), shape=(C.shape[1], store.Y.shape[1]))
        X = np.asarray(Ct @ store.Y.T).T - self.relief @ B
        MX = np.asarray(Ct @ store.MY.T).T - self.mass_relief @ B
        return X, MX

    def _implicit_basis(self, comb) -> "AttachmentBasis":
        """The :class:`AttachmentBasis` of a contact set from the store's node-pair products:
        nothing n_dof-sized is formed (:data:`GRAM_PRODUCTS`)."""
        distinct, C, B, dofs = comb
        store = self.unit_loads
        cols = store.columns(distinct)
        H, P, Yd, Rd, KU = store.node_set_blocks(distinct, cols)
        CHB = C.T @ H @ B
        G = C.T @ P @ C - CHB - CHB.T + B.T @ self.relief_gram @ B   # X^T M X
        Xd = Yd @ C - Rd @ B                                          # X at the loaded dofs
        XKU = C.T @ KU - B.T @ self.relief_ku
        d, Q = np.linalg.eigh(0.5 * (G + G.T))
        keep = d > _DEPENDENT * max(float(d.max()), 1e-300)
        T = Q[:, keep] / np.sqrt(d[keep])
        S = Xd.T @ C                                      # X^T F (see _attachment)
        Kpsi = T.T @ (0.5 * (S + S.T) - self.sigma * G) @ T
        return AttachmentBasis(None, 0.5 * (Kpsi + Kpsi.T), T.T @ XKU, None, self.M,
                               implicit=(self, distinct, C, B, T))

    def attachment_basis(self, points_m: np.ndarray, directions: np.ndarray) -> "AttachmentBasis":
        """The :class:`AttachmentBasis` of unit forces at ``points_m`` (a, 3) along
        ``directions`` (a, 3) (:meth:`attachment_modes`; kept for the same points and
        directions, as a coupled group's partner asks for its own again and again)."""
        pts = np.ascontiguousarray(points_m, dtype=float).reshape(-1, 3)
        dirs = np.ascontiguousarray(directions, dtype=float).reshape(-1, 3)
        key = (pts.tobytes(), dirs.tobytes(), bool(REUSE_UNIT_LOADS), bool(GRAM_PRODUCTS))
        return self._bases.get_or_build(key, lambda: self._basis(pts, dirs))

    def _basis(self, pts, dirs) -> "AttachmentBasis":
        if REUSE_UNIT_LOADS and GRAM_PRODUCTS and 0 < len(pts) <= MAX_ATTACHMENT_VECTORS:
            tet, bary = located_once(self.model.locator, check_points_m(pts))
            comb = self._combination(shape_functions(bary, self.model.element), self.model.elements[tet], dirs)
            if comb is not None:
                return self._implicit_basis(comb)
        return AttachmentBasis(*self._attachment(pts, dirs, None), self.M)


class _LoadPattern:
    """What :meth:`ContactFlexibility._combination` derives from a contact set's element nodes
    and which shape functions it keeps alone (:data:`NODE_SET_BLOCKS`): the distinct nodes, each
    kept weight's row and column in C, the nodes' dofs and the rigid-body modes there."""

    def __init__(self, nodes: np.ndarray, used: np.ndarray, R: np.ndarray) -> None:
        self.distinct, index = np.unique(nodes[used], return_inverse=True)
        self.shape = (3 * self.distinct.size, len(nodes))
        self.used = used
        self.cols = np.broadcast_to(np.arange(len(nodes))[:, None], nodes.shape)[used]
        self.rows = [3 * index + j for j in range(3)]
        # an element's nodes are distinct, so each (row, column) is written once: C's entries are
        # then np.add.at's 0.0 + w exactly (the + 0.0 makes a -0.0 weight +0.0, as that sum does)
        self.once = np.unique(np.stack([3 * index, self.cols]), axis=1).shape[1] == index.size
        self.dofs = (3 * self.distinct[:, None] + np.arange(3)).ravel()
        self.R_dofs = R[self.dofs]

    def loads(self, N: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """C (3 s, a): the unit forces along ``directions`` at the points as unit loads at the
        distinct nodes (shape-function weights ``N``)."""
        C = np.zeros(self.shape)
        for j in range(3):
            w = (N * directions[:, j:j + 1])[self.used]
            if self.once:
                C[self.rows[j], self.cols] = w + 0.0
            else:
                np.add.at(C, (self.rows[j], self.cols), w)
        return C


def located_once(locator, p: np.ndarray):
    """``locator.locate(p)`` with each run of repeated rows located once: a spring's normal and
    tangents share its point, so the located points are the springs' own, in their order, which
    the spring modes' Ritz rows then find kept in the locator (one location per contact set, not
    two).  A point's location does not depend on the batch it is in."""
    if len(p) < 2:
        return locator.locate(p)
    new = np.empty(len(p), bool)
    new[0] = True
    np.any(p[1:] != p[:-1], axis=1, out=new[1:])
    if new.all():
        return locator.locate(p)
    tet, bary = locator.locate(p[new])
    run = np.cumsum(new) - 1
    return tet[run], bary[run]


class AttachmentBasis:
    """Attachment vectors of one contact set (:meth:`ContactFlexibility.attachment_modes`):
    ``psi`` (n_dof, a), their stiffness ``stiffness`` (a, a) = Psi^T K Psi and ``coupling``
    (a, r) = Psi^T K U, :meth:`mass_psi` (M Psi), :meth:`nodal` (Psi at mesh nodes) and
    :meth:`mass_product` (Psi^T M Psi_other: a state transfer).

    Built from kept unit-load solves (:data:`GRAM_PRODUCTS`) it is implicit: Psi = (Y C -
    relief B) T is kept as its nodes, C, B and T, its rows and products come from the store
    (solving again what it evicted since), and ``psi`` is formed only when asked for."""

    def __init__(self, psi, stiffness, coupling, mass_psi, M, implicit=None) -> None:
        self._psi, self.stiffness, self.coupling = psi, stiffness, coupling
        self._M, self._mass_psi = M, mass_psi
        self._implicit = implicit            # (flex, nodes, C, B, T) or None
        # of an implicit basis: the nodes whose Psi rows are made (sorted) and the rows (k, 3, a)
        self._rows = (np.zeros(0, int), np.zeros((0, 3, self.size)))

    @property
    def psi(self) -> np.ndarray:
        """Psi (n_dof, a), formed on first use for an implicit basis."""
        if self._psi is None:
            flex, nodes, C, B, T = self._implicit
            X, MX = flex.combined(nodes, C, B)
            self._psi, self._mass_psi = X @ T, MX @ T
        return self._psi

    @property
    def size(self) -> int:
        """The number of attachment vectors a."""
        return int(self.stiffness.shape[0])

    def mass_psi(self) -> np.ndarray:
        """M Psi (n_dof, a)."""
        if self._mass_psi is None:
            self._mass_psi = self._M @ self.psi
        return self._mass_psi

    def nodal(self, nodes: np.ndarray) -> np.ndarray:
        """Psi at mesh ``nodes`` (k,): (k, 3, a)."""
        nodes = np.asarray(nodes)
        if self._implicit is None or self._psi is not None:
            return self.psi.reshape(-1, 3, self.size)[nodes]
        flex, own, C, B, T = self._implicit
        kept, values = self._rows
        missing = np.setdiff1d(nodes, kept)
        if missing.size:
            store = flex.unit_loads
            cols = store.columns(own)
            Ym, Rm = store.row_blocks(missing, cols)
            rows = (Ym @ C - Rm @ B) @ T
            kept = np.concatenate([kept, missing])
            order = np.argsort(kept, kind="stable")
            kept, values = kept[order], np.concatenate([values, rows.reshape(-1, 3, rows.shape[1])])[order]
            self._rows = kept, values
        return values[np.searchsorted(kept, nodes)]

    def mass_product(self, other: "AttachmentBasis") -> np.ndarray:
        """Psi^T M Psi_other (a, a_other), from the store's node-pair products when both are
        implicit bases of the same model and their nodes fit the store together."""
        if self._implicit is not None and other._implicit is not None and self._implicit[0] is other._implicit[0]:
            flex, na, Ca, Ba, Ta = self._implicit
            _, nb, Cb, Bb, Tb = other._implicit
            store = flex.unit_loads
            if np.union1d(na, nb).size <= store.capacity:
                ca = store.columns(na)
                cb = store.columns(nb)                  # evicts none of na (just used, fit together)
                ca = store.columns(na)
                H = store.relief_gram
                XMX = (Ca.T @ store.products(ca, cb) @ Cb - (Ca.T @ H[ca]) @ Bb - Ba.T @ (H[cb].T @ Cb)
                       + Ba.T @ flex.relief_gram @ Bb)
                return Ta.T @ XMX @ Tb
        return self.psi.T @ other.mass_psi()


class UnitLoadStore:
    """The kept unit-load solves of one model, side by side in one array so that a contact
    set's loads combine them with one sparse product (no copy of the columns it uses).

    ``Y`` (n_dof, 3 slots): each kept node's P (K + sigma M)^-1 [e_3n, e_3n+1, e_3n+2] in its
    slot's three columns, ``MY`` the same times M; ``KU`` (3 slots, r): their Y^T K U rows;
    ``gram`` (3 slots, 3 slots): Y_i^T M Y_j between kept nodes (the pairs asked for, made
    once: :meth:`products`) and ``relief_gram`` (3 slots, 6): Y_i^T M relief, so that a
    contact set of kept nodes whose pairs are known needs nothing n_dof-sized.  Which
    node holds which slot is an ``LRU`` (``CACHE_SIZES["modal.unit_loads"]`` nodes, emptied by
    ``clear_all``).  Each product is made the same way whatever the order nodes came in (the
    lower node's Y times the higher node's M Y), so results do not depend on history."""

    def __init__(self, flex: "ContactFlexibility", capacity: int | None = None) -> None:
        self.flex = flex
        self.capacity = CACHE_SIZES["modal.unit_loads"] if capacity is None else int(capacity)
        self.slots: LRU = LRU(self.capacity)               # node -> slot
        # zeros: the pages of slots never used are never touched (no memory until then)
        self.Y = np.zeros((flex.n_dof, 3 * self.capacity), order="F")
        self.MY = np.zeros((flex.n_dof, 3 * self.capacity), order="F")
        self.KU = np.zeros((3 * self.capacity, flex.U.shape[1]))
        self.gram = np.zeros((3 * self.capacity, 3 * self.capacity))
        self.known = np.zeros((self.capacity, self.capacity), bool)    # slot pairs whose gram is made
        self.relief_gram = np.zeros((3 * self.capacity, 6))
        self.slot_node = np.full(self.capacity, -1)      # the node each slot holds (-1: none)
        # KEEP_NODE_ROWS: node_rows[3 i:3 i+3, 3 j:3 j+3] = Y at the node of slot i, columns of
        # slot j, where row_known[i, j]; node_slot: the slot of each node (-1: none)
        self.node_rows = np.zeros((3 * self.capacity, 3 * self.capacity))
        self.row_known = np.zeros((self.capacity, self.capacity), bool)
        self.node_slot = np.full(flex.n_dof // 3, -1)
        # NODE_SET_BLOCKS: each slot's version (bumped when it takes a solve) and the blocks
        # gathered per node set, with the versions they were gathered at
        self.slot_version = np.zeros(self.capacity, np.int64)
        self._blocks: LRU = LRU(CACHE_SIZES["modal.node_set_blocks"])
        self._disk = None                                 # unit_load_files.UnitLoadFiles, made on first use

    def columns(self, nodes: np.ndarray) -> np.ndarray:
        """The store columns (3 per node, in order) of ``nodes`` (distinct, at most
        ``capacity``): missing ones read from their files (:mod:`.unit_load_files`) or else
        solved in one call."""
        slot = {}
        for n in nodes.tolist():
            k = self.slots.get(n)          # a hit makes it recent: not evicted below
            if k is not None:
                slot[n] = k
        missing = [n for n in nodes.tolist() if n not in slot]
        if missing:
            flex = self.flex
            m = 3 * len(missing)
            files = self._files()
            loaded = files.load(missing) if files is not None else {}
            solve = [n for n in missing if n not in loaded]
            Y = self._solved(solve) if solve else None
            at = {n: i for i, n in enumerate(missing)}
            if loaded:  # the read columns in their places, the solved ones in theirs (same width as a solve of all)
                Yr = np.zeros((flex.n_dof, max(_solve_width(m), MIN_PROJECTED_COLUMNS)), order="F")
                for n, y in loaded.items():
                    Yr[:, 3 * at[n]:3 * at[n] + 3] = y
                for j, n in enumerate(solve):
                    Yr[:, 3 * at[n]:3 * at[n] + 3] = Y[:, 3 * j:3 * j + 3]
                Y = Yr
            if solve and files is not None:   # a copy of their columns: the writer thread keeps it
                files.save(solve, Y[:, (3 * np.array([at[n] for n in solve])[:, None] + np.arange(3)).ravel()])
            KU = Y.T @ flex.KU
            MY = flex.M @ Y[:, :m]  # a sparse product: each column its own sums, padding not needed
            # the free slots, lowest first (the LRU may have been emptied by clear_all)
            free = sorted(set(range(self.capacity)) - set(self.slots.values()), reverse=True)
            for i, n in enumerate(missing):
                if free:
                    k = free.pop()
                else:                               # the least recently used node gives its slot
                    k = self.slots.oldest()[1]
                self.slots.put(n, k)
                self.Y[:, 3 * k:3 * k + 3] = Y[:, 3 * i:3 * i + 3]
                self.MY[:, 3 * k:3 * k + 3] = MY[:, 3 * i:3 * i + 3]
                self.KU[3 * k:3 * k + 3] = KU[3 * i:3 * i + 3]
                old = self.slot_node[k]
                if old >= 0 and self.node_slot[old] == k:
                    self.node_slot[old] = -1
                self.node_slot[n] = k
                self.slot_node[k] = n
                self.slot_version[k] += 1
                self.known[k, :] = self.known[:, k] = False
                self.row_known[k, :] = self.row_known[:, k] = False
                self.relief_gram[3 * k:3 * k + 3] = self.Y[:, 3 * k:3 * k + 3].T @ flex.mass_relief
                slot[n] = k
        ks = np.array([slot[n] for n in nodes.tolist()])
        return (3 * ks[:, None] + np.arange(3)).ravel()

    def _solved(self, nodes: list) -> np.ndarray:
        """The projected unit-load solves of ``nodes`` (3 columns each, in order; zero columns pad
        a narrow call so that each column's bytes are its own: MIN_SOLVE_COLUMNS, SOLVE_COLUMN_BLOCK)."""
        flex = self.flex
        m = 3 * len(nodes)
        width = _solve_width(m)
        X = np.zeros((flex.n_dof, max(width, MIN_PROJECTED_COLUMNS)), order="F")
        if m:
            B = np.zeros((flex.n_dof, width), order="F")
            rows = (3 * np.asarray(nodes)[:, None] + np.arange(3)).ravel()
            B[rows, np.arange(m)] = 1.0
            X[:, :width] = np.asarray(flex.factor.solve(B)).reshape(flex.n_dof, -1)
            X = flex.unit_load_projected(X)
        return X

    def _files(self):
        """This model's :class:`UnitLoadFiles` (made on first use, again when a setting that
        changes a solve's bytes or the factorization changed), or None when they are off."""
        if not unit_load_files.ENABLED:
            return None
        settings = (SINGLE_ELASTIC_PROJECTION, MIN_SOLVE_COLUMNS, MIN_PROJECTED_COLUMNS, SOLVE_COLUMN_BLOCK)  # sigma: in the key
        files = self._disk
        if files is None or files.settings != settings or files.factor is not self.flex.factor \
                or files.cache_dir != default_cache_dir():
            files = self._disk = unit_load_files.UnitLoadFiles(self.flex, settings)
        return files

    def _read_state(self, nodes: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """What blocks gathered at ``nodes`` from ``columns`` depend on: the nodes' slots, the
        versions of those slots and of the columns' slots."""
        slot = self.node_slot[nodes]
        v = self.slot_version
        return np.concatenate([slot, np.where(slot >= 0, v[np.maximum(slot, 0)], -1), columns[::3], v[columns[::3] // 3]])

    def _kept(self, key, nodes, columns, gather):
        """``gather()``, or what it gave for ``key`` while the slots it read are unchanged."""
        if not NODE_SET_BLOCKS:
            return gather()
        state = self._read_state(nodes, columns)
        hit = self._blocks.get(key)
        if hit is not None and np.array_equal(hit[0], state):
            return hit[1]
        return self._blocks.put(key, (state, gather()))[1]

    def node_set_blocks(self, nodes: np.ndarray, columns: np.ndarray):
        """``(relief_gram[columns], products(columns, columns), rows(nodes, columns), relief at
        the nodes' dofs, KU[columns])`` of a contact set's distinct ``nodes`` and their
        ``columns`` (from :meth:`columns`): kept per node set (:data:`NODE_SET_BLOCKS`)."""
        def gather():
            dofs = (3 * np.asarray(nodes)[:, None] + np.arange(3)).ravel()
            return (self.relief_gram[columns], self.products(columns, columns), self.rows(nodes, columns),
                    self.flex.relief[dofs], self.KU[columns])
        return self._kept(("set", nodes.tobytes()), nodes, columns, gather)

    def row_blocks(self, nodes: np.ndarray, columns: np.ndarray):
        """``(rows(nodes, columns), relief at the nodes' dofs)``: kept per (nodes, columns)
        (:data:`NODE_SET_BLOCKS`)."""
        nodes = np.asarray(nodes, dtype=np.intp)

        def gather():
            dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
            return self.rows(nodes, columns), self.flex.relief[dofs]
        return self._kept(("rows", nodes.tobytes(), columns.tobytes()), nodes, columns, gather)

    def rows(self, nodes: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """``Y[np.ix_(dofs, columns)]`` (3 rows per node of ``nodes``, kept ``columns`` from
        :meth:`columns`): the same values, from the block array ``node_rows`` for nodes that
        hold a slot (:data:`KEEP_NODE_ROWS`; blocks not kept yet are copied in first)."""
        nodes = np.asarray(nodes, dtype=np.intp)
        three = np.arange(3)
        dofs = (3 * nodes[:, None] + three).ravel()
        if not KEEP_NODE_ROWS:
            return self.Y[np.ix_(dofs, columns)]
        slot = self.node_slot[nodes]
        held = slot >= 0
        col_slots = columns[::3] // 3
        if held.any():
            rs = slot[held]
            new = ~self.row_known[np.ix_(rs, col_slots)].all(axis=1)
            if new.any():                 # copy these nodes' rows of every asked column in
                r_new = (3 * rs[new][:, None] + three).ravel()
                y_new = (3 * nodes[held][new][:, None] + three).ravel()
                self.node_rows[np.ix_(r_new, columns)] = self.Y[np.ix_(y_new, columns)]
                self.row_known[np.ix_(rs[new], col_slots)] = True
        if held.all():
            return self.node_rows[np.ix_((3 * slot[:, None] + three).ravel(), columns)]
        out = np.empty((len(dofs), len(columns)))
        held3 = np.repeat(held, 3)
        out[held3] = self.node_rows[np.ix_((3 * slot[held][:, None] + three).ravel(), columns)]
        out[~held3] = self.Y[np.ix_(dofs[~held3], columns)]
        return out

    def products(self, columns_a: np.ndarray, columns_b: np.ndarray) -> np.ndarray:
        """``gram[columns_a, columns_b]`` (Y^T M Y between kept columns, from :meth:`columns`),
        making the node pairs not made yet.  Each pair is made one way (the lower node's Y
        times the higher node's M Y) in a product of one fixed shape, (3, n_dof) by (n_dof, 3)
        on the two slots' own columns: BLAS sums it in the same order whatever else the store
        holds, so results do not depend on history.  The slots' columns are contiguous (the
        arrays are Fortran-ordered), so nothing is copied: a pair reads 6 columns, where
        padded blocks of four lower nodes copied 12 columns per higher node (6.3 of 23 s of
        ObjectRecognition-v0's first 300 probes went to those copies and products)."""
        sa, sb = np.unique(columns_a // 3), np.unique(columns_b // 3)
        need = ~self.known[np.ix_(sa, sb)]
        if need.any():
            node = self.slot_node
            Y, MY, gram, known = self.Y, self.MY, self.gram, self.known
            for i, j in zip(*np.nonzero(need)):
                lo, hi = (int(sa[i]), int(sb[j])) if node[sa[i]] <= node[sb[j]] else (int(sb[j]), int(sa[i]))
                if known[lo, hi]:                 # the same pair asked for both ways round
                    continue
                P = Y[:, 3 * lo:3 * lo + 3].T @ MY[:, 3 * hi:3 * hi + 3]       # Y_lo^T M Y_hi
                gram[3 * lo:3 * lo + 3, 3 * hi:3 * hi + 3] = P
                gram[3 * hi:3 * hi + 3, 3 * lo:3 * lo + 3] = P.T
                known[lo, hi] = known[hi, lo] = True
        return self.gram[np.ix_(columns_a, columns_b)]


class RitzGeometry:
    """The light part of a :class:`ContactFlexibility`: ``model``, ``M`` and ``rigid_at``."""

    def __init__(self, model, centroid_m, rigid_transform, M) -> None:
        self.model, self.centroid_m, self.rigid_transform, self.M = model, centroid_m, rigid_transform, M

    rigid_at = ContactFlexibility.rigid_at


def _solve_width(m: int) -> int:
    """The solve columns of a call for ``m`` right-hand sides (MIN_SOLVE_COLUMNS, SOLVE_COLUMN_BLOCK)."""
    return -(-max(m, MIN_SOLVE_COLUMNS) // SOLVE_COLUMN_BLOCK) * SOLVE_COLUMN_BLOCK


def contact_flexibility(model) -> ContactFlexibility:
    """The :class:`ContactFlexibility` of ``model`` (a ``ModalModel``), built once and kept."""
    return _CACHE.get_or_build(IdentityKey(model), lambda: ContactFlexibility(model))
