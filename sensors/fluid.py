"""Fluid loading of a container's dry modes by an inviscid, incompressible liquid.

Physics (potential flow, the classic added-mass model of liquid-filled shells; Lindholm, Kana
& Abramson 1962; Amabili, Paidoussis & Lakis, J. Sound Vib. 213 (1998) 259):

* The liquid's velocity is grad(phi) with Laplace's equation in the liquid volume,
  phi = 0 (p = -rho dphi/dt = 0) on the free surface, and d(phi)/dn = u . n on the wetted
  wall (normal velocity continuity). Gravity waves (sloshing, < 10 Hz) are ignored.
* With the wall velocity expanded on the dry modes, u = sum_i qdot_i u_i, each mode's
  potential phi_i solves that problem with Neumann data n . u_i. The liquid's kinetic energy
  is 1/2 qdot^T M_a qdot with M_a[i, j] = rho integral_wet phi_i (n . u_j) dS.
* Wet modes: Lambda q = w^2 (I + M_a) q on the dry modes plus the six rigid-body modes of the
  free container (liquid couples them to the elastic modes); the wet shapes are U q with
  q^T (I + M_a) q = 1, so the wet model is mass-normalized including the liquid.

Numerics: P2 tets on the liquid (:mod:`sensors.cavity`), Neumann data from the dry model's
``mode_shapes_at`` at the wetted boundary's quadrature points (7-point rule on each face of
the liquid mesh), one sparse factorization for all modes.

Truncation: the basis is every dry mode the model has (by default up to 22 kHz), so the wet
modes in the audio band are well inside it; the top few wet modes converge least (the
benchmark measures it).

Damping: structural Rayleigh and contact damping as for the dry model (Rayleigh damping acts
on the wall only: Q^T diag(alpha + beta Lambda) Q), plus the viscous Stokes boundary layer of
the liquid on the wetted wall: a wall slipping tangentially past the potential flow at
velocity amplitude U dissipates 1/2 U^2 sqrt(rho mu w / 2) per unit area (Landau & Lifshitz,
Fluid Mechanics, section 24), so wet mode k gains a decay rate
sigma_k = 1/2 sqrt(rho mu w_k / 2) integral_wet |(u_k - grad phi_k)_tangential|^2 dS.
Bulk dissipation of the potential flow (smaller by the boundary-layer thickness over the
container size) and free-surface losses are neglected; the model is for thin layers
(honey's is ~1 mm at 3 kHz, still thin against a cup).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .cavity import AxisymmetricCavity, LiquidMesh, SurfaceCavity, unit
from .damping import check_on_surface, contact_damping_matrix
from .fem import QUADRATURE, shape_functions, shape_gradients_ref
from .liquids import Liquid, get_liquid

__all__ = ["Container", "FilledModalModel", "liquid_loading", "laplace_stiffness", "wetted_quadrature"]

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


def _jacobian(X: np.ndarray, dN: np.ndarray):
    """X (m, 10, 3) nodes, dN (m or 1, q, 10, 3) -> det J (m, q), physical gradients (m, q, 10, 3)."""
    J = np.einsum("mai,mqak->mqik", X, np.broadcast_to(dN, (len(X),) + dN.shape[1:]))
    det = np.linalg.det(J)
    if np.any(det <= 0):
        raise ValueError(f"{int((det <= 0).any(axis=1).sum())} liquid elements have a non-positive Jacobian")
    G = np.einsum("mqak,mqki->mqai", np.broadcast_to(dN, (len(X),) + dN.shape[1:]), np.linalg.inv(J))
    return det, G


def laplace_stiffness(nodes_m: np.ndarray, tets10: np.ndarray) -> scipy.sparse.csr_matrix:
    """H[a, b] = integral grad N_a . grad N_b dV for P2 tets (degree-5 rule, exact on straight tets)."""
    xi, w = QUADRATURE["deg5"]
    det, G = _jacobian(nodes_m[tets10], shape_gradients_ref(xi, "p2")[None])
    Ke = np.einsum("mq,mqai,mqbi->mab", det * w, G, G)
    rows = np.repeat(tets10, 10, axis=1).ravel()
    cols = np.tile(tets10, (1, 10)).ravel()
    n = len(nodes_m)
    H = scipy.sparse.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    return ((H + H.T) * 0.5).tocsr()


def _boundary_faces(tets4: np.ndarray):
    """(owner tet, local vertex opposite the face) of every boundary face of a tet mesh."""
    faces = tets4[:, _FACE_LOCAL].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    single = np.flatnonzero(counts[inverse.ravel()] == 1)
    return single // 4, single % 4


def wetted_quadrature(mesh: LiquidMesh) -> dict:
    """Quadrature on the wetted boundary (every boundary face not on the free surface).

    Returns a dict of arrays over the P quadrature points: ``points_m`` (P, 3), ``normal_area_m2``
    (P, 3) outward normal of the liquid times the weight dS, ``shape`` (P, 10) P2 shape values,
    ``gradients`` (P, 10, 3) their physical gradients and ``nodes`` (P, 10) node indices.
    """
    tets = mesh.tets
    owner, opposite = _boundary_faces(tets[:, :4])
    corners = tets[owner][np.arange(len(owner))[:, None], _FACE_LOCAL[opposite]]
    wet = ~np.all(mesh.free_surface[corners], axis=1)
    owner, opposite = owner[wet], opposite[wet]
    n_f, n_q = len(owner), len(_TRI_WEIGHTS)
    bary = np.zeros((n_f, n_q, 4))
    loc = _FACE_LOCAL[opposite]  # (f, 3)
    for j in range(3):
        bary[np.arange(n_f)[:, None], np.arange(n_q)[None, :], loc[:, j][:, None]] = _TRI_POINTS[None, :, j]
    flat = bary.reshape(-1, 4)
    N = shape_functions(flat, "p2").reshape(n_f, n_q, 10)
    dN = shape_gradients_ref(flat[:, 1:], "p2").reshape(n_f, n_q, 10, 3)
    X = mesh.nodes_m[tets[owner]]
    J = np.einsum("mai,mqak->mqik", X, dN)
    det = np.linalg.det(J)
    Jinv = np.linalg.inv(J)
    # Nanson: n dS = det J J^-T n_ref dA_ref.
    nda = det[..., None] * np.einsum("mqki,mk->mqi", Jinv, _FACE_NORMAL_AREA[opposite]) * _TRI_WEIGHTS[None, :, None]
    G = np.einsum("mqak,mqki->mqai", dN, Jinv)
    points = np.einsum("mqa,mai->mqi", N, X)
    return {"points_m": points.reshape(-1, 3), "normal_area_m2": nda.reshape(-1, 3), "shape": N.reshape(-1, 10),
            "gradients": G.reshape(-1, 10, 3), "nodes": np.repeat(tets[owner], n_q, axis=0)}


def liquid_loading(mesh: LiquidMesh, shapes_at, density_kg_m3: float):
    """Added-mass matrix and wall-slip matrix of the liquid on a basis of wall motions.

    Args:
        mesh: The liquid's P2 mesh.
        shapes_at: callable(points (P, 3)) -> (P, 3, k) wall displacement of each basis mode.
        density_kg_m3: Liquid density.

    Returns:
        (M_a (k, k) [dimensionless for mass-normalized modes], S (k, k) [m^2 / kg]: the
        integral over the wetted wall of the tangential slip between wall and potential flow,
        S[i, j] = integral (u_i - grad phi_i)_t . (u_j - grad phi_j)_t dS).
    """
    q = wetted_quadrature(mesh)
    U = np.asarray(shapes_at(q["points_m"]), dtype=np.float64)  # (P, 3, k)
    g = np.einsum("pi,pik->pk", q["normal_area_m2"], U)  # (n . u) dS
    n_nodes = len(mesh.nodes_m)
    P = len(g)
    B = scipy.sparse.csr_matrix((q["shape"].ravel(), (q["nodes"].ravel(), np.repeat(np.arange(P), 10))),
                                shape=(n_nodes, P))
    F = B @ g  # (n, k) Neumann load of each mode
    H = laplace_stiffness(mesh.nodes_m, mesh.tets)
    free = np.flatnonzero(~mesh.free_surface)
    solve = scipy.sparse.linalg.factorized(H[free][:, free].tocsc())
    phi = np.zeros_like(F)
    phi[free] = solve(F[free])
    Ma = density_kg_m3 * (phi.T @ F)
    Ma = 0.5 * (Ma + Ma.T)
    grad = np.einsum("pai,pak->pik", q["gradients"], phi[q["nodes"]])  # (P, 3, k)
    dS = np.linalg.norm(q["normal_area_m2"], axis=1)
    n = q["normal_area_m2"] / dS[:, None]
    rel = U - grad
    rel_t = rel - n[:, :, None] * np.einsum("pi,pik->pk", n, rel)[:, None, :]
    S = np.einsum("pik,pil,p->kl", rel_t, rel_t, dS)
    return Ma, 0.5 * (S + S.T)


def _rigid_body_data(model):
    """Mass [kg], centre of mass [m] and inverse square root of the inertia tensor of the dry model."""
    xi, w = QUADRATURE["deg5"]
    L = np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1)
    N = shape_functions(L, model.element)
    dN = shape_gradients_ref(xi, model.element)
    X = model.nodes_m[model.elements]
    det = np.linalg.det(np.einsum("mai,qak->mqik", X, dN))
    x = np.einsum("qa,mai->mqi", N, X)
    dm = model.material.density_kg_m3 * det * w  # (m, q)
    mass = float(dm.sum())
    centre = np.einsum("mq,mqi->i", dm, x) / mass
    r = x - centre
    second = np.einsum("mq,mqi,mqj->ij", dm, r, r)
    inertia = np.trace(second) * np.eye(3) - second
    val, vec = np.linalg.eigh(inertia)
    return mass, centre, (vec / np.sqrt(val)) @ vec.T


class Container:
    """A container's dry modal model and its cavity; :meth:`fill` gives the wet model.

    Per-container work (rigid-body modes of the dry model) is done once here; each fill only
    meshes the liquid and solves one small Laplace problem.

    Args:
        dry: The container's dry :class:`~sensors.ModalModel` (free-free elastic modes).
        cavity: :class:`~sensors.cavity.AxisymmetricCavity` or
            :class:`~sensors.cavity.SurfaceCavity` in the model's frame.
        max_dry_frequency_hz: Use only dry modes up to this frequency as the basis (default:
            all of them); for truncation studies.
        liquid_n_theta: Liquid elements around an axisymmetric cavity.
        liquid_element_size_m: Liquid element size (axial for axisymmetric cavities).
    """

    def __init__(self, dry, cavity, *, max_dry_frequency_hz: float | None = None, liquid_n_theta: int = 16,
                 liquid_element_size_m: float | None = None):
        if not isinstance(cavity, (AxisymmetricCavity, SurfaceCavity)):
            raise TypeError(f"cavity must be an AxisymmetricCavity or SurfaceCavity, got {type(cavity).__name__}")
        self.dry = dry
        self.cavity = cavity
        f = np.asarray(dry.frequencies_hz)
        self.n_basis = len(f) if max_dry_frequency_hz is None else int(np.searchsorted(f, max_dry_frequency_hz, "right"))
        self.liquid_n_theta = int(liquid_n_theta)
        self.liquid_element_size_m = liquid_element_size_m
        self._mass_kg, self._centre_m, self._rot = _rigid_body_data(dry)

    @property
    def upright_gravity(self) -> np.ndarray:
        """Gravity direction (object frame) of the container standing upright."""
        if isinstance(self.cavity, AxisymmetricCavity):
            return -self.cavity.upright_up
        return np.array([0.0, 0.0, -1.0])

    def basis_shapes_at(self, points_m) -> np.ndarray:
        """(n, 3, 6 + r) mass-normalized rigid-body modes (3 translations, 3 rotations) then dry modes."""
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        r = p - self._centre_m
        cross = np.zeros((len(p), 3, 3))  # [r]_x
        cross[:, 0, 1], cross[:, 0, 2] = -r[:, 2], r[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = r[:, 2], -r[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = -r[:, 1], r[:, 0]
        trans = np.broadcast_to(np.eye(3) / math.sqrt(self._mass_kg), (len(p), 3, 3))
        rot = -cross @ self._rot  # (a x r) for rotation vectors a = columns of J^-1/2
        elastic = self.dry.mode_shapes_at(p)[:, :, : self.n_basis]
        return np.concatenate([trans, rot, elastic], axis=2)

    def volume_m3(self, *, fill_fraction=None, fill_height_m=None, volume_m3=None) -> float:
        """Liquid volume from exactly one of a fill fraction (of the cavity), an upright height or a volume."""
        given = [v is not None for v in (fill_fraction, fill_height_m, volume_m3)]
        if sum(given) != 1:
            raise TypeError("give exactly one of fill_fraction, fill_height_m, volume_m3")
        total = self.cavity.volume_m3
        if fill_fraction is not None:
            if not 0.0 <= fill_fraction <= 1.0:
                raise ValueError(f"fill_fraction must be in [0, 1], got {fill_fraction}")
            return float(fill_fraction) * total
        if fill_height_m is not None:
            if not isinstance(self.cavity, AxisymmetricCavity):
                raise TypeError("fill_height_m needs an AxisymmetricCavity; give fill_fraction or volume_m3")
            if not 0.0 <= fill_height_m <= self.cavity.depth_m:
                raise ValueError(f"fill_height_m must be in [0, {self.cavity.depth_m:.4g}] m, got {fill_height_m}")
            return self.cavity.volume_below_m3(fill_height_m)
        if not 0.0 <= volume_m3 <= total:
            raise ValueError(f"volume_m3 must be in [0, {total:.4g}] m^3, got {volume_m3}")
        return float(volume_m3)

    def liquid_mesh(self, volume_m3: float, gravity=None) -> LiquidMesh:
        up = -unit(self.upright_gravity if gravity is None else gravity)
        return self.cavity.liquid_mesh(volume_m3, up, n_theta=self.liquid_n_theta,
                                       element_size_m=self.liquid_element_size_m)

    def fill(self, liquid="water", *, fill_fraction=None, fill_height_m=None, volume_m3=None,
             gravity=None) -> "FilledModalModel":
        """The container holding ``liquid`` (name, :class:`~sensors.liquids.Liquid` or density).

        Args:
            fill_fraction / fill_height_m / volume_m3: How much liquid (exactly one).
            gravity: Gravity direction in the object frame (default: standing upright); a
                tilted container keeps its volume and gets a tilted free surface.
        """
        liquid = get_liquid(liquid)
        volume = self.volume_m3(fill_fraction=fill_fraction, fill_height_m=fill_height_m, volume_m3=volume_m3)
        k = 6 + self.n_basis
        lam = np.concatenate([np.zeros(6), np.asarray(self.dry.eigenvalues)[: self.n_basis]])
        if volume <= 0.0:
            # No liquid: exactly the dry modes (no eigen-solve whose round-off would rotate pairs).
            Q = np.zeros((k, self.n_basis))
            Q[6:, :] = np.eye(self.n_basis)
            return FilledModalModel(self, liquid, 0.0, lam[6:].copy(), Q, None, None)
        mesh = self.liquid_mesh(volume, gravity)
        Ma, S = liquid_loading(mesh, self.basis_shapes_at, liquid.density_kg_m3)
        w2, Q = scipy.linalg.eigh(np.diag(lam), np.eye(k) + Ma)
        if np.any(np.abs(w2[:6]) > 1e-8 * lam.max()):
            raise ArithmeticError(f"the six rigid-body modes of the filled container are not at zero: {w2[:6]}")
        w2, Q = w2[6:], Q[:, 6:]
        return FilledModalModel(self, liquid, volume, w2, Q, S, mesh)


class FilledModalModel:
    """A container with liquid: the interface of :class:`~sensors.ModalModel` that synthesis and
    the simulated sensor use, delegating geometry to the dry model.

    Build with :meth:`Container.fill`. ``mode_shapes`` are the wall's displacement (the liquid has
    no nodes); modal mass is 1 including the liquid's kinetic energy.
    """

    def __init__(self, container: Container, liquid: Liquid, volume_m3: float, eigenvalues, Q, slip, mesh):
        self.container = container
        self.dry = container.dry
        self.liquid = liquid
        self.liquid_volume_m3 = float(volume_m3)
        self.eigenvalues = np.asarray(eigenvalues, dtype=np.float64)
        self.modal_coefficients = Q  # (6 + r_basis, r): wet modes on rigid-body + dry modes
        self._slip = slip
        self.liquid_mesh = mesh
        self.metadata = dict(self.dry.metadata, kind="filled " + str(self.dry.metadata.get("kind", "mesh")),
                             liquid=liquid.to_dict(), liquid_volume_m3=self.liquid_volume_m3)

    # ---------------------------------------------------------------- modal quantities

    @property
    def material(self):
        return self.dry.material

    @property
    def n_modes(self) -> int:
        return len(self.eigenvalues)

    @property
    def angular_frequencies_rad_s(self) -> np.ndarray:
        return np.sqrt(self.eigenvalues)

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.angular_frequencies_rad_s / (2.0 * np.pi)

    @property
    def liquid_mass_kg(self) -> float:
        return self.liquid.density_kg_m3 * self.liquid_volume_m3

    @property
    def mass_kg(self) -> float:
        """Container plus liquid [kg]."""
        return self.dry.mass_kg + self.liquid_mass_kg

    @property
    def fill_fraction(self) -> float:
        return self.liquid_volume_m3 / self.container.cavity.volume_m3

    def viscous_decay_rates(self) -> np.ndarray:
        """Boundary-layer decay rate of each wet mode [1/s] (zero when empty or inviscid)."""
        if self._slip is None or self.liquid.viscosity_pa_s == 0.0:
            return np.zeros(self.n_modes)
        Q = self.modal_coefficients
        integral = np.einsum("ik,ij,jk->k", Q, self._slip, Q)
        w = self.angular_frequencies_rad_s
        return 0.5 * np.sqrt(self.liquid.density_kg_m3 * self.liquid.viscosity_pa_s * w / 2.0) * integral

    def damping_matrix(self, contacts=()):
        """Modal damping (r, r) [1/s]: wall Rayleigh + contact damping, plus the liquid's boundary layer."""
        contacts = list(contacts)
        mat = self.material
        Q = self.modal_coefficients
        k = Q.shape[0]
        lam = np.concatenate([np.zeros(6), np.asarray(self.dry.eigenvalues)[: k - 6]])
        diag = float(mat.alpha) + float(mat.beta) * lam
        C = (Q.T * diag) @ Q + np.diag(2.0 * self.viscous_decay_rates())
        if contacts:
            check_on_surface(self, np.array([c.position_m for c in contacts]), "contact")
            C = C + float(mat.gamma) * contact_damping_matrix(self, contacts)
        return 0.5 * (C + C.T)

    @property
    def decay_rates(self) -> np.ndarray:
        """Modal decay rates [1/s] without contacts (half the damping matrix's diagonal)."""
        return 0.5 * np.diag(self.damping_matrix())

    # ---------------------------------------------------------------- geometry (delegated)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Wet mode shapes of the wall at points [m / sqrt(kg)], (n, 3, r)."""
        return self.container.basis_shapes_at(points_m) @ self.modal_coefficients

    def surface_distance_m(self, points_m) -> np.ndarray:
        return self.dry.surface_distance_m(points_m)

    def surface_normal_at(self, points_m) -> np.ndarray:
        return self.dry.surface_normal_at(points_m)

    def describe(self) -> str:
        f = self.frequencies_hz
        return (f"{self.dry.describe()} holding {self.liquid_volume_m3 * 1e6:.4g} ml of {self.liquid.name} "
                f"({100 * self.fill_fraction:.0f}% full), wet modes {f[0]:.0f}-{f[-1]:.0f} Hz")

    def __repr__(self) -> str:
        return f"FilledModalModel<{self.describe()}>"
