"""The entry point: a container holding a liquid, as a modal basis synthesis takes as is::

    wet = sensors.fluid.filled("mug", fill_fraction=0.5, liquid="water")
    wet.frequencies_hz, wet.mode_shapes_at(points_m)     # a ModalBasis
    wet.liquid.mass_kg, wet.liquid.centre_of_mass_m      # what MuJoCo should carry

``compressible=True`` (the default) couples the liquid's own acoustic modes to the wall;
``compressible=False`` is the incompressible added-mass model. Containers (dry model and
static correction) and their fills (per liquid, volume, tilt and model) are memoized in this
process (``CACHE_SIZES["fluid.containers"]`` and ``["fluid.fills"]``); the physics is described in
:mod:`sensors.fluid.filled_model`.
"""

from __future__ import annotations

import functools
import json

import numpy as np

from .._infra.checks import holds_bool
from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from .acoustic import LIQUID_MODES_BAND_FACTOR, acoustic_loading, check_liquid_mode_count
from .added_mass import unit_potential_flow, wall_coupling
from .cavity import AxisymmetricCavity, cavity_of, unit
from .container import CONTAINER_OPTIONS, Container, check_container_options, liquid_volume_in, solid_of
from .fill_table import fill_table
from .filled_model import FilledModalModel
from .liquid_body import LiquidBody
from ..materials.liquids import get_liquid
from ..modal.build import DEFAULT_MAX_FREQUENCY_HZ

__all__ = ["container", "filled"]

#: The containers of this process, by object (or model and cavity) and options.
CONTAINERS = LRU(CACHE_SIZES["fluid.containers"])
#: Whether an exact fill (``filled(..., interpolated=False)``, or a height a fill table leaves to
#: the exact solve: the bottle's neck and shoulder, 7 % of FillLevel-v0's fills and then 0.3-0.6 s
#: each) solves the liquid's loading when the model's modes are first read (True: a fill whose
#: modes are never heard, FillLevel-v0 with sensing off or a rest-grid fill, needs only the
#: liquid's body from its mesh) or at once (False, the reference).  The same numbers, later
#: (``tests/test_lazy_fill.py``).  Read at each call.
LAZY_EXACT_MATRICES = True
#: The potential flow (:class:`~sensors.fluid.added_mass.LiquidFlow`) of the latest exact fill's
#: liquid mesh, by container, volume and free-surface normal: another liquid or the other liquid
#: model in the same fill reuses the Laplace solve (its factorization, added mass per unit
#: density, slip), most of an incompressible fill's cost.  The same function of the same mesh:
#: the same bits (``tests/test_lazy_fill.py``).
LIQUID_FLOWS = LRU(CACHE_SIZES["fluid.liquid_flows"])


def container(obj, *, cavity=None, **options) -> Container:
    """The (memoized) :class:`Container` of ``obj``.

    Args:
        obj: A catalog container (a name such as ``"mug"``, ``"glass"``, ``"steel_can"``,
            ``"bottle"``, ``"box"``, or its :class:`~sensors.objects.catalog.ObjectSpec`), an
            :class:`~sensors.objects.everyday.EverydayObject`, a :class:`Container` (returned as
            is), or a dry :class:`~sensors.ModalModel` together with ``cavity``.
        cavity: For a bare modal model: its cavity (an ``AxisymmetricCavity``,
            ``SurfaceCavity``, or an object with ``inner_profile_m`` / ``cavity``).
        options: :class:`Container` options and the dry model's build options (see
            :meth:`Container.of`).
    """
    if isinstance(obj, Container):
        if options or cavity is not None:
            raise TypeError("a Container is already built: options and cavity do not apply")
        return obj
    key, make, keep = _container_key(obj, cavity, options)
    # ``keep`` holds the objects whose id() is in the key alive as long as the entry.
    return CONTAINERS.get_or_build(key, lambda: (make(), keep))[0]


def _container_key(obj, cavity, options):
    """(memo key, build, objects to keep alive) of the container of ``obj`` (not a Container)."""
    if hasattr(obj, "mode_shapes_at") and not hasattr(obj, "tet_mesher"):  # a modal model
        if cavity is None:
            raise TypeError("a bare modal model does not know its cavity: pass cavity= (or the EverydayObject)")
        key = ("model", id(obj), id(cavity), json.dumps(options, sort_keys=True, default=repr))
        make = lambda: Container(obj, cavity, **options)  # noqa: E731
        keep = (obj, cavity)
    else:
        obj = solid_of(obj)
        if cavity is not None:
            raise TypeError("an everyday object brings its cavity: do not pass cavity=")
        key = ("object", json.dumps(obj.to_dict(), sort_keys=True, default=repr),
               json.dumps(options, sort_keys=True, default=repr))
        make = lambda: Container.of(obj, **dict(options))  # noqa: E731
        keep = (obj,)
    return key, make, keep


def _built_container(obj, cavity, options) -> Container | None:
    """The container of ``obj`` if this process has built it (None otherwise, or for bad arguments:
    :func:`container` raises for those)."""
    if isinstance(obj, Container):
        return None
    try:
        key = _container_key(obj, cavity, options)[0]
    except (TypeError, ValueError):
        return None
    hit = CONTAINERS.get(key)
    return None if hit is None else hit[0]


def filled(obj, fill_fraction: float | None = None, *, liquid="water", surface_normal=None,
           fill_height_m: float | None = None, volume_m3: float | None = None, cavity=None,
           compressible: bool = True, interpolated: bool = False, **options) -> FilledModalModel:
    """A container holding a liquid, as a :class:`~sensors.ModalBasis`.

    Args:
        obj: The container: a catalog name (``"mug"``, ``"glass"``, ``"steel_can"``, ``"bottle"``)
            or :class:`~sensors.objects.catalog.ObjectSpec`, an
            :class:`~sensors.objects.everyday.EverydayObject`, a :class:`Container`, or a dry
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
        compressible: True (default): the liquid compresses with its speed of sound, and its
            own acoustic modes (up to twice the band limit) couple to the wall; False: the
            incompressible potential-flow added mass alone (the model before 2026-11-26).
        interpolated: True: an upright fill of an axisymmetric container comes from the
            container's fill table (:mod:`sensors.fluid.fill_table`: milliseconds, within
            ``GRID_RTOL`` of the exact wet frequencies as measured between its grid heights; the
            first fill of a container and liquid builds the table, about 25 s, or loads it from
            the disk cache). Tilted fills, surface cavities and films thinner than the table's
            first height (0.01 % of the liquid's element height: about a micrometre) take the
            exact solve. False (default): the exact solve of this fill.
        options: :class:`Container` and dry-model build options (:func:`container`).

    Returns:
        :class:`FilledModalModel`: wet modes up to the dry model's band limit; ``.liquid`` is the
        :class:`LiquidBody` (mass [kg], centre of mass [m] in the object frame, inertia).

    Raises:
        sensors.fluid.cavity.LiquidSpillError: the liquid does not fit below the rim at this tilt
            (``container(obj).max_fill_fraction(surface_normal)`` is the most that does).
        sensors.MeshError: the tilted surface uncovers part of the floor (a revolved cavity's
            structured liquid mesh cannot represent it).
        sensors.mesh.surface.MeshTooLargeError: the liquid mesh would exceed ``liquid_max_nodes``
            (default :data:`sensors.fluid.cavity.MAX_LIQUID_NODES`).
        ValueError: a compressible liquid whose acoustic modes up to twice the band would number
            above :data:`sensors.fluid.acoustic.MAX_LIQUID_MODES` by Weyl's law (a speed of sound
            far below any liquid's).
        TypeError, ValueError: a bad fill, option or object; all of these are raised before the
            container is built.
    """
    liquid = get_liquid(liquid)
    for flag, value in (("compressible", compressible), ("interpolated", interpolated)):
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{flag} must be True or False, got {value!r}")
    compressible = bool(compressible)
    # Every input checked before the container is built (minutes with an empty cache); against
    # its cavity when it is built already (a new fill of a known container).
    built = _built_container(obj, cavity, options)
    volume = _checked_fill(obj if built is None else built, cavity if built is None else None,
                           options if built is None else {}, fill_fraction=fill_fraction,
                           fill_height_m=fill_height_m, volume_m3=volume_m3, surface_normal=surface_normal)
    if compressible and volume > 0.0:
        band = _band_limit_hz(obj if built is None else built, options)
        if band is not None:
            check_liquid_mode_count(volume, liquid.speed_of_sound_m_per_s, LIQUID_MODES_BAND_FACTOR * band)
    c = container(obj, cavity=cavity, **options) if built is None else built
    up = c.surface_normal(surface_normal)

    def wet() -> FilledModalModel:
        if volume <= 0.0:
            return FilledModalModel(c, LiquidBody.in_cavity(c.cavity, liquid, 0.0, up, None), None, None,
                                    compressible=compressible)
        mesh = c.liquid_mesh(volume, up)
        body = LiquidBody.in_cavity(c.cavity, liquid, volume, up, mesh)
        loading = functools.partial(_loading, c, mesh, liquid, compressible)   # picklable, unlike a closure
        if LAZY_EXACT_MATRICES:
            return FilledModalModel.pending(c, body, compressible, loading)
        Ma, S, B, wl2 = loading()
        return FilledModalModel(c, body, Ma, S, liquid_coupling=B, liquid_eigenvalues=wl2, compressible=compressible)

    key = (liquid, round(volume, 15), tuple(np.round(up, 12)), compressible)
    if interpolated and volume > 0.0 and isinstance(c.cavity, AxisymmetricCavity) \
            and float(up @ c.cavity.axis) >= 1.0 - 1e-12:
        table = fill_table(c, liquid)
        if table.covers(c.cavity.height_below_m(volume)):
            return c.fills.get_or_build(key + ("interpolated",),
                                        lambda: table.filled(c, liquid, volume, compressible=compressible))
    return c.fills.get_or_build(key, wet)


def _loading(c, mesh, liquid, compressible: bool) -> tuple:
    """``(added_mass, slip, liquid_coupling, liquid_eigenvalues)`` of the liquid mesh ``mesh`` in
    container ``c`` (the last two None for an incompressible liquid)."""
    key = (IdentityKey(c), float(mesh.volume_m3), np.asarray(mesh.up, float).tobytes())
    flow = LIQUID_FLOWS.get_or_build(
        key, lambda: unit_potential_flow(wall_coupling(mesh.nodes_m, mesh.tets, mesh.free_surface, c.basis_shapes_at)))
    if not compressible:
        return flow.added_mass(liquid.density_kg_m3), flow.slip, None, None
    return acoustic_loading(mesh.nodes_m, mesh.tets, mesh.free_surface, c.basis_shapes_at,
                            liquid.density_kg_m3, liquid.speed_of_sound_m_per_s,
                            LIQUID_MODES_BAND_FACTOR * c.band_limit_hz, flow=flow)


def _checked_fill(obj, cavity, options, *, surface_normal, **amount):
    """The liquid volume [m^3] of a fill, checked with its free-surface normal against the cavity
    (range, spill, wet floor, liquid-mesh size) without building the container's modes."""
    mine = check_container_options(**{k: options[k] for k in CONTAINER_OPTIONS if k in options})
    if isinstance(obj, Container):
        cav, up_axis = obj.cavity, obj.up_axis
        mine = dict(liquid_n_theta=obj.liquid_n_theta, liquid_element_size_m=obj.liquid_element_size_m,
                    liquid_max_nodes=obj.liquid_max_nodes)
    elif hasattr(obj, "mode_shapes_at") and not hasattr(obj, "tet_mesher"):  # a bare model: container() refuses
        if cavity is None:
            raise TypeError("a bare modal model does not know its cavity: pass cavity= (or the EverydayObject)")
        cav = cavity_of(cavity)
        up_axis = cav.upright_up if isinstance(cav, AxisymmetricCavity) else (0.0, 0.0, 1.0)
    else:
        if cavity is not None:
            raise TypeError("an everyday object brings its cavity: do not pass cavity=")
        solid = solid_of(obj)
        cav, up_axis = cavity_of(solid), solid.up_axis
    volume = liquid_volume_in(cav, **amount)
    up = unit(up_axis if surface_normal is None else _checked_normal(surface_normal))
    if volume > 0.0:
        cav.check_liquid_mesh_size(mine["liquid_n_theta"], mine["liquid_element_size_m"], mine["liquid_max_nodes"])
        if isinstance(cav, AxisymmetricCavity):
            # The liquid mesh's own checks (spill, dry floor), run now: no build.
            cav.check_fill(volume, up, mine["liquid_n_theta"])
    return volume


def _band_limit_hz(obj, options) -> float | None:
    """The wet model's band limit [Hz] before the container is built (None: not known yet; the
    liquid's own solve checks its mode count then)."""
    if isinstance(obj, Container):
        return obj.band_limit_hz
    band = options.get("max_dry_frequency_hz")
    if band is None and hasattr(obj, "mode_shapes_at") and not hasattr(obj, "tet_mesher"):  # a bare model
        band = obj.metadata.get("max_frequency_hz") if hasattr(obj, "metadata") else None
    elif band is None:
        band = options.get("max_frequency_hz", DEFAULT_MAX_FREQUENCY_HZ)
    try:
        return float(band) if band is not None and float(band) > 0 else None
    except (TypeError, ValueError):  # a bad option: the dry model's build refuses it
        return None


def _checked_normal(surface_normal) -> np.ndarray:
    """A finite, non-zero 3-vector of numbers (booleans refused)."""
    v = np.asarray(surface_normal)
    if v.dtype.kind not in "iuf" or v.shape != (3,) or holds_bool(surface_normal):
        raise TypeError(f"surface_normal must be 3 numbers, got {surface_normal!r}")
    v = v.astype(float)
    if not np.all(np.isfinite(v)) or not np.linalg.norm(v) > 0:
        raise ValueError(f"surface_normal must be a finite non-zero vector, got {surface_normal!r}")
    return v
