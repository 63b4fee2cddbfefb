"""Containers holding a liquid: wet modes from the dry modes and a potential-flow added mass.

Entry point::

    wet = sensors.fluid.model.filled("mug", fill_fraction=0.5, liquid="water")
    wet.frequencies_hz, wet.mode_shapes_at(points_m)     # a ModalBasis: synthesis takes it as is
    wet.liquid.mass_kg, wet.liquid.centre_of_mass_m      # what MuJoCo should carry

Physics (potential flow, the classic added-mass model of liquid-filled shells; Lindholm, Kana
& Abramson 1962; Amabili, Paidoussis & Lakis, J. Sound Vib. 213 (1998) 259):

* The liquid's velocity is grad(phi) with Laplace's equation in the liquid volume,
  phi = 0 (p = -rho dphi/dt = 0) on the free surface, and d(phi)/dn = u . n on the wetted
  wall (normal velocity continuity). Gravity waves (sloshing, < 10 Hz) are ignored, and so is
  compressibility. That is exact for the ovalling modes, which change no volume, but not for
  the axisymmetric (breathing) ones: a water column h deep over a rigid floor under a free
  surface rings at c / 4h, 4.2 kHz in a full mug, inside the band; the volume-changing wall
  modes near it couple to it, which this model misses (the issue's model is incompressible;
  a compressible liquid adds its acoustic modes to the coupled problem).
* With the wall motion expanded on a basis, u = sum_i qdot_i u_i, each vector's potential
  phi_i solves that problem with Neumann data n . u_i, and the liquid's kinetic energy is
  1/2 qdot^T M_a qdot with M_a[i, j] = rho integral_wet phi_i (n . u_j) dS.
* The basis: the six rigid-body modes of the free container (the liquid couples them to the
  elastic modes), its dry elastic modes, and a static correction (:mod:`sensors.fluid.added_mass`):
  the container's static response to smooth pressures on its wetted wall, with the dry modes
  removed. A liquid's pressure excites the wall's stiff breathing motion, far above the band,
  and the correction supplies that compliance (without it a cup's bottom mode came out 2.4 %
  high against a fully coupled solve). The dry modes and the correction are K- and
  M-orthogonal, so the wet modes solve Lambda q = w^2 (I + M_a) q; the wet shapes are
  U q with q^T (I + M_a) q = 1 (mass-normalized including the liquid). Wet modes are kept up to
  the dry model's band limit (never cutting a cluster).

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
  is about 1 mm at 3 kHz, against a 30 mm cup).
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math

import numpy as np
import scipy.linalg

from .._infra import cache as cache_mod
from .added_mass import liquid_loading, static_correction
from .cavity import AxisymmetricCavity, LiquidMesh, cavity_of, p2_mass_properties, unit
from ..modal.damping import modal_damping_matrix
from ..fem.assembly import QUADRATURE, shape_functions, shape_gradients_ref
from ..materials.liquids import LIQUIDS, Liquid, get_liquid
from ..materials.solids import get_material
from ..modal.basis import band_text, material_scaling

__all__ = ["filled", "container", "Container", "FilledModalModel", "LiquidBody", "Liquid", "LIQUIDS"]

#: Options of :class:`Container` (the rest of ``filled``'s keyword arguments build the dry model).
CONTAINER_OPTIONS = ("correction_degree", "liquid_n_theta", "liquid_element_size_m", "max_dry_frequency_hz")
#: Frequencies within this relative distance count as one cluster, never cut (as the dry solve).
_CLUSTER_RTOL = 2e-3


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


@dataclasses.dataclass(frozen=True)
class LiquidBody:
    """The liquid in a container, as a rigid body for a physics engine (object frame, SI).

    Attributes:
        liquid: What it is.
        volume_m3: Its volume.
        mass_kg: Its mass.
        centre_of_mass_m: (3,) centre of mass in the object frame (the cavity's floor centre
            when empty).
        inertia_kg_m2: (3, 3) inertia tensor about the centre of mass, object axes, of the
            liquid frozen in its shape. A liquid does not spin with its container, so this is an
            upper bound of what it resists in rotation; its mass and centre are exact.
        surface_normal: (3,) unit normal of the free surface, against gravity (object frame).
        surface_offset_m: The free surface is the plane ``surface_normal . p = surface_offset_m``.
    """

    liquid: Liquid
    volume_m3: float
    mass_kg: float
    centre_of_mass_m: np.ndarray
    inertia_kg_m2: np.ndarray
    surface_normal: np.ndarray
    surface_offset_m: float

    def to_dict(self) -> dict:
        """Plain-JSON form."""
        return {"liquid": self.liquid.to_dict(), "volume_m3": self.volume_m3, "mass_kg": self.mass_kg,
                "centre_of_mass_m": np.asarray(self.centre_of_mass_m).tolist(),
                "inertia_kg_m2": np.asarray(self.inertia_kg_m2).tolist(),
                "surface_normal": np.asarray(self.surface_normal).tolist(),
                "surface_offset_m": self.surface_offset_m}


class Container:
    """A container's dry modal model and its cavity, with the per-container work every fill reuses.

    Per container (once; the static correction is cached on disk next to the modal models):
    the rigid-body modes and the static-correction vectors. Per fill: the liquid's mesh, one
    Laplace solve for all basis vectors and a small dense eigenproblem.

    Args:
        dry: The container's dry :class:`~sensors.ModalModel` (free-free, P2, with its mesh).
        cavity: An :class:`~sensors.fluid.cavity.AxisymmetricCavity` or
            :class:`~sensors.fluid.cavity.SurfaceCavity` in the model's frame, or an object with one
            (:func:`sensors.fluid.cavity.cavity_of`).
        up_axis: The object-frame direction that points up when the container stands upright
            (default: the axis of an axisymmetric cavity, else +z).
        correction_degree: Total polynomial degree of the wall pressures whose static response
            corrects the basis (0 or None: no correction; 4 gives about 35 vectors).
        liquid_n_theta: Liquid elements around an axisymmetric cavity (a multiple of 8).
        liquid_element_size_m: Liquid element size (axial for axisymmetric cavities).
        max_dry_frequency_hz: Use only dry modes up to this frequency (default: all); for
            truncation studies.
        cache, cache_dir: The disk cache of the static correction (as the modal models').
    """

    def __init__(self, dry, cavity, *, up_axis=None, correction_degree: int | None = 4, liquid_n_theta: int = 16,
                 liquid_element_size_m: float | None = None, max_dry_frequency_hz: float | None = None,
                 cache: bool = True, cache_dir=None, name: str | None = None):
        if not all(hasattr(dry, a) for a in ("nodes_m", "elements", "mode_shapes", "locator")):
            raise TypeError(f"a Container needs a sensors.ModalModel with its mesh, got {type(dry).__name__} "
                            "(for another material, fill the container and use the filled model's with_material)")
        self.dry = dry
        self.cavity = cavity_of(cavity)
        self.name = name or str(dry.metadata.get("kind", "container"))
        if up_axis is None:
            up_axis = self.cavity.upright_up if isinstance(self.cavity, AxisymmetricCavity) else (0.0, 0.0, 1.0)
        self.up_axis = unit(up_axis)
        f = np.asarray(dry.frequencies_hz)
        self.n_dry = len(f) if max_dry_frequency_hz is None else int(np.searchsorted(f, max_dry_frequency_hz, "right"))
        self.band_limit_hz = float(max_dry_frequency_hz if max_dry_frequency_hz is not None
                                   else dry.metadata.get("max_frequency_hz", f[-1] if len(f) else 0.0))
        self.liquid_n_theta = int(liquid_n_theta)
        self.liquid_element_size_m = liquid_element_size_m
        self._mass_kg, self._centre_m, self._rot = _rigid_body_data(dry)
        self.correction_degree = int(correction_degree or 0)
        if self.correction_degree > 0:
            lam_c, shapes_c = self._correction(cache, cache_dir)
        else:
            lam_c, shapes_c = np.zeros(0), np.zeros((len(dry.nodes_m), 3, 0))
        self.n_correction = len(lam_c)
        #: (6 + n_dry + n_correction,) eigenvalues [rad^2/s^2] of the basis: rigid, dry, correction.
        self.basis_eigenvalues = np.concatenate([np.zeros(6), np.asarray(dry.eigenvalues)[: self.n_dry], lam_c])
        self._nodal = np.ascontiguousarray(np.concatenate([dry.mode_shapes[:, :, : self.n_dry], shapes_c], axis=2))
        self._fills: collections.OrderedDict = collections.OrderedDict()

    # ---------------------------------------------------------------- construction helpers

    @classmethod
    def of(cls, obj, dry=None, **options) -> "Container":
        """The container of an :class:`~sensors.objects.everyday.EverydayObject` (or its name).

        Args:
            dry: Its dry modal model if already built (default ``obj.modal_model(...)``, cached).
            options: :class:`Container` options (``correction_degree``, ...) and options of
                ``obj.modal_model`` (``resolution``, ``max_frequency_hz``, ``cache_dir``,
                ``progress``, ...).
        """
        if isinstance(obj, str):
            from ..objects.everyday import everyday_object  # trimesh-heavy: only when asked by name

            obj = everyday_object(obj)
        mine = {k: options.pop(k) for k in list(options) if k in CONTAINER_OPTIONS}
        caching = {k: options[k] for k in ("cache", "cache_dir") if k in options}
        if dry is None:
            dry = obj.modal_model(**options)
        elif set(options) - set(caching):
            raise TypeError(f"dry model given: build options {sorted(set(options) - set(caching))} do not apply")
        return cls(dry, cavity_of(obj), up_axis=obj.up_axis, name=obj.name, **caching, **mine)

    def _wetted_faces(self):
        tol = 5e-3 * self.cavity.size_m

        def select(corners, points):
            d = self.cavity.wall_distance_m(points.reshape(-1, 3)).reshape(points.shape[:2])
            return np.all(d <= tol, axis=1)

        return select

    def _correction(self, cache, cache_dir):
        dry = self.dry
        ident = dry.metadata.get("cache_key") or cache_mod.content_key(dry.nodes_m, dry.elements, dry.frequencies_hz)
        cav = self.cavity
        cav_id = ([cav.axial_m, cav.radius_m, cav.origin_m, cav.axis] if isinstance(cav, AxisymmetricCavity)
                  else [np.asarray(cav.mesh.vertices), np.asarray(cav.mesh.faces)])
        key = cache_mod.content_key("fluid static correction", ident, dry.material.to_dict(), self.n_dry,
                                    type(cav).__name__, cav_id, self.correction_degree,
                                    cache_mod.source_version("sensors.fluid.added_mass", "sensors.fluid.cavity", "sensors.fem.assembly", "sensors.fem.eigen"))

        def build():
            dry_n = dry if self.n_dry == dry.n_modes else _truncated(dry, self.n_dry)
            return static_correction(dry_n, self._wetted_faces(), degree=self.correction_degree)

        if not cache:
            return build()
        hit = cache_mod.load_arrays(key, cache_dir)
        if hit is None:
            with cache_mod.build_lock(key, cache_dir):
                hit = cache_mod.load_arrays(key, cache_dir)
                if hit is None:
                    lam, shapes = build()
                    hit = {"eigenvalues": lam, "shapes": shapes}
                    cache_mod.save_arrays(key, hit, cache_dir)
        return np.asarray(hit["eigenvalues"]), np.asarray(hit["shapes"])

    # ---------------------------------------------------------------- the basis

    @property
    def n_basis(self) -> int:
        """Basis size: 6 rigid-body modes, the dry modes used and the correction vectors."""
        return len(self.basis_eigenvalues)

    def basis_shapes_at(self, points_m) -> np.ndarray:
        """(n, 3, n_basis) mass-normalized basis at points [m / sqrt(kg)]: 3 translations, 3
        rotations about the centre of mass, the dry modes, the correction vectors."""
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        r = p - self._centre_m
        cross = np.zeros((len(p), 3, 3))  # [r]_x
        cross[:, 0, 1], cross[:, 0, 2] = -r[:, 2], r[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = r[:, 2], -r[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = -r[:, 1], r[:, 0]
        trans = np.broadcast_to(np.eye(3) / math.sqrt(self._mass_kg), (len(p), 3, 3))
        rot = -cross @ self._rot  # (a x r) for rotation vectors a = columns of J^-1/2
        tet, bary = self.dry.locator.locate(p)
        N = shape_functions(bary, self.dry.element)
        nodal = self._nodal[self.dry.elements[tet]]  # (n, n_el, 3, k)
        elastic = np.matmul(N[:, None, :], nodal.reshape(len(p), N.shape[1], -1)).reshape(len(p), 3, -1)
        return np.concatenate([trans, rot, elastic], axis=2)

    # ---------------------------------------------------------------- how much liquid

    @property
    def volume_m3(self) -> float:
        """Volume of the whole cavity (floor to rim) [m^3]."""
        return self.cavity.volume_m3

    def surface_normal(self, surface_normal=None) -> np.ndarray:
        """The unit free-surface normal (against gravity, object frame); default upright."""
        return self.up_axis.copy() if surface_normal is None else unit(surface_normal)

    def max_fill_fraction(self, surface_normal=None) -> float:
        """The largest fill fraction that stays in the container at this tilt."""
        return min(1.0, self.cavity.max_volume_m3(self.surface_normal(surface_normal)) / self.volume_m3)

    def liquid_volume_m3(self, *, fill_fraction=None, fill_height_m=None, volume_m3=None) -> float:
        """Liquid volume from exactly one of a fill fraction (of the cavity), an upright height
        above the inner floor [m] (axisymmetric cavities) or a volume [m^3]."""
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
                raise TypeError("fill_height_m needs an axisymmetric cavity; give fill_fraction or volume_m3")
            if not 0.0 <= fill_height_m <= self.cavity.depth_m * (1 + 1e-12):
                raise ValueError(f"fill_height_m must be in [0, {self.cavity.depth_m:.4g}] m, got {fill_height_m}")
            return self.cavity.volume_below_m3(fill_height_m)
        if not 0.0 <= volume_m3 <= total * (1 + 1e-12):
            raise ValueError(f"volume_m3 must be in [0, {total:.4g}] m^3, got {volume_m3}")
        return float(volume_m3)

    def liquid_mesh(self, volume_m3: float, surface_normal=None) -> LiquidMesh:
        """The liquid's P2 mesh (raises :class:`~sensors.fluid.cavity.LiquidSpillError` if it spills,
        :class:`~sensors.MeshError` if the tilted surface uncovers part of the floor)."""
        return self.cavity.liquid_mesh(volume_m3, self.surface_normal(surface_normal), n_theta=self.liquid_n_theta,
                                       element_size_m=self.liquid_element_size_m)

    def _body(self, liquid: Liquid, volume: float, up: np.ndarray, mesh: LiquidMesh | None) -> LiquidBody:
        if mesh is None:
            floor = (self.cavity.origin_m if isinstance(self.cavity, AxisymmetricCavity)
                     else np.asarray(self.cavity.mesh.vertices).min(axis=0))
            return LiquidBody(liquid, 0.0, 0.0, np.array(floor, float), np.zeros((3, 3)), up, float(up @ floor))
        mass, centre, inertia = p2_mass_properties(mesh.nodes_m, mesh.tets, liquid.density_kg_m3)
        # The mesh's volume is within its discretization error of the one asked for: scale to it.
        scale = liquid.density_kg_m3 * volume / mass
        return LiquidBody(liquid, volume, liquid.density_kg_m3 * volume, centre, inertia * scale, up,
                          mesh.surface_offset_m)

    def liquid_body(self, liquid="water", *, fill_fraction=None, fill_height_m=None, volume_m3=None,
                    surface_normal=None) -> LiquidBody:
        """The liquid's mass, centre of mass and inertia (object frame) without the modal work."""
        liquid = get_liquid(liquid)
        volume = self.liquid_volume_m3(fill_fraction=fill_fraction, fill_height_m=fill_height_m, volume_m3=volume_m3)
        up = self.surface_normal(surface_normal)
        return self._body(liquid, volume, up, self.liquid_mesh(volume, up) if volume > 0 else None)

    # ---------------------------------------------------------------- the wet model

    def fill(self, liquid="water", *, fill_fraction=None, fill_height_m=None, volume_m3=None,
             surface_normal=None) -> "FilledModalModel":
        """The container holding ``liquid`` (a name, a :class:`~sensors.materials.liquids.Liquid` or a
        density [kg/m^3]).

        Args:
            fill_fraction / fill_height_m / volume_m3: How much liquid (exactly one).
            surface_normal: Unit normal of the free surface against gravity, in the object frame
                (the world's up direction seen from the object; default: standing upright). A
                tilted container keeps its volume and gets a tilted free surface.
        """
        liquid = get_liquid(liquid)
        volume = self.liquid_volume_m3(fill_fraction=fill_fraction, fill_height_m=fill_height_m, volume_m3=volume_m3)
        up = self.surface_normal(surface_normal)
        key = (liquid, round(volume, 15), tuple(np.round(up, 12)))
        hit = self._fills.get(key)
        if hit is not None:
            self._fills.move_to_end(key)
            return hit
        if volume <= 0.0:
            wet = FilledModalModel(self, self._body(liquid, 0.0, up, None), None, None)
        else:
            mesh = self.liquid_mesh(volume, up)
            Ma, S = liquid_loading(mesh.nodes_m, mesh.tets, mesh.free_surface, self.basis_shapes_at,
                                   liquid.density_kg_m3)
            wet = FilledModalModel(self, self._body(liquid, volume, up, mesh), Ma, S)
        self._fills[key] = wet
        while len(self._fills) > 16:
            self._fills.popitem(last=False)
        return wet

    def __repr__(self) -> str:
        return (f"Container<{self.name}: {self.volume_m3 * 1e6:.4g} ml cavity, {self.n_dry} dry modes + "
                f"{self.n_correction} correction vectors>")


def _truncated(model, n: int):
    """``model`` with only its first ``n`` modes (same mesh)."""
    from ..modal.model import ModalModel

    return ModalModel(model.nodes_m, model.elements, model.frequencies_hz[:n], model.mode_shapes[:, :, :n],
                      model.material, element=model.element, metadata=model.metadata)


def _cut(freqs: np.ndarray, limit_hz: float) -> int:
    """Modes to keep: all up to ``limit_hz`` plus the rest of a cluster at the cut."""
    n = int(np.searchsorted(freqs, limit_hz, side="right"))
    while 0 < n < len(freqs) and freqs[n] <= freqs[n - 1] * (1.0 + _CLUSTER_RTOL):
        n += 1
    return n


class FilledModalModel:
    """A container with liquid: a :class:`~sensors.ModalBasis` (what synthesis and the simulated
    sensor take), with the wall's geometry queries delegated to the dry model.

    Build with :func:`filled` or :meth:`Container.fill`. Mode shapes are the wall's
    displacement (the liquid has no nodes); the modal mass is 1 including the liquid's kinetic
    energy. ``liquid`` is the :class:`LiquidBody` (mass, centre of mass) a physics engine
    should carry.
    """

    #: A plain material rescaling (``sensors.MaterialView``) is not exact for a filled container:
    #: the liquid's added mass does not scale with the wall's density. ``with_material`` is.
    material_scales_modes = False

    def __init__(self, container: Container, liquid: LiquidBody, added_mass, slip, material=None):
        self.container = container
        self.dry = container.dry
        self.liquid = liquid
        self.material = get_material(material) if material is not None else self.dry.material
        freq_scale, self._shape_scale = material_scaling(self.dry.material, self.material)
        lam = container.basis_eigenvalues * freq_scale**2
        band = container.band_limit_hz * freq_scale
        if added_mass is None:
            # No liquid: exactly the dry modes (no eigen-solve whose round-off would rotate pairs).
            n = container.n_dry
            Q = np.zeros((container.n_basis, n))
            Q[6:6 + n] = np.eye(n)
            w2, self._Ma, self._S = lam[6:6 + n].copy(), None, None
        else:
            self._Ma = added_mass * self._shape_scale**2
            self._S = slip * self._shape_scale**2
            w2, Q = scipy.linalg.eigh(np.diag(lam), np.eye(len(lam)) + self._Ma)
            if np.any(np.abs(w2[:6]) > 1e-8 * lam.max()):
                raise ArithmeticError(f"the six rigid-body modes of the filled container are not at zero: {w2[:6]}")
            w2, Q = w2[6:], Q[:, 6:]
            n = _cut(np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi), band)
            w2, Q = w2[:n], Q[:, :n]
        #: w^2 [rad^2/s^2] of the wet modes.
        self.eigenvalues = np.asarray(w2, dtype=np.float64)
        #: (n_basis, r) wet modes on the container's basis (rigid, dry, correction).
        self.modal_coefficients = Q
        self.angular_frequencies_rad_s = np.sqrt(self.eigenvalues)
        self.frequencies_hz = self.angular_frequencies_rad_s / (2.0 * np.pi)
        self.added_damping_per_s = 2.0 * self.viscous_decay_rates_per_s()
        self.metadata = dict(self.dry.metadata, kind=f"{container.name} with {liquid.liquid.name}",
                             material=self.material.name, liquid=liquid.liquid.to_dict(),
                             liquid_volume_m3=liquid.volume_m3, fill_fraction=self.fill_fraction,
                             surface_normal=np.asarray(liquid.surface_normal).tolist(), max_frequency_hz=band)

    # ---------------------------------------------------------------- modal quantities

    @property
    def n_modes(self) -> int:
        """Number of wet elastic modes r."""
        return len(self.eigenvalues)

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
        ma = None if self._Ma is None else self._Ma / self._shape_scale**2
        s = None if self._S is None else self._S / self._shape_scale**2
        return FilledModalModel(self.container, self.liquid, ma, s, material)

    # ---------------------------------------------------------------- geometry (the wall's)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Wet mode shapes of the wall at points [m / sqrt(kg)], (n, 3, r)."""
        U = self.container.basis_shapes_at(points_m)
        return (U @ self.modal_coefficients) * self._shape_scale

    def surface_distance_m(self, points_m) -> np.ndarray:
        """Distance [m] to the container's surface (the dry model's)."""
        return self.dry.surface_distance_m(points_m)

    def surface_normal_at(self, points_m) -> np.ndarray:
        """Outward unit normal of the container's surface (the dry model's)."""
        return self.dry.surface_normal_at(points_m)

    def describe(self) -> str:
        band = band_text(self.frequencies_hz)
        return (f"{self.container.name} of {self.material.name} holding {self.liquid.volume_m3 * 1e6:.4g} ml of "
                f"{self.liquid.liquid.name} ({100 * self.fill_fraction:.0f}% full), {self.n_modes} wet modes {band}")

    def __repr__(self) -> str:
        return f"FilledModalModel<{self.describe()}>"


# -------------------------------------------------------------------- the entry point

_CONTAINERS: collections.OrderedDict = collections.OrderedDict()
_MAX_CONTAINERS = 8


def container(obj, *, cavity=None, **options) -> Container:
    """The (memoized) :class:`Container` of ``obj``.

    Args:
        obj: An everyday container's name (``"mug"``, ``"glass"``, ``"can"``, ``"bottle"``,
            ``"box"``), an :class:`~sensors.objects.everyday.EverydayObject`, a :class:`Container`
            (returned as is), or a dry :class:`~sensors.ModalModel` together with ``cavity``.
        cavity: For a bare modal model: its cavity (an ``AxisymmetricCavity``,
            ``SurfaceCavity``, or an object with ``inner_profile_m`` / ``cavity``).
        options: :class:`Container` options and the dry model's build options (see
            :meth:`Container.of`).
    """
    if isinstance(obj, Container):
        if options or cavity is not None:
            raise TypeError("a Container is already built: options and cavity do not apply")
        return obj
    if hasattr(obj, "mode_shapes_at") and not hasattr(obj, "tet_mesher"):  # a modal model
        if cavity is None:
            raise TypeError("a bare modal model does not know its cavity: pass cavity= (or the EverydayObject)")
        key = ("model", id(obj), id(cavity), json.dumps(options, sort_keys=True, default=repr))
        make = lambda: Container(obj, cavity, **options)  # noqa: E731
        keep = (obj, cavity)
    else:
        if isinstance(obj, str):
            from ..objects.everyday import everyday_object  # trimesh-heavy: only when asked by name

            obj = everyday_object(obj)
        if cavity is not None:
            raise TypeError("an everyday object brings its cavity: do not pass cavity=")
        key = ("object", json.dumps(obj.to_dict(), sort_keys=True, default=repr),
               json.dumps(options, sort_keys=True, default=repr))
        make = lambda: Container.of(obj, **dict(options))  # noqa: E731
        keep = (obj,)
    hit = _CONTAINERS.get(key)
    if hit is not None:
        _CONTAINERS.move_to_end(key)
        return hit[0]
    c = make()
    _CONTAINERS[key] = (c, keep)
    while len(_CONTAINERS) > _MAX_CONTAINERS:
        _CONTAINERS.popitem(last=False)
    return c


def filled(obj, fill_fraction: float | None = None, *, liquid="water", surface_normal=None,
           fill_height_m: float | None = None, volume_m3: float | None = None, cavity=None,
           **options) -> FilledModalModel:
    """A container holding a liquid, as a :class:`~sensors.ModalBasis`.

    Args:
        obj: The container: an everyday name (``"mug"``, ``"glass"``, ``"can"``, ``"bottle"``),
            an :class:`~sensors.objects.everyday.EverydayObject`, a :class:`Container`, or a dry
            :class:`~sensors.ModalModel` with ``cavity=``. Containers are memoized and their
            dry modes and static correction disk-cached, so a new fill costs a small fraction
            of the first.
        fill_fraction: Liquid volume as a fraction of the cavity (0 = empty: exactly the dry
            modes; 1 = full to the rim). Or give ``fill_height_m`` (upright height above the
            inner floor) or ``volume_m3`` instead.
        liquid: ``"water"``, ``"oil"``, ``"honey"``, ``"ethanol"``, a
            :class:`~sensors.materials.liquids.Liquid`, or a density [kg/m^3] (an inviscid liquid).
        surface_normal: Unit normal of the free surface against gravity, in the object frame:
            the world's up direction seen from the object, ``R.T @ (0, 0, 1)`` for the object's
            world rotation R. Default: standing upright (the container's up axis, +x for the
            everyday containers).
        options: :class:`Container` and dry-model build options (:func:`container`).

    Returns:
        :class:`FilledModalModel`: wet modes up to the dry model's band limit; ``.liquid`` is the
        :class:`LiquidBody` (mass [kg], centre of mass [m] in the object frame, inertia).

    Raises:
        sensors.fluid.cavity.LiquidSpillError: the liquid does not fit below the rim at this tilt
            (``container(obj).max_fill_fraction(surface_normal)`` is the most that does).
        sensors.MeshError: the tilted surface uncovers part of the floor (a revolved cavity's
            structured liquid mesh cannot represent it).
    """
    return container(obj, cavity=cavity, **options).fill(
        liquid, fill_fraction=fill_fraction, fill_height_m=fill_height_m, volume_m3=volume_m3,
        surface_normal=surface_normal)
