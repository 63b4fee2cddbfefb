"""Objects given by a closed surface: the shipped everyday set (:mod:`sensors.objects.everyday`) and
users' meshes. Their rest pose on the table, their grasps anywhere on the surface, and their
MuJoCo bodies.

* A user's surface is stored content-addressed in the cache folder (``surfaces``), so a
  scene's ``aas_object:`` text names it by its id and any process of the user finds it again.
* Rest pose: the object's ``up_axis`` (``+x`` for the containers, ``+z`` for a user's mesh,
  which rests as it was modelled) points up; the body frame stays the modal model's frame.
* Grasps: antipodal pairs (:mod:`aas_gym.antipodal`) the hand reaches from above, cached on
  disk, and a path along the object's main axis on which grasp positions are measured.
* MuJoCo: convex pieces of CoACD for collision (cached), the surface itself as the visual
  mesh, mass and inertia of the solid (:mod:`aas_gym.collision`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from pathlib import Path

import mujoco
import numpy as np

from sensors._infra import cache as cache_mod
from sensors.mesh.tets import MeshError

__all__ = ["MESH_SUFFIXES", "FINGER_REACH_M", "ObjectGrasp", "GraspSet", "load_mesh_file", "store_surface",
           "stored_surface", "solid_of", "rest_rotation", "rest_height_m", "grasp_set", "add_solid_geoms"]

#: Files ``get_object`` reads as meshes (anything trimesh loads as one solid).
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")
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


@dataclasses.dataclass(frozen=True)
class ObjectGrasp:
    """A two-finger grasp in the object frame: contact midpoint, closing axis (unit), the
    distance between the contacts [m] (None: from the collision geometry, prisms), and its
    position along the object's grasp path [m]."""

    centre_m: np.ndarray
    axis: np.ndarray
    width_m: float | None
    position_m: float


def load_mesh_file(path) -> "trimesh.Trimesh":  # noqa: F821
    """A closed surface from a mesh file (every part of a multi-part file concatenated)."""
    import trimesh

    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {path} does not exist")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many types for foreign files
        raise MeshError(f"cannot read {path} as a mesh ({type(exc).__name__}: {exc}); "
                        f"use one of {', '.join(MESH_SUFFIXES)}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"{path} holds no triangle surface")
    return mesh


def _surface_id(vertices: np.ndarray, faces: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(faces, dtype="<i8").tobytes())
    return h.hexdigest()[:20]


_SURFACES: dict[str, object] = {}


def store_surface(surface, persist: bool = True) -> str:
    """Keep a checked surface under its content id in this process and, with ``persist``,
    in the cache folder (where other processes find it); returns the id."""
    v = np.asarray(surface.vertices, float)
    f = np.asarray(surface.faces, np.int64)
    mesh_id = _surface_id(v, f)
    _SURFACES.setdefault(mesh_id, surface)
    if persist and cache_mod.load_arrays(f"surface-{mesh_id}") is None:
        cache_mod.save_arrays(f"surface-{mesh_id}", {"vertices": v, "faces": f})
    return mesh_id


def stored_surface(mesh_id: str):
    """The surface stored as ``mesh_id`` (this process or the cache folder)."""
    import trimesh

    if mesh_id not in _SURFACES:
        hit = cache_mod.load_arrays(f"surface-{mesh_id}")
        if hit is None or _surface_id(hit["vertices"], hit["faces"]) != mesh_id:
            raise MeshError(f"the mesh {mesh_id} is not in the cache folder {cache_mod.default_cache_dir()}: "
                            "build the object again with ObjectSpec.from_mesh(...) (or get_object('<file>:<material>'))")
        _SURFACES[mesh_id] = trimesh.Trimesh(hit["vertices"], hit["faces"], process=False)
    return _SURFACES[mesh_id]


@functools.lru_cache(maxsize=64)
def solid_of(shape: str, material: str, mesh_id: str = "", name: str = ""):
    """The :class:`sensors.objects.everyday.EverydayObject` of an everyday shape in ``material``, or of
    a stored user surface (rests on its own -z side; tet-meshed with pytetwild)."""
    from sensors.objects.everyday import EVERYDAY_OBJECTS, EverydayObject
    from sensors.materials.solids import get_material

    mat = get_material(material)
    if shape in EVERYDAY_OBJECTS:
        obj = EVERYDAY_OBJECTS[shape]()
        return obj if obj.material.name == mat.name else dataclasses.replace(obj, material=mat)
    surface = stored_surface(mesh_id)
    axis = np.asarray(surface.principal_inertia_vectors[0], float)
    axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    mesher = functools.partial(_user_tet_mesh, mesh_id)
    return EverydayObject(name or mesh_id, mat, surface, mesher, main_axis=tuple(axis), up_axis=(0.0, 0.0, 1.0))


def _user_tet_mesh(mesh_id: str, resolution: float = 1.0):
    """pytetwild mesh of a user's surface: edges a quarter of its smallest extent, at most the
    thinnest wall (one P2 element across), divided by ``resolution``."""
    from sensors.mesh.surface import min_thickness_m, tetrahedralize_tuned

    surface = stored_surface(mesh_id)
    extents = np.ptp(np.asarray(surface.vertices), axis=0)
    h = min(float(extents.min()) / 4.0, 1.5 * min_thickness_m(surface)) / resolution
    h = max(h, float(extents.max()) / 80.0 / resolution)  # keeps a detailed scan within the dof guard
    return tetrahedralize_tuned(surface, element_size_m=h, kind="mesh")


def rest_rotation(solid) -> np.ndarray:
    """Rotation (3, 3) from the object frame to the world, before the placement's yaw: the
    object's ``up_axis`` to world +z and its main axis (or, parallel to up, object +z) to +x."""
    up = np.asarray(solid.up_axis, float)
    up /= np.linalg.norm(up)
    a = np.asarray(solid.main_axis, float)
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

    def nearest(self, position_m: float, avoid_m=(), clearance_m: float = 0.0,
                min_width_m: float = 0.0) -> ObjectGrasp:
        """The grasp whose position is closest to ``position_m``, among those at least
        ``min_width_m`` wide whose contacts stay ``clearance_m`` from every point of
        ``avoid_m`` (object frame)."""
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


def grasp_set(shape: str, material: str, mesh_id: str = "", name: str = "") -> GraspSet:
    """Antipodal grasps of the object, reachable by the hand with the object at rest; cached
    on disk (content key of the surface and the sampler's settings) and in this process."""
    return _grasp_set(shape, material, mesh_id, name)


@functools.lru_cache(maxsize=64)
def _grasp_set(shape, material, mesh_id, name) -> GraspSet:
    from aas_gym.antipodal import AntipodalGrasp, grasp_path, sample_antipodal_grasps

    solid = solid_of(shape, material, mesh_id, name)
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


def add_solid_geoms(spec: mujoco.MjSpec, body: mujoco.MjsBody, body_name: str, solid, common: dict) -> None:
    """Collision pieces (CoACD, hidden group 3), the visual surface (group 1), and the body's
    mass, centre of mass and inertia from the solid."""
    from aas_gym.collision import collision_geometry

    geometry = collision_geometry(solid.surface, solid.material)
    for i, piece in enumerate(geometry.pieces):
        mesh = f"{body_name}_piece{i}"
        spec.add_mesh(name=mesh, uservert=np.asarray(piece, float).ravel().tolist())
        body.add_geom(name=f"{body_name}_geom{i}" if i else f"{body_name}_geom", type=mujoco.mjtGeom.mjGEOM_MESH,
                      meshname=mesh, mass=0, group=3, **common)
    visual = f"{body_name}_visual"
    spec.add_mesh(name=visual, uservert=np.asarray(solid.surface.vertices, float).ravel().tolist(),
                  userface=np.asarray(solid.surface.faces, int).ravel().tolist())
    body.add_geom(name=visual, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=visual, mass=0, contype=0,
                  conaffinity=0, group=1, rgba=common["rgba"])
    inertia = geometry.inertia_kg_m2
    body.mass = geometry.mass_kg
    body.ipos = geometry.center_of_mass_m.tolist()
    body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    body.explicitinertial = True


def rotation_to_quat(rotation: np.ndarray) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation matrix."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, float).ravel())
    return quat


def yaw_rest_quat(solid, yaw_rad: float) -> np.ndarray:
    """Orientation of the object resting on the table, turned by ``yaw_rad`` about world z."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rotation_to_quat(rz @ rest_rotation(solid))
