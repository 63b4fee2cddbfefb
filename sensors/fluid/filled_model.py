"""The wet modes of a container holding a liquid: the dry modes, a potential-flow added mass and,
for a compressible liquid, the liquid's own acoustic modes.

Built by :func:`sensors.fluid.filled` (the entry point, :mod:`sensors.fluid.filling`) on a
:class:`~sensors.fluid.container.Container`.

Physics (potential flow, the classic added-mass model of liquid-filled shells; Lindholm, Kana
& Abramson 1962; Amabili, Paidoussis & Lakis, J. Sound Vib. 213 (1998) 259):

* The liquid's velocity is grad(phi) with Laplace's equation in the liquid volume,
  phi = 0 (p = -rho dphi/dt = 0) on the free surface, and d(phi)/dn = u . n on the wetted
  wall (normal velocity continuity). Gravity waves (sloshing, < 10 Hz) are ignored. This is the
  incompressible model (``compressible=False``): exact for the ovalling modes, which change no
  volume, but not for the volume-changing (breathing) ones, which couple to the liquid's own
  acoustic modes (a water column h deep over a rigid floor under a free surface rings at
  c / 4h, 4.2 kHz in a full mug).
* With the wall motion expanded on a basis, u = sum_i qdot_i u_i, each vector's potential
  phi_i solves that problem with Neumann data n . u_i, and the liquid's kinetic energy is
  1/2 qdot^T M_a qdot with M_a[i, j] = rho integral_wet phi_i (n . u_j) dS = rho C^T H^-1 C
  (H the liquid's Laplacian, C[a, j] = integral_wet N_a (n . u_j) dS).
* The basis: the six rigid-body modes of the free container (the liquid couples them to the
  elastic modes), its dry elastic modes, and a static correction (:mod:`sensors.fluid.added_mass`):
  the container's static response to smooth pressures on its wetted wall, with the dry modes
  removed. A liquid's pressure excites the wall's stiff breathing motion, far above the band,
  and the correction supplies that compliance (without it a cup's bottom mode came out 2.4 %
  high against a fully coupled solve). The dry modes and the correction are K- and
  M-orthogonal, so the wet modes solve Lambda q = w^2 (I + M_a) q; the wet shapes are
  U q with q^T (I + M_a) q = 1 (mass-normalized including the liquid). Wet modes are kept up to
  the dry model's band limit (never cutting a cluster).
* The compressible liquid (``compressible=True``, the default): the pressure obeys Helmholtz'
  equation with the liquid's speed of sound c, p = 0 on the free surface, dp/dn = rho w^2 u . n
  on the wetted wall, and the pressure loads the wall. On the liquid's P2 mesh
  (H - w^2 Q) p = rho w^2 C q and (Lambda - w^2 I) q = C^T p, with Q = Q0 / c^2 (Q0 the liquid's
  mass matrix): the unsymmetric coupled problem [Lambda 0; -C^T H] = w^2 [I 0; rho C Q]. The
  liquid's basis is its own acoustic modes with rigid walls, H psi_l = w_l^2 Q psi_l
  (psi^T Q psi = I), kept up to twice the band limit, plus their static remainder:
  (H - w^2 Q)^-1 = H^-1 + sum_l psi_l psi_l^T w^2 / (w_l^2 (w_l^2 - w^2)) exactly, and the
  first term is the incompressible added mass. With B[:, l] = sqrt(rho) C^T psi_l / w_l and
  the liquid coordinates r_l = w^2 B[:, l]^T q / (w_l^2 - w^2), the coupled problem becomes the
  symmetric one

      [Lambda 0; 0 diag(w_l^2)] [q; r] = w^2 [I + M_a  B; B^T  I] [q; r],

  whose mass matrix is positive definite (B B^T <= M_a). Dropped: the modes above the cut, each
  of which would add w^2 / (w_l^2 - w^2) of its (small) share of M_a, at most 1/3 at the band's
  top, 1/15 at half of it. As c -> infinity every w_l leaves the cut and the model is exactly
  the incompressible one. The wet shapes are U q, normalized with the liquid's kinetic and
  compressive energy.

Numerics: P2 tets on the liquid (:mod:`sensors.fluid.cavity`: structured and cheap for revolved
cavities, any tilt), Neumann data from the basis at the wetted boundary's quadrature points,
one sparse factorization of the liquid's Laplacian per fill.

Damping (a documented approximation):

* The wall's Rayleigh damping alpha M + beta K: the stiffness part is exactly diagonal on the
  wet modes, beta w^2; the mass part is applied to the wet modal mass (wall plus liquid), which
  overstates it by the liquid's share (alpha is 1-5 1/s for the container materials, small
  against beta w^2 in the audio band).
* The liquid's viscosity: the Stokes boundary layer on the wetted wall. A wall slipping
  tangentially past the potential flow at velocity amplitude U dissipates on average
  1/2 U^2 sqrt(rho mu w / 2) per unit area (Landau & Lifshitz, Fluid Mechanics, section 24),
  so wet mode k gains the decay rate
  sigma_k = 1/2 sqrt(rho mu w_k / 2) integral_wet |(u_k - grad phi_k)_tangential|^2 dS,
  given to synthesis as the extra modal damping 2 sigma_k (``added_damping_per_s``). Bulk
  dissipation of the potential flow (smaller by the layer thickness over the container size)
  and free-surface losses are neglected; the layer is thin for every built-in liquid (honey's
  is about 1 mm at 3 kHz, against a 30 mm cup). The compressible model takes the slip of the
  incompressible flow (its tangential velocity near the wall), an approximation for modes with
  a large share of liquid compression.
"""


from __future__ import annotations

import functools

import numpy as np
import scipy.linalg

from .liquid_body import LiquidBody
from ..materials.solids import get_material
from ..modal.basis import band_text, material_scaling
from ..modal.damping import modal_damping_matrix, within_surface_distance_m

__all__ = ["FilledModalModel"]

#: Frequencies within this relative distance count as one cluster, never cut (as the dry solve).
_CLUSTER_RTOL = 2e-3


def _cut(freqs: np.ndarray, limit_hz: float) -> int:
    """Modes to keep: all up to ``limit_hz`` plus the rest of a cluster at the cut."""
    n = int(np.searchsorted(freqs, limit_hz, side="right"))
    while 0 < n < len(freqs) and freqs[n] <= freqs[n - 1] * (1.0 + _CLUSTER_RTOL):
        n += 1
    return n


def _unscaled_wall(model: "FilledModalModel") -> tuple:
    """``model``'s wall matrices as :class:`FilledModalModel` takes them (its material's scale
    taken off): what a material view of it is built from."""
    ma, s, b, wl2 = model._wall
    if ma is None:
        return None, None, None, None
    scale = model._shape_scale
    return ma / scale**2, s / scale**2, b / scale, wl2


class FilledModalModel:
    """A container with liquid: a :class:`~sensors.ModalBasis` (what synthesis and the simulated
    sensor take), with the wall's geometry queries delegated to the dry model.

    Build with :func:`sensors.fluid.filled`. Mode shapes are the wall's
    displacement (the liquid has no nodes); the modal mass is 1 including the liquid's kinetic
    energy. ``liquid`` is the :class:`LiquidBody` (mass, centre of mass) a physics engine
    should carry.
    """

    #: A plain material rescaling (``sensors.MaterialView``) is not exact for a filled container:
    #: the liquid's added mass does not scale with the wall's density. ``with_material`` is.
    material_scales_modes = False

    def __init__(self, container, liquid: LiquidBody, added_mass, slip, material=None, *,
                 liquid_coupling=None, liquid_eigenvalues=None, compressible: bool = False):
        """``added_mass`` M_a and ``slip`` S on the container's basis (None: empty); for a
        compressible liquid ``liquid_coupling`` B (n_basis, m) and ``liquid_eigenvalues`` w_l^2
        (m,) [rad^2/s^2] of its acoustic modes (:mod:`sensors.fluid.acoustic`)."""
        self.container = container
        self.compressible = bool(compressible)
        self.dry = container.dry
        self.liquid = liquid
        self.material = get_material(material) if material is not None else self.dry.material
        freq_scale, self._shape_scale = material_scaling(self.dry.material, self.material)
        band = container.band_limit_hz * freq_scale
        self._freq_scale, self._band_hz = freq_scale, band
        self.__dict__["_wall"] = self._scaled(added_mass, slip, liquid_coupling, liquid_eigenvalues)
        self.metadata = dict(self.dry.metadata, kind=f"{container.name} with {liquid.liquid.name}",
                             material=self.material.name, liquid=liquid.liquid.to_dict(),
                             liquid_volume_m3=liquid.volume_m3, fill_fraction=self.fill_fraction,
                             liquid_model=self.liquid_model,
                             surface_normal=np.asarray(liquid.surface_normal).tolist(), max_frequency_hz=band)

    def _scaled(self, added_mass, slip, liquid_coupling=None, liquid_eigenvalues=None) -> tuple:
        if added_mass is None:
            return None, None, None, None
        return (added_mass * self._shape_scale**2, slip * self._shape_scale**2,
                (np.zeros((self.container.n_basis, 0)) if liquid_coupling is None
                 else liquid_coupling * self._shape_scale),
                np.zeros(0) if liquid_eigenvalues is None else np.asarray(liquid_eigenvalues, float))

    @classmethod
    def pending(cls, container, liquid: LiquidBody, compressible: bool, build, material=None) -> "FilledModalModel":
        """The model of ``liquid`` (its :class:`LiquidBody`, now) whose ``added_mass``, ``slip``,
        ``liquid_coupling`` and ``liquid_eigenvalues`` (as :meth:`__init__` takes them) ``build()``
        returns when one is first read: a table's fill (``sensors.fluid.fill_table.LAZY_WET_MATRICES``),
        an exact fill (``sensors.fluid.filling.LAZY_EXACT_MATRICES``) and a material view
        (:meth:`with_material`)."""
        self = cls(container, liquid, None, None, material, compressible=compressible)
        del self.__dict__["_wall"]
        self._build = build
        return self

    # The wall's matrices and the wet eigen-solve are both made when first read, not at
    # construction: an env with sensing off reads neither (it needs only the liquid's body), and
    # an env that hears a filled container through a material view (domain randomization,
    # ``with_material``) reads only the view's modes, so the filled model's own solve would be
    # thrown away. The quantities are exactly those of making them at construction.
    @functools.cached_property
    def _wall(self) -> tuple:
        """(M_a, S, B, w_l^2): added mass, slip, liquid coupling (scaled to the wall's material)
        and the liquid's eigenvalues; Nones without liquid. Given to :meth:`__init__`, or built
        by :meth:`pending`'s build."""
        return self._scaled(*self._build())

    _Ma = property(lambda self: self._wall[0])
    _S = property(lambda self: self._wall[1])
    _B = property(lambda self: self._wall[2])
    _wl2 = property(lambda self: self._wall[3])

    @functools.cached_property
    def _wet_solution(self) -> tuple[np.ndarray, np.ndarray]:
        """(w^2 (r,) [rad^2/s^2], Q (n_basis, r)) of the wet modes up to the band limit."""
        container = self.container
        lam = container.basis_eigenvalues * self._freq_scale**2
        if self._Ma is None:
            # No liquid: exactly the dry modes (no eigen-solve whose round-off would rotate pairs).
            n = container.n_dry
            Q = np.zeros((container.n_basis, n))
            Q[6:6 + n] = np.eye(n)
            return np.asarray(lam[6:6 + n], dtype=np.float64).copy(), Q
        B, wl2 = self._B, self._wl2
        nb, m = len(lam), len(wl2)
        mass = np.block([[np.eye(nb) + self._Ma, B], [B.T, np.eye(m)]])
        w2, X = scipy.linalg.eigh(np.diag(np.concatenate([lam, wl2])), 0.5 * (mass + mass.T))
        Q = X[:nb]
        if np.any(np.abs(w2[:6]) > 1e-8 * lam.max()):
            raise ArithmeticError(f"the six rigid-body modes of the filled container are not at zero: {w2[:6]}")
        w2, Q = w2[6:], Q[:, 6:]
        n = _cut(np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi), self._band_hz)
        return np.asarray(w2[:n], dtype=np.float64), Q[:, :n]

    @functools.cached_property
    def eigenvalues(self) -> np.ndarray:
        """w^2 [rad^2/s^2] of the wet modes."""
        return self._wet_solution[0]

    @functools.cached_property
    def modal_coefficients(self) -> np.ndarray:
        """(n_basis, r) wet modes on the container's basis (rigid, dry, correction)."""
        return self._wet_solution[1]

    @functools.cached_property
    def angular_frequencies_rad_s(self) -> np.ndarray:
        return np.sqrt(self.eigenvalues)

    @functools.cached_property
    def frequencies_hz(self) -> np.ndarray:
        return self.angular_frequencies_rad_s / (2.0 * np.pi)

    @functools.cached_property
    def added_damping_per_s(self) -> np.ndarray:
        """Twice the liquid's boundary-layer decay rate of each wet mode [1/s]."""
        return 2.0 * self.viscous_decay_rates_per_s()

    # ---------------------------------------------------------------- modal quantities

    @property
    def n_modes(self) -> int:
        """Number of wet elastic modes r."""
        return len(self.eigenvalues)

    @property
    def liquid_model(self) -> str:
        """``"compressible"`` (the liquid's acoustic modes coupled to the wall) or
        ``"incompressible"`` (potential-flow added mass)."""
        return "compressible" if self.compressible else "incompressible"

    @property
    def n_liquid_modes(self) -> int:
        """Acoustic modes of the liquid in the basis (0 for an incompressible or no liquid)."""
        return 0 if self._wl2 is None else len(self._wl2)

    @property
    def liquid_modes_hz(self) -> np.ndarray:
        """The liquid's own acoustic modes [Hz] (rigid walls, free surface) in the basis."""
        return np.zeros(0) if self._wl2 is None else np.sqrt(self._wl2) / (2 * np.pi)

    @property
    def liquid_volume_m3(self) -> float:
        return self.liquid.volume_m3

    @property
    def fill_fraction(self) -> float:
        """Liquid volume over the cavity's volume."""
        return self.liquid.volume_m3 / self.container.volume_m3

    @property
    def mass_kg(self) -> float:
        """Container plus liquid [kg] (the drive model's object mass)."""
        return self.dry.mass_kg * self.material.density_kg_m3 / self.dry.material.density_kg_m3 + self.liquid.mass_kg

    def viscous_decay_rates_per_s(self) -> np.ndarray:
        """Boundary-layer decay rate sigma_k of each wet mode [1/s] (zero when empty or inviscid)."""
        mu = self.liquid.liquid.viscosity_pa_s
        if self._S is None or mu == 0.0:
            return np.zeros(self.n_modes)
        Q = self.modal_coefficients
        integral = np.einsum("ik,ij,jk->k", Q, self._S, Q)
        rho = self.liquid.liquid.density_kg_m3
        return 0.5 * np.sqrt(rho * mu * self.angular_frequencies_rad_s / 2.0) * integral

    @property
    def decay_rates_per_s(self) -> np.ndarray:
        """Decay rates without contacts [1/s]: Rayleigh (alpha + beta w^2) / 2 plus the liquid's."""
        return self.material.decay_rate(self.angular_frequencies_rad_s) + 0.5 * self.added_damping_per_s

    def damping_matrix(self, contacts=()) -> np.ndarray:
        """C_m (r, r) [1/s] as synthesis builds it (:func:`sensors.modal_damping_matrix`)."""
        return modal_damping_matrix(self, contacts)

    def with_material(self, material) -> "FilledModalModel":
        """The same container and liquid with the wall in ``material`` (same Poisson ratio):
        exact without a new FEM solve (K scales with E, the wall's mass with its density, the
        liquid's added mass not at all)."""
        material = get_material(material)
        if material == self.material:
            return self
        # a view of a model whose wall is not built yet stays unbuilt; the two share one build
        return FilledModalModel.pending(self.container, self.liquid, self.compressible,
                                        functools.partial(_unscaled_wall, self), material)

    # ---------------------------------------------------------------- geometry (the wall's)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Wet mode shapes of the wall at points [m / sqrt(kg)], (n, 3, r)."""
        U = self.container.basis_shapes_at(points_m)
        return (U @ self.modal_coefficients) * self._shape_scale

    @functools.cached_property
    def rigid_coefficients(self) -> np.ndarray:
        """(n_basis, 6) the filled container's rigid-body modes on its basis, mass-normalized
        with the liquid (Q_r^T (I + M_a) Q_r = I; no liquid coordinates).

        The basis's six rigid columns span the stiffness's null space (the liquid's acoustic
        coordinates, with w_l > 0, are not in it), so the rigid modes are those columns
        orthonormalized in the wet mass, Q_r = [L^-T; 0] with L L^T the rigid block of
        I + M_a: no eigen-solve, exactly zero frequency, and M-orthogonal to every wet elastic
        mode (w^2 x_r^T M x_e = x_r^T K x_e = 0)."""
        Q = np.zeros((self.container.n_basis, 6))
        mass = np.eye(6) if self._Ma is None else np.eye(6) + 0.5 * (self._Ma[:6, :6] + self._Ma[:6, :6].T)
        Q[:6] = scipy.linalg.solve_triangular(np.linalg.cholesky(mass), np.eye(6), lower=True).T
        return Q

    def rigid_mode_shapes_at(self, points_m) -> np.ndarray:
        """The filled container's six rigid-body modes at points [m / sqrt(kg)], (n, 3, 6): what
        its contact springs hold beside the wet elastic modes (``sensors.modal.spring_modes``)."""
        U = self.container.rigid_shapes_at(points_m)
        return (U @ self.rigid_coefficients[:6]) * self._shape_scale

    def surface_distance_m(self, points_m) -> np.ndarray:
        """Distance [m] to the container's surface (the dry model's)."""
        return self.dry.surface_distance_m(points_m)

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        """Whether points lie within ``limit_m`` [m] of the container's surface (the dry model's)."""
        return within_surface_distance_m(self.dry, points_m, limit_m)

    def surface_normal_at(self, points_m) -> np.ndarray:
        """Outward unit normal of the container's surface (the dry model's)."""
        return self.dry.surface_normal_at(points_m)

    def describe(self) -> str:
        band = band_text(self.frequencies_hz)
        return (f"{self.container.name} of {self.material.name} holding {self.liquid.volume_m3 * 1e6:.4g} ml of "
                f"{self.liquid.liquid.name} ({100 * self.fill_fraction:.0f}% full, {self.liquid_model}), "
                f"{self.n_modes} wet modes {band}")

    def __repr__(self) -> str:
        return f"FilledModalModel<{self.describe()}>"

