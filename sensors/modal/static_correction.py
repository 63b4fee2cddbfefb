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
are solved once and kept (an LRU per model, ``CACHE_SIZES["modal.unit_loads"]`` nodes), and a
contact set's attachment vectors are their combination minus the inertia relief's (also
solved once), and Psi^T K Psi follows from the solves without K (see ``attachment_modes``).
The same span as the direct solve, summed in another order: the reduced stiffness agrees to
rounding (eigenvalues within 1e-8 relative, 1.5e-9 measured on the 200 mm wood bar; the span
within 1e-9: ``tests/test_unit_load_reuse.py``); ``reuse_unit_loads=False`` (or
:data:`REUSE_UNIT_LOADS`) is the direct solve, the reference.  Random grasps of the same
object touch the same few elements over and over, so after a few contact sets a new one
needs no solve at all: 36 -> 12 ms per contact set of GraspPosition-v0's wood bar.
"""

from __future__ import annotations

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from ..fem.assembly import shape_functions
from ..fem.direct_solver import factorize
from ..fem.eigen import rigid_body_modes
from .basis import check_points_m

__all__ = ["MAX_ATTACHMENT_VECTORS", "REUSE_UNIT_LOADS", "ContactFlexibility", "RitzGeometry", "contact_flexibility",
           "nodal_at"]

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
# The regularising shift of K, relative to the first elastic eigenvalue (see the docstring).
_SHIFT = 1e-3
# Attachment vectors whose M-norm after orthogonalisation is below this fraction of the
# largest are (numerically) in the span of the others and dropped.
_DEPENDENT = 1e-10
# Shape-function weights below this are rounding (a point on a vertex, edge or face has exact
# zeros there): the reused path leaves those nodes out (a load change below 1e-13 relative).
_NEGLIGIBLE_WEIGHT = 1e-13

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
        self._unit_loads: LRU = LRU(CACHE_SIZES["modal.unit_loads"])

    def _projected(self, X: np.ndarray) -> np.ndarray:
        """``X`` made M-orthogonal to the rigid-body and kept elastic modes (in place)."""
        for _ in range(2):                                           # twice: M-orthogonal to rounding
            X -= self.R @ (self.MR.T @ X)
            X -= self.U @ (self.MU.T @ X)
        return X

    def unit_load_solves(self, nodes) -> np.ndarray:
        """P (K + sigma M)^-1 [e_3n, e_3n+1, e_3n+2] for each node n of ``nodes`` (distinct),
        side by side: (n_dof, 3 len(nodes)).  Solved once per node (the missing ones in one
        call) and kept in this model's LRU."""
        blocks = {int(n): self._unit_loads.get(int(n)) for n in nodes}
        missing = [n for n, b in blocks.items() if b is None]
        if missing:
            B = np.zeros((self.n_dof, 3 * len(missing)), order="F")
            rows = (3 * np.asarray(missing)[:, None] + np.arange(3)).ravel()
            B[rows, np.arange(rows.size)] = 1.0
            Y = self._projected(np.asarray(self.factor.solve(B)).reshape(self.n_dof, -1))
            for i, n in enumerate(missing):
                # a copy: a view would keep the whole batch alive after the LRU drops the block
                blocks[n] = self._unit_loads.put(n, Y[:, 3 * i:3 * i + 3].copy(order="F"))
        return np.concatenate([blocks[int(n)] for n in nodes], axis=1)

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
        a = len(points_m)
        if a > MAX_ATTACHMENT_VECTORS:
            raise ValueError(
                f"{a} constrained contact directions need {a} attachment vectors (about {a * self.n_dof * 8 / 1e6:.0f} MB "
                f"and a {6 + self.U.shape[1] + a}-column eigenproblem per contact set); the limit is "
                f"{MAX_ATTACHMENT_VECTORS} (20 contacts with normal and tangential springs): merge contact points "
                "or raise sensors.modal.static_correction.MAX_ATTACHMENT_VECTORS")
        if a == 0:
            return np.zeros((self.n_dof, 0)), np.zeros((0, 0)), np.zeros((0, self.U.shape[1]))
        model = self.model
        p = check_points_m(points_m)
        tet, bary = model.locator.locate(p)
        N = shape_functions(bary, model.element)                     # (a, n_el)
        nodes = model.elements[tet]                                  # (a, n_el)
        cols = np.arange(a)
        reuse = REUSE_UNIT_LOADS if reuse_unit_loads is None else reuse_unit_loads
        if reuse:
            # The loads on the distinct nodes: C[3i + j, c] = sum of N * d_j over node i's
            # entries.  Shape functions below _NEGLIGIBLE_WEIGHT are a point on a vertex or face
            # seen from the element's other nodes (rounding of its barycentric coordinates).
            used = np.abs(N) > _NEGLIGIBLE_WEIGHT
            distinct, index = np.unique(nodes[used], return_inverse=True)
            C = np.zeros((3 * distinct.size, a))
            cols_used = np.broadcast_to(cols[:, None], nodes.shape)[used]
            for j in range(3):
                np.add.at(C, (3 * index + j, cols_used), (N * directions[:, j:j + 1])[used])
            dofs = (3 * distinct[:, None] + np.arange(3)).ravel()
            X = self.unit_load_solves(distinct) @ C - self.relief @ (self.R[dofs].T @ C)
        else:
            F = np.zeros((self.n_dof, a))
            for j in range(3):
                np.add.at(F, (3 * nodes + j, np.broadcast_to(cols[:, None], nodes.shape)), N * directions[:, j:j + 1])
            F -= self.MR @ (self.R.T @ F)                            # inertia relief: no rigid-body load
            X = self._projected(np.asarray(self.factor.solve(F)).reshape(self.n_dof, a))
        G = X.T @ (self.M @ X)
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
        else:
            Kpsi = Psi.T @ (self.K @ Psi)
        return Psi, 0.5 * (Kpsi + Kpsi.T), Psi.T @ self.KU


class RitzGeometry:
    """The light part of a :class:`ContactFlexibility`: ``model``, ``M`` and ``rigid_at``."""

    def __init__(self, model, centroid_m, rigid_transform, M) -> None:
        self.model, self.centroid_m, self.rigid_transform, self.M = model, centroid_m, rigid_transform, M

    rigid_at = ContactFlexibility.rigid_at


def contact_flexibility(model) -> ContactFlexibility:
    """The :class:`ContactFlexibility` of ``model`` (a ``ModalModel``), built once and kept."""
    hit = _CACHE.get(id(model))
    if hit is None or hit.model is not model:
        hit = _CACHE.put(id(model), ContactFlexibility(model))
    return hit
