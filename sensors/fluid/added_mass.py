"""Numerics of the liquid's added mass: P2 Laplace on the liquid, boundary quadrature, and the
static correction of the container's dry modal basis.

Used by :mod:`sensors.fluid` (the physics is described in :mod:`sensors.fluid.filled_model`).

* :func:`laplace_stiffness` - H = integral grad N_a . grad N_b dV on P2 tets.
* :func:`boundary_quadrature` - a 7-point rule on selected boundary faces of a P2 tet mesh
  (points, outward normal times dS, shape values and gradients).
* :func:`liquid_loading` - the added-mass matrix M_a and the wall-slip matrix S of a liquid
  mesh on a basis of wall motions (one sparse factorization for all of them).
* :func:`static_correction` - residual-flexibility vectors of the dry container: its static
  response to smooth pressure patterns on the wetted wall, made M-orthogonal to the kept modes
  and Rayleigh-Ritz diagonalized. A liquid loads the wall with pressures that excite the
  container's stiff breathing (n = 0) motion far above the audio band; without these vectors
  the reduced model misses that compliance (a cylindrical cup's bottom mode came out 2.4 % high
  against a fully coupled solve with dry modes to 20 kHz, 0.2 % with them).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from ..fem.eigen import rigid_body_modes
from ..fem.assembly import QUADRATURE, assemble, shape_functions, shape_gradients_ref

__all__ = ["laplace_stiffness", "boundary_quadrature", "WallCoupling", "wall_coupling", "symmetric_lu", "LiquidFlow",
           "unit_potential_flow", "potential_flow", "liquid_loading", "static_correction", "static_correction_solver",
           "pressure_patterns"]

#: The sparse solver of the static correction's one factorization of K + s M: a name of
#: :func:`sensors.fem.direct_solver.factorize`'s solvers, ``"default"`` (PARDISO where MKL is
#: installed, else SuperLU: the pure-SciPy path), or None: SciPy SuperLU with MMD ordering, the
#: reference. The default because the mug's correction (98,964 dof, OMP 1) took 10.4 against 45.5
#: CPU s and 0.58 GB less peak, with its wet frequencies at half full within 1.6e-12 of the
#: reference's (``tests/test_fluid.py``). The solver that ran is part of the container's cache key
#: (not the reference's).  Read at each call.
STATIC_CORRECTION_SOLVER: str | None = "default"


def static_correction_solver() -> str | None:
    """The solver :data:`STATIC_CORRECTION_SOLVER` names, ``"default"`` resolved (None: the reference)."""
    from ..fem.direct_solver import default_solver

    name = STATIC_CORRECTION_SOLVER
    return default_solver() if name == "default" else (None if name is None else str(name).lower())

#: Degree-5 7-point rule on a triangle (Dunavant 1985): barycentric points, weights summing to 1.
_A1, _B1, _W1 = 0.059715871789770, 0.470142064105115, 0.132394152788506
_A2, _B2, _W2 = 0.797426985353087, 0.101286507323456, 0.125939180544827
_TRI_POINTS = np.array([[1 / 3, 1 / 3, 1 / 3], [_A1, _B1, _B1], [_B1, _A1, _B1], [_B1, _B1, _A1],
                        [_A2, _B2, _B2], [_B2, _A2, _B2], [_B2, _B2, _A2]])
_TRI_WEIGHTS = np.array([0.225, _W1, _W1, _W1, _W2, _W2, _W2])
#: Local corners of the face opposite each tet vertex, and that face's reference normal
#: times its reference area (outward for a positively oriented tet).
_FACE_LOCAL = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
_FACE_NORMAL_AREA = np.array([[0.5, 0.5, 0.5], [-0.5, 0, 0], [0, -0.5, 0], [0, 0, -0.5]])


def laplace_stiffness(nodes_m: np.ndarray, tets10: np.ndarray) -> scipy.sparse.csr_matrix:
    """H[a, b] = integral grad N_a . grad N_b dV [m] for P2 tets (degree-5 rule, exact on straight tets)."""
    xi, w = QUADRATURE["deg5"]
    dN = shape_gradients_ref(xi, "p2")
    X = nodes_m[tets10]
    J = np.einsum("mai,qak->mqik", X, dN)
    det = np.linalg.det(J)
    if np.any(det <= 0):
        raise ValueError(f"{int((det <= 0).any(axis=1).sum())} liquid elements have a non-positive Jacobian")
    G = np.einsum("qak,mqki->mqai", dN, np.linalg.inv(J))
    Ke = np.einsum("mq,mqai,mqbi->mab", det * w, G, G)
    rows = np.repeat(tets10, 10, axis=1).ravel()
    cols = np.tile(tets10, (1, 10)).ravel()
    n = len(nodes_m)
    H = scipy.sparse.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    return ((H + H.T) * 0.5).tocsr()


def boundary_faces(tets4: np.ndarray):
    """(owner tet, local vertex opposite the face) of every boundary face of a tet mesh."""
    faces = tets4[:, _FACE_LOCAL].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    single = np.flatnonzero(counts[inverse.ravel()] == 1)
    return single // 4, single % 4


def boundary_quadrature(nodes_m: np.ndarray, tets10: np.ndarray, select) -> dict:
    """7-point quadrature on the boundary faces of a P2 tet mesh that ``select`` keeps.

    Args:
        select: callable(corners (f, 3) node indices, corner points (f, 3, 3)) -> (f,) bool.

    Returns a dict of arrays over the P quadrature points: ``points_m`` (P, 3),
    ``normal_area_m2`` (P, 3) the mesh's outward normal times the weight dS, ``shape`` (P, 10)
    P2 shape values, ``gradients`` (P, 10, 3) their physical gradients, ``nodes`` (P, 10) node
    indices.
    """
    owner, opposite = boundary_faces(tets10[:, :4])
    corners = tets10[owner][np.arange(len(owner))[:, None], _FACE_LOCAL[opposite]]
    keep = np.asarray(select(corners, nodes_m[corners]), dtype=bool)
    owner, opposite = owner[keep], opposite[keep]
    n_f, n_q = len(owner), len(_TRI_WEIGHTS)
    bary = np.zeros((n_f, n_q, 4))
    loc = _FACE_LOCAL[opposite]  # (f, 3)
    for j in range(3):
        bary[np.arange(n_f)[:, None], np.arange(n_q)[None, :], loc[:, j][:, None]] = _TRI_POINTS[None, :, j]
    flat = bary.reshape(-1, 4)
    N = shape_functions(flat, "p2").reshape(n_f, n_q, 10)
    dN = shape_gradients_ref(flat[:, 1:], "p2").reshape(n_f, n_q, 10, 3)
    X = nodes_m[tets10[owner]]
    J = np.einsum("mai,mqak->mqik", X, dN)
    det = np.linalg.det(J)
    Jinv = np.linalg.inv(J)
    # Nanson: n dS = det J J^-T n_ref dA_ref.
    nda = det[..., None] * np.einsum("mqki,mk->mqi", Jinv, _FACE_NORMAL_AREA[opposite]) * _TRI_WEIGHTS[None, :, None]
    G = np.einsum("mqak,mqki->mqai", dN, Jinv)
    points = np.einsum("mqa,mai->mqi", N, X)
    return {"points_m": points.reshape(-1, 3), "normal_area_m2": nda.reshape(-1, 3), "shape": N.reshape(-1, 10),
            "gradients": G.reshape(-1, 10, 3), "nodes": np.repeat(tets10[owner], n_q, axis=0)}


@dataclasses.dataclass
class WallCoupling:
    """A liquid mesh coupled to a basis of wall motions (:func:`wall_coupling`).

    Attributes:
        quadrature: :func:`boundary_quadrature` on the wetted wall (every boundary face not on
            the free surface).
        shapes: (P, 3, k) the wall displacement of each basis vector at its points.
        load: (n, k) C[a, j] = integral over the wetted wall of N_a (n . u_j) dS [m^2 * the
            basis' unit], n out of the liquid: the Neumann load of each vector.
        laplace: (n, n) H of the liquid mesh (:func:`laplace_stiffness`).
        free: Indices of the nodes off the free surface (p = 0 on it).
    """

    quadrature: dict
    shapes: np.ndarray
    load: np.ndarray
    laplace: scipy.sparse.csr_matrix
    free: np.ndarray


def wall_coupling(nodes_m: np.ndarray, tets10: np.ndarray, free_surface: np.ndarray, shapes_at) -> WallCoupling:
    """The coupling of a liquid's P2 mesh (``free_surface``: (n,) True on the free surface; every
    other boundary face is wetted wall) to the wall motions ``shapes_at(points (P, 3)) -> (P, 3, k)``."""
    q = boundary_quadrature(nodes_m, tets10, lambda corners, _: ~np.all(free_surface[corners], axis=1))
    U = np.asarray(shapes_at(q["points_m"]), dtype=np.float64)  # (P, 3, k)
    g = np.einsum("pi,pik->pk", q["normal_area_m2"], U)  # (n . u) dS
    n_nodes = len(nodes_m)
    P = len(g)
    B = scipy.sparse.csr_matrix((q["shape"].ravel(), (q["nodes"].ravel(), np.repeat(np.arange(P), 10))),
                                shape=(n_nodes, P))
    return WallCoupling(q, U, B @ g, laplace_stiffness(nodes_m, tets10), np.flatnonzero(~free_surface))


def symmetric_lu(A):
    """Sparse LU of a symmetric positive definite matrix (no pivoting, symmetric ordering)."""
    return scipy.sparse.linalg.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                    options={"SymmetricMode": True})


@dataclasses.dataclass
class LiquidFlow:
    """A liquid mesh's potential flow on a basis of wall motions, per unit density
    (:func:`unit_potential_flow`): what every liquid filling that mesh shares, whatever its
    density and speed of sound.

    Attributes:
        flux: (k, k) phi^T C: the added mass per unit density, before symmetrizing.
        slip: (k, k) the wall-slip matrix S (as :func:`liquid_loading`).
        lu: The factorization of the liquid's Laplacian on its free nodes.
        laplace_free: (n_free, n_free) that Laplacian H.
        load_free: (n_free, k) the Neumann load C on the free nodes.
        free: Indices of the free nodes (off the free surface).
    """

    flux: np.ndarray
    slip: np.ndarray
    lu: object
    laplace_free: scipy.sparse.csr_matrix
    load_free: np.ndarray
    free: np.ndarray

    def added_mass(self, density_kg_m3: float) -> np.ndarray:
        """M_a of a liquid of this density (symmetric)."""
        Ma = density_kg_m3 * self.flux
        return 0.5 * (Ma + Ma.T)


def unit_potential_flow(coupling: WallCoupling) -> LiquidFlow:
    """The :class:`LiquidFlow` of a liquid mesh's coupling (one sparse factorization)."""
    F, free, q, U = coupling.load, coupling.free, coupling.quadrature, coupling.shapes
    laplace_free = coupling.laplace[free][:, free]
    lu = symmetric_lu(laplace_free)
    load_free = F[free]
    phi = np.zeros_like(F)
    phi[free] = lu.solve(np.ascontiguousarray(load_free))
    flux = phi.T @ F
    grad = np.matmul(q["gradients"].transpose(0, 2, 1), phi[q["nodes"]])  # (P, 3, k)
    dS = np.linalg.norm(q["normal_area_m2"], axis=1)
    n = q["normal_area_m2"] / dS[:, None]
    rel = U - grad
    rel_t = rel - n[:, :, None] * np.einsum("pi,pik->pk", n, rel)[:, None, :]
    W = (np.sqrt(dS)[:, None, None] * rel_t).reshape(-1, rel_t.shape[2])
    S = W.T @ W
    return LiquidFlow(flux, 0.5 * (S + S.T), lu, laplace_free, load_free, free)


def potential_flow(coupling: WallCoupling, density_kg_m3: float):
    """Added mass M_a, wall-slip matrix S (as :func:`liquid_loading`) and the factorization of
    the liquid's Laplacian on its free nodes (for reuse)."""
    flow = unit_potential_flow(coupling)
    return flow.added_mass(density_kg_m3), flow.slip, flow.lu


def liquid_loading(nodes_m: np.ndarray, tets10: np.ndarray, free_surface: np.ndarray, shapes_at,
                   density_kg_m3: float):
    """Added-mass matrix and wall-slip matrix of a liquid mesh on a basis of wall motions.

    Args:
        nodes_m, tets10: The liquid's P2 mesh (positively oriented).
        free_surface: (n,) True for nodes on the free surface (phi = 0 there); every other
            boundary face is wetted wall.
        shapes_at: callable(points (P, 3)) -> (P, 3, k) wall displacement of each basis vector.
        density_kg_m3: Liquid density.

    Returns:
        (M_a (k, k) [dimensionless for mass-normalized vectors], S (k, k) [m^2 / kg]: the
        integral over the wetted wall of the tangential slip between wall and potential flow,
        S[i, j] = integral (u_i - grad phi_i)_t . (u_j - grad phi_j)_t dS).
    """
    Ma, S, _ = potential_flow(wall_coupling(nodes_m, tets10, free_surface, shapes_at), density_kg_m3)
    return Ma, S


def pressure_patterns(points_m: np.ndarray, lower_m, upper_m, degree: int) -> np.ndarray:
    """(P, n) products of Legendre polynomials of total degree <= ``degree`` in the coordinates
    scaled to [-1, 1] over the box ``lower_m`` .. ``upper_m``: smooth pressure shapes."""
    lo, hi = np.asarray(lower_m, float), np.asarray(upper_m, float)
    t = 2.0 * (np.asarray(points_m, float) - lo) / np.where(hi > lo, hi - lo, 1.0) - 1.0
    leg = [np.polynomial.legendre.legvander(t[:, i], degree) for i in range(3)]  # (P, d + 1) each
    cols = [leg[0][:, a] * leg[1][:, b] * leg[2][:, c]
            for a in range(degree + 1) for b in range(degree + 1 - a) for c in range(degree + 1 - a - b)]
    return np.stack(cols, axis=1)


def static_correction(dry, wetted, *, degree: int = 6, shift_hz: float | None = None):
    """Residual-flexibility modes of ``dry`` for pressures on its wetted wall.

    Args:
        dry: A :class:`~sensors.ModalModel` with its mesh (``nodes_m``, ``elements``, P2).
        wetted: callable(corners (f, 3), points (f, 3, 3)) -> (f,) bool selecting the mesh's
            boundary faces in contact with the liquid (the cavity wall and floor).
        degree: Total polynomial degree of the pressure patterns.
        shift_hz: The static solves use K + (2 pi shift_hz)^2 M (a free body's K is singular);
            default a tenth of the lowest dry mode.

    Returns:
        (eigenvalues (p,) [rad^2/s^2] ascending, shapes (n_nodes, 3, p) [m / sqrt(kg)]): Ritz
        pairs of the static responses with the rigid-body and the dry model's modes removed,
        mass-normalized and M-orthogonal to the dry modes, so that dry modes and these vectors
        together are a K- and M-diagonal basis. Their eigenvalues lie above the dry band.
    """
    if dry.element != "p2":
        raise ValueError("the static correction needs a P2 model")
    K, M = assemble(dry.nodes_m, dry.elements, dry.material, "p2")
    q = boundary_quadrature(dry.nodes_m, dry.elements, wetted)
    if len(q["points_m"]) == 0:
        raise ValueError("no boundary face of the container's mesh lies on its cavity")
    pts = q["points_m"]
    patterns = pressure_patterns(pts, pts.min(axis=0), pts.max(axis=0), degree)  # (P, n)
    # F[3 a + i, j] = integral p_j N_a n_i dS.
    vals = q["shape"][:, :, None, None] * q["normal_area_m2"][:, None, :, None] * patterns[:, None, None, :]
    n_nodes = len(dry.nodes_m)
    rows = (3 * q["nodes"][:, :, None] + np.arange(3)[None, None, :]).reshape(-1)
    F = np.zeros((3 * n_nodes, patterns.shape[1]))
    np.add.at(F, rows, vals.reshape(-1, patterns.shape[1]))
    f0 = float(dry.frequencies_hz[0]) if dry.n_modes else 100.0
    s = (2 * math.pi * (0.1 * f0 if shift_hz is None else shift_hz)) ** 2
    solver = static_correction_solver()
    if solver is None:
        lu = scipy.sparse.linalg.splu((K + s * M).tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                      options={"SymmetricMode": True})
    else:
        from ..fem.direct_solver import factorize

        lu = factorize((K + s * M).tocsc(), solver)
    X = lu.solve(F)
    R = rigid_body_modes(dry.nodes_m)
    U = np.concatenate([R, dry.mode_matrix()], axis=1)
    G = U.T @ (M @ U)
    for _ in range(2):  # M-orthogonal projection off the rigid-body and dry modes (twice: round-off)
        X = X - U @ np.linalg.solve(G, U.T @ (M @ X))
    Gx = X.T @ (M @ X)
    w, V = np.linalg.eigh(0.5 * (Gx + Gx.T))
    keep = w > 1e-10 * w.max()
    X = (X @ V[:, keep]) / np.sqrt(w[keep])
    Kr = X.T @ (K @ X)
    lam, Q = scipy.linalg.eigh(0.5 * (Kr + Kr.T))
    Y = X @ Q
    return lam, Y.reshape(n_nodes, 3, -1)
