"""Where the hand can hold an object: its rest pose on the table, its antipodal grasps (any
surface object) and the span of grasp positions along its main axis (any object).

* Rest pose: the object's ``up_axis`` (``+x`` for the containers, ``+z`` for a user's mesh,
  which rests as it was modelled) points up; the body frame stays the modal model's frame.
* Grasps: antipodal pairs (:mod:`aas_gym.antipodal`) the hand reaches from above, cached on
  disk and in this process (``CACHE_SIZES["sim.grasp_sets"]``), and a path along the object's
  main axis on which grasp positions are measured. A prism is grasped across its main axis.

No MuJoCo here: the objects are catalog entries (:class:`sensors.objects.ObjectSpec`).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from aas_gym.antipodal import AntipodalGrasp, grasp_path, sample_antipodal_grasps
from sensors._infra import cache as cache_mod
from sensors._infra.lru import CACHE_SIZES, LRU
from sensors.mesh.tets import MeshError
from sensors.objects.catalog import ObjectSpec

__all__ = ["END_MARGIN_M", "FINGER_REACH_M", "ObjectGrasp", "GraspSet", "grasp_set", "grasp_span_m",
           "rest_rotation", "rest_height_m"]

#: Fingertip pads (20 mm wide) stay this far from a prism's ends.
END_MARGIN_M = 0.02
#: Contacts lie at most this far below the object's top: the hand body sits 45 mm above the
#: pads' centre, so deeper grasps would push it into the object.
FINGER_REACH_M = 0.035
#: Pads (16 mm tall) stay off the table: contacts at least this far above the object's bottom.
MIN_CONTACT_HEIGHT_M = 0.002
#: Grasps kept per object (best friction-cone margin first) and the sampler's seed.
N_GRASPS = 200
GRASP_SEED = 0
#: Part of the grasp cache key: raise it when the sampler's rules change.
_SAMPLER_VERSION = 3
#: Whether ``GraspSet.nearest`` compares the grasps' widths as one array kept with the set
#: (``widths_m``) instead of a list built per call (~100 us for 200 grasps, twice a FillLevel-v0
#: reset): the same comparisons, the same mask.  False: the list (the reference;
#: ``tests/test_episode_glue.py``).  Read at each call.
WIDTH_ARRAY = True
#: Whether :func:`rest_rotation` keeps its result by the object's up and main axes (the only
#: inputs, the catalog's tuples; ~75 us a call, ``np.cross`` most of it, once a FillLevel-v0 reset).  False: computed
#: each call (the reference; ``tests/test_episode_glue.py``).  Read at each call.
REST_ROTATION_CACHE = True
_REST_ROTATIONS: LRU = LRU(CACHE_SIZES["sim.rest_rotations"])


@dataclasses.dataclass(frozen=True)
class ObjectGrasp:
    """A two-finger grasp in the object frame: contact midpoint, closing axis (unit), the
    distance between the contacts [m] (None: from the collision geometry, prisms), and its
    position along the object's grasp path [m]."""

    centre_m: np.ndarray
    axis: np.ndarray
    width_m: float | None
    position_m: float


def rest_rotation(solid) -> np.ndarray:
    """Rotation (3, 3) from the object frame to the world, before the placement's yaw: the
    object's ``up_axis`` to world +z and its main axis (or, parallel to up, object +z) to +x."""
    if not REST_ROTATION_CACHE or isinstance(solid.up_axis, np.ndarray):   # (an array is normalized in place)
        return _rest_rotation(solid.up_axis, solid.main_axis)
    up, main = np.asarray(solid.up_axis, float), np.asarray(solid.main_axis, float)
    key = (up.shape, up.tobytes(), main.shape, main.tobytes())
    return _REST_ROTATIONS.get_or_build(key, lambda: _rest_rotation(up, main)).copy()


def _rest_rotation(up_axis, main_axis) -> np.ndarray:
    up = np.asarray(up_axis, float)
    up /= np.linalg.norm(up)
    a = np.asarray(main_axis, float)
    if abs(a @ up) > 0.99:
        a = np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    a = a - (a @ up) * up
    a /= np.linalg.norm(a)
    return np.stack([a, np.cross(up, a), up])


def rest_height_m(solid) -> float:
    """Height of the body origin above the table when the object rests in :func:`rest_rotation`."""
    return float(-(np.asarray(solid.surface.vertices) @ rest_rotation(solid)[2]).min())


@dataclasses.dataclass(frozen=True)
class GraspSet:
    """The grasps of one object (object frame) and the positions [m] along its grasp path."""

    grasps: tuple
    positions_m: np.ndarray
    path_start_m: np.ndarray
    path_direction: np.ndarray

    @property
    def span_m(self) -> tuple[float, float]:
        return float(self.positions_m.min()), float(self.positions_m.max())

    @functools.cached_property
    def widths_m(self) -> np.ndarray:
        """The grasps' widths [m] (float64, read-only)."""
        w = np.array([g.width_m for g in self.grasps], dtype=np.float64)
        w.flags.writeable = False
        return w

    def nearest(self, position_m: float, avoid_m=(), clearance_m: float = 0.0,
                min_width_m: float = 0.0) -> ObjectGrasp:
        """The grasp whose position is closest to ``position_m``, among those at least
        ``min_width_m`` wide whose contacts stay ``clearance_m`` from every point of
        ``avoid_m`` (object frame)."""
        if WIDTH_ARRAY:
            ok = self.widths_m >= min_width_m
        else:
            ok = np.array([g.width_m >= min_width_m for g in self.grasps], bool)
        for point in avoid_m:
            for g_i, g in enumerate(self.grasps):
                if ok[g_i] and min(np.linalg.norm(c - point) for c in g.contacts_m) < clearance_m:
                    ok[g_i] = False
        if not ok.any():
            raise ValueError(f"no grasp of this object is {min_width_m * 1e3:.0f} mm wide or more and stays clear of "
                             "the other objects' contacts")
        idx = np.flatnonzero(ok)
        i = int(idx[np.argmin(np.abs(self.positions_m[idx] - position_m))])
        g = self.grasps[i]
        return ObjectGrasp(g.centre_m, g.axis, g.width_m, float(self.positions_m[i]))


#: Grasp sets by object in this process.
_GRASP_SETS = LRU(CACHE_SIZES["sim.grasp_sets"])


def grasp_set(obj: ObjectSpec) -> GraspSet:
    """Antipodal grasps of a surface object, reachable by the hand with the object at rest;
    cached on disk (content key of the surface and the sampler's settings) and in this
    process. Raises ``MeshError`` if the hand cannot hold it anywhere."""
    return _GRASP_SETS.get_or_build((obj.shape, obj.material, obj.mesh_id, obj.name), lambda: _sample(obj))


def _sample(obj: ObjectSpec) -> GraspSet:
    solid = obj.solid()
    surface = solid.surface
    up = rest_rotation(solid)[2]
    settings = dict(n_grasps=N_GRASPS, up=up.tolist(), max_depth_m=FINGER_REACH_M,
                    min_height_m=MIN_CONTACT_HEIGHT_M, seed=GRASP_SEED, sampler=_SAMPLER_VERSION)
    key = cache_mod.content_key("antipodal", np.asarray(surface.vertices, float),
                                np.asarray(surface.faces, np.int64), settings)
    hit = cache_mod.load_arrays(key)
    if hit is not None:
        grasps = [AntipodalGrasp(c, a, float(w), float(q)) for c, a, w, q in
                  zip(hit["centre_m"], hit["axis"], hit["width_m"], hit["quality"])]
    else:
        grasps = sample_antipodal_grasps(surface, np.random.default_rng(GRASP_SEED), n_grasps=N_GRASPS, up=up,
                                         max_depth_m=FINGER_REACH_M, min_height_m=MIN_CONTACT_HEIGHT_M)
        if not grasps:
            raise MeshError(f"the {solid.name} has no antipodal grasp the hand reaches from above (80 mm opening, "
                            f"contacts within {FINGER_REACH_M * 1e3:.0f} mm of its top): scale it or rest it on "
                            "another side")
        cache_mod.save_arrays(key, {"centre_m": np.array([g.centre_m for g in grasps]),
                                    "axis": np.array([g.axis for g in grasps]),
                                    "width_m": np.array([g.width_m for g in grasps]),
                                    "quality": np.array([g.quality for g in grasps])})
    path = grasp_path(surface, grasps, axis=solid.main_axis)
    positions = np.array([path.position_of(g.centre_m) for g in grasps])
    return GraspSet(tuple(grasps), positions, path.start_m, path.direction)


def grasp_span_m(obj: ObjectSpec) -> tuple[float, float]:
    """Grasp positions [m] the hand can take: along the main axis from the centre for a
    prism (pads 20 mm from the ends), along the grasp path from its start otherwise."""
    if obj.is_prism:
        half = obj.length_m / 2 - END_MARGIN_M
        return -half, half
    return grasp_set(obj).span_m
