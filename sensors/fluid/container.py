"""A container: its dry modal model, its cavity, and the per-container work every fill reuses
(rigid-body modes, the static correction of the dry basis, the basis at any point).

How much liquid a fill holds (fraction, height or volume, at any tilt) is asked here too; the
wet model itself is :func:`sensors.fluid.filled`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .._infra import cache as cache_mod
from .._infra.checks import real_number, whole_number
from .._infra.lru import CACHE_SIZES, LRU
from . import added_mass
from .added_mass import static_correction
from .cavity import MAX_LIQUID_NODES, AxisymmetricCavity, LiquidMesh, cavity_of, unit
from .liquid_body import LiquidBody
from ..fem.assembly import QUADRATURE, shape_functions, shape_gradients_ref
from ..materials.liquids import get_liquid
from ..modal.basis import check_points_m

__all__ = ["Container", "CONTAINER_OPTIONS", "check_container_options", "liquid_volume_in"]

#: Options of :class:`Container` (the rest of ``filled``'s keyword arguments build the dry model).
CONTAINER_OPTIONS = ("correction_degree", "liquid_n_theta", "liquid_element_size_m", "max_dry_frequency_hz",
                     "liquid_max_nodes")


def check_container_options(correction_degree=4, liquid_n_theta=16, liquid_element_size_m=None,
                            max_dry_frequency_hz=None, liquid_max_nodes=MAX_LIQUID_NODES) -> dict:
    """The :class:`Container` options checked (TypeError/ValueError naming the option), before any build."""
    return dict(
        correction_degree=0 if correction_degree is None else whole_number(correction_degree, "correction_degree",
                                                                            minimum=0, maximum=12),
        liquid_n_theta=_multiple_of_8(whole_number(liquid_n_theta, "liquid_n_theta", minimum=8, maximum=1024)),
        liquid_element_size_m=None if liquid_element_size_m is None else real_number(
            liquid_element_size_m, "liquid_element_size_m", above=0.0),
        max_dry_frequency_hz=None if max_dry_frequency_hz is None else real_number(
            max_dry_frequency_hz, "max_dry_frequency_hz", above=0.0),
        liquid_max_nodes=None if liquid_max_nodes is None else whole_number(liquid_max_nodes, "liquid_max_nodes",
                                                                            minimum=1))


def _multiple_of_8(n: int) -> int:
    if n % 8:
        raise ValueError(f"liquid_n_theta must be a multiple of 8, got {n}")
    return n


def liquid_volume_in(cavity, *, fill_fraction=None, fill_height_m=None, volume_m3=None) -> float:
    """Liquid volume [m^3] in ``cavity`` from exactly one of a fill fraction (of the cavity), an
    upright height above the inner floor [m] (axisymmetric cavities) or a volume [m^3]."""
    given = [v is not None for v in (fill_fraction, fill_height_m, volume_m3)]
    if sum(given) != 1:
        raise TypeError("give exactly one of fill_fraction, fill_height_m, volume_m3")
    total = cavity.volume_m3
    if fill_fraction is not None:
        return real_number(fill_fraction, "fill_fraction", minimum=0.0, maximum=1.0) * total
    if fill_height_m is not None:
        if not isinstance(cavity, AxisymmetricCavity):
            raise TypeError("fill_height_m needs an axisymmetric cavity; give fill_fraction or volume_m3")
        height = real_number(fill_height_m, "fill_height_m [m]", minimum=0.0, maximum=cavity.depth_m * (1 + 1e-12))
        return cavity.volume_below_m3(height)
    return real_number(volume_m3, "volume_m3", minimum=0.0, maximum=total * (1 + 1e-12))


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
    """A container's dry modal model and its cavity, with the per-container work every fill reuses.

    Per container (once; the static correction is cached on disk next to the modal models):
    the rigid-body modes and the static-correction vectors. Per fill: the liquid's mesh, one
    Laplace solve for all basis vectors and a small dense eigenproblem (:func:`sensors.fluid.filled`).

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
        liquid_max_nodes: Refuse, before meshing, a revolved cavity's liquid mesh above this many
            P2 nodes (default :data:`~sensors.fluid.cavity.MAX_LIQUID_NODES`; None: no limit).
        cache, cache_dir: The disk cache of the static correction (as the modal models').
    """

    def __init__(self, dry, cavity, *, up_axis=None, correction_degree: int | None = 4, liquid_n_theta: int = 16,
                 liquid_element_size_m: float | None = None, max_dry_frequency_hz: float | None = None,
                 liquid_max_nodes: int | None = MAX_LIQUID_NODES, cache: bool = True, cache_dir=None,
                 name: str | None = None):
        if not all(hasattr(dry, a) for a in ("nodes_m", "elements", "mode_shapes", "locator")):
            raise TypeError(f"a Container needs a sensors.ModalModel with its mesh, got {type(dry).__name__} "
                            "(for another material, fill the container and use the filled model's with_material)")
        checked = check_container_options(correction_degree, liquid_n_theta, liquid_element_size_m,
                                          max_dry_frequency_hz, liquid_max_nodes)
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
        self.liquid_n_theta = checked["liquid_n_theta"]
        self.liquid_element_size_m = checked["liquid_element_size_m"]
        self.liquid_max_nodes = checked["liquid_max_nodes"]
        self._mass_kg, self._centre_m, self._rot = _rigid_body_data(dry)
        self.correction_degree = checked["correction_degree"]
        #: The disk cache of the static correction and the fill tables (``cache=False``: none).
        self.cache, self.cache_dir = bool(cache), cache_dir
        if self.correction_degree > 0:
            lam_c, shapes_c = self._correction(cache, cache_dir)
        else:
            lam_c, shapes_c = np.zeros(0), np.zeros((len(dry.nodes_m), 3, 0))
        self.n_correction = len(lam_c)
        #: (6 + n_dry + n_correction,) eigenvalues [rad^2/s^2] of the basis: rigid, dry, correction.
        self.basis_eigenvalues = np.concatenate([np.zeros(6), np.asarray(dry.eigenvalues)[: self.n_dry], lam_c])
        self._nodal = np.ascontiguousarray(np.concatenate([dry.mode_shapes[:, :, : self.n_dry], shapes_c], axis=2))
        #: The wet models of this container by (liquid, volume, free-surface normal) (:func:`sensors.fluid.filled`).
        self.fills = LRU(CACHE_SIZES["fluid.fills"])
        #: Its fill tables by liquid (density, speed of sound) (:func:`sensors.fluid.fill_table.fill_table`).
        self.fill_tables = LRU(CACHE_SIZES["fluid.fill_tables"])

    # ---------------------------------------------------------------- construction helpers

    @classmethod
    def of(cls, obj, dry=None, **options) -> "Container":
        """The container of an :class:`~sensors.objects.everyday.EverydayObject` (or of a
        catalog object or name: ``"mug"``, ``get_object("steel_can")``).

        Args:
            dry: Its dry modal model if already built (default ``obj.modal_model(...)``, cached).
            options: :class:`Container` options (``correction_degree``, ...) and options of
                ``obj.modal_model`` (``resolution``, ``max_frequency_hz``, ``cache_dir``,
                ``progress``, ...).
        """
        obj = solid_of(obj)
        mine = {k: options.pop(k) for k in list(options) if k in CONTAINER_OPTIONS}
        check_container_options(**mine)
        cavity = cavity_of(obj)  # refuses a solid without a cavity before its modes are built
        caching = {k: options[k] for k in ("cache", "cache_dir") if k in options}
        if dry is None:
            dry = obj.modal_model(**options)
        elif set(options) - set(caching):
            raise TypeError(f"dry model given: build options {sorted(set(options) - set(caching))} do not apply")
        return cls(dry, cavity, up_axis=obj.up_axis, name=obj.name, **caching, **mine)

    def _wetted_faces(self):
        tol = 5e-3 * self.cavity.size_m

        def select(corners, points):
            d = self.cavity.wall_distance_m(points.reshape(-1, 3)).reshape(points.shape[:2])
            return np.all(d <= tol, axis=1)

        return select

    def _key_parts(self) -> list:
        """What the container's basis depends on (dry model, cavity, correction degree)."""
        dry = self.dry
        ident = dry.metadata.get("cache_key") or cache_mod.content_key(dry.nodes_m, dry.elements, dry.frequencies_hz)
        cav = self.cavity
        cav_id = ([cav.axial_m, cav.radius_m, cav.origin_m, cav.axis] if isinstance(cav, AxisymmetricCavity)
                  else [np.asarray(cav.mesh.vertices), np.asarray(cav.mesh.faces)])
        parts = [ident, dry.material.to_dict(), self.n_dry, type(cav).__name__, cav_id, self.correction_degree,
                 cache_mod.source_version("sensors.fluid.added_mass", "sensors.fluid.cavity",
                                          "sensors.fem.assembly", "sensors.fem.eigen")]
        solver = added_mass.static_correction_solver()
        if solver is not None:  # not the reference's correction: its own entries
            parts.append(solver)
        return parts

    @functools.cached_property
    def cache_key(self) -> str:
        """Content key of the container's basis (what a fill's work is keyed by on disk)."""
        return cache_mod.content_key("fluid container", *self._key_parts())

    def _correction(self, cache, cache_dir):
        dry = self.dry
        key = cache_mod.content_key("fluid static correction", *self._key_parts())

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
        p = check_points_m(points_m)
        rigid = self.rigid_shapes_at(p)
        tet, bary = self.dry.locator.locate(p)
        N = shape_functions(bary, self.dry.element)
        nodal = self._nodal[self.dry.elements[tet]]  # (n, n_el, 3, k)
        elastic = np.matmul(N[:, None, :], nodal.reshape(len(p), N.shape[1], -1)).reshape(len(p), 3, -1)
        return np.concatenate([rigid, elastic], axis=2)

    def rigid_shapes_at(self, points_m) -> np.ndarray:
        """(n, 3, 6) the basis's first six columns at points [m / sqrt(kg)]: 3 translations and 3
        rotations about the centre of mass, mass-normalized on the dry container."""
        p = check_points_m(points_m)
        r = p - self._centre_m
        cross = np.zeros((len(p), 3, 3))  # [r]_x
        cross[:, 0, 1], cross[:, 0, 2] = -r[:, 2], r[:, 1]
        cross[:, 1, 0], cross[:, 1, 2] = r[:, 2], -r[:, 0]
        cross[:, 2, 0], cross[:, 2, 1] = -r[:, 1], r[:, 0]
        trans = np.broadcast_to(np.eye(3) / math.sqrt(self._mass_kg), (len(p), 3, 3))
        rot = -cross @ self._rot  # (a x r) for rotation vectors a = columns of J^-1/2
        return np.concatenate([trans, rot], axis=2)

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
        return liquid_volume_in(self.cavity, fill_fraction=fill_fraction, fill_height_m=fill_height_m,
                                volume_m3=volume_m3)

    def liquid_mesh(self, volume_m3: float, surface_normal=None) -> LiquidMesh:
        """The liquid's P2 mesh (raises :class:`~sensors.fluid.cavity.LiquidSpillError` if it spills,
        :class:`~sensors.MeshError` if the tilted surface uncovers part of the floor)."""
        return self.cavity.liquid_mesh(volume_m3, self.surface_normal(surface_normal), n_theta=self.liquid_n_theta,
                                       element_size_m=self.liquid_element_size_m, max_nodes=self.liquid_max_nodes)

    def liquid_body(self, liquid="water", *, fill_fraction=None, fill_height_m=None, volume_m3=None,
                    surface_normal=None) -> LiquidBody:
        """The liquid's mass, centre of mass and inertia (object frame) without the modal work."""
        liquid = get_liquid(liquid)
        volume = self.liquid_volume_m3(fill_fraction=fill_fraction, fill_height_m=fill_height_m, volume_m3=volume_m3)
        up = self.surface_normal(surface_normal)
        mesh = self.liquid_mesh(volume, up) if volume > 0 else None
        return LiquidBody.in_cavity(self.cavity, liquid, volume, up, mesh)

    def __repr__(self) -> str:
        return (f"Container<{self.name}: {self.volume_m3 * 1e6:.4g} ml cavity, {self.n_dry} dry modes + "
                f"{self.n_correction} correction vectors>")


def _truncated(model, n: int):
    """``model`` with only its first ``n`` modes (same mesh)."""
    from ..modal.model import ModalModel

    return ModalModel(model.nodes_m, model.elements, model.frequencies_hz[:n], model.mode_shapes[:, :, :n],
                      model.material, element=model.element, metadata=model.metadata)


def solid_of(obj):
    """The solid (:class:`~sensors.objects.everyday.EverydayObject`) of a catalog name or
    :class:`~sensors.objects.catalog.ObjectSpec`; anything else is returned as is."""
    from ..objects.catalog import ObjectSpec, get_object  # trimesh-heavy: only when asked by name

    if not isinstance(obj, (str, ObjectSpec)):
        return obj
    spec = get_object(obj)
    if spec.is_prism:
        raise TypeError(f"a {spec.label} is not a container: it has no cavity to fill")
    return spec.solid()
