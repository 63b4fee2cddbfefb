"""MuJoCo bodies of catalog objects, and the descriptions a scene keeps of them.

Prisms lie with their main axis along the body's x axis, centred at the body origin: the frame
of ``sensors.ModalModel.bar/tube/rod``, so contact points in the body frame are directly points
of the modal model. Tubes and rods collide through a convex prism mesh (flat facets at the true
outer radius): MuJoCo 4.0.0's cylinder-edge multicontact bug is avoided and a flat fingertip
gets a stable face contact. Tubes are drawn hollow by a separate visual-only mesh.

Surface objects (everyday shapes, users' meshes) collide through convex pieces of CoACD
(hidden group 3, :mod:`aas_gym.collision`), are drawn with their surface, and carry the mass,
centre of mass and inertia of the solid.

Every object is described inside the compiled model by a custom text element
``aas_object:<body name>`` (``ObjectSpec.to_text``), which is how ``aas_gym.SimAcousticSensor``
finds shapes and materials in our scenes without extra input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from aas_gym.object_grasps import grasp_set, rest_height_m, rest_rotation
from sensors.objects.catalog import MESH_SHAPE, ObjectSpec

__all__ = ["OBJECT_TEXT_PREFIX", "Placement", "add_object", "object_specs_from_model", "euler_to_quat",
           "rotation_to_quat", "yaw_rest_quat"]

#: Prefix of the custom text elements that describe sensed objects.
OBJECT_TEXT_PREFIX = "aas_object:"
_PRISM_FACETS = 24  # collision prism of tubes and rods (multiple of 4: facets face +-y, +-z)
_VISUAL_SEGMENTS = 32
_MATERIAL_RGBA = {
    "aluminium": (0.78, 0.80, 0.83, 1.0),
    "steel": (0.45, 0.47, 0.50, 1.0),
    "wood": (0.66, 0.47, 0.27, 1.0),
    "abs": (0.90, 0.88, 0.80, 1.0),
    "pla": (0.95, 0.50, 0.15, 1.0),
    "glass": (0.70, 0.85, 0.90, 0.6),
    "ceramic": (0.93, 0.92, 0.88, 1.0),
}
#: Objects: stiff contacts like the fingertips so the grasp does not sink; moderate friction.
OBJECT_SOLREF = (0.004, 1.0)
OBJECT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
OBJECT_FRICTION = (0.5, 0.005, 0.0001)


@dataclass(frozen=True)
class Placement:
    """Initial pose of an object: centre position [m] (z = None rests it on the table) and
    rotation (yaw about world z, then roll/pitch) in radians."""

    x_m: float = 0.0
    y_m: float = 0.0
    z_m: float | None = None
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0


def euler_to_quat(yaw_rad: float, pitch_rad: float = 0.0, roll_rad: float = 0.0) -> np.ndarray:
    """Quaternion (w, x, y, z) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    quat = np.zeros(4)
    mujoco.mju_euler2Quat(quat, np.array([roll_rad, pitch_rad, yaw_rad]), "XYZ")
    return quat


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


def _prism_vertices(length_m: float, apothem_m: float, facets: int) -> np.ndarray:
    """Convex prism along x whose flat facets lie at ``apothem_m`` and face +-y, +-z."""
    radius = apothem_m / math.cos(math.pi / facets)
    theta = (np.arange(facets) + 0.5) * 2 * math.pi / facets
    ring = np.c_[np.cos(theta), np.sin(theta)] * radius
    half = length_m / 2
    return np.concatenate([np.c_[np.full(facets, -half), ring], np.c_[np.full(facets, half), ring]])


def _hollow_tube_mesh(length_m: float, ro: float, ri: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed, outward-oriented triangle mesh of a hollow tube along x (visual only)."""
    theta = np.arange(n) * 2 * math.pi / n
    c, s = np.cos(theta), np.sin(theta)
    h = length_m / 2
    verts = np.concatenate([
        np.c_[np.full(n, -h), ro * c, ro * s], np.c_[np.full(n, h), ro * c, ro * s],
        np.c_[np.full(n, -h), ri * c, ri * s], np.c_[np.full(n, h), ri * c, ri * s]])
    o0, o1, i0, i1 = 0, n, 2 * n, 3 * n
    faces = []
    for k in range(n):
        j = (k + 1) % n
        faces += [(o0 + k, o0 + j, o1 + j), (o0 + k, o1 + j, o1 + k)]      # outer, normal out
        faces += [(i0 + k, i1 + j, i0 + j), (i0 + k, i1 + k, i1 + j)]      # inner, normal in
        faces += [(o1 + k, o1 + j, i1 + j), (o1 + k, i1 + j, i1 + k)]      # +x end
        faces += [(o0 + k, i0 + j, o0 + j), (o0 + k, i0 + k, i0 + j)]      # -x end
    return verts, np.asarray(faces)


def add_object(spec: mujoco.MjSpec, obj: ObjectSpec, body_name: str,
               placement: Placement = Placement(), free: bool = True) -> mujoco.MjsBody:
    """Add ``obj`` as a body named ``body_name`` (free joint by default) and register its
    description (custom text ``aas_object:<body_name>``). A surface object rests on the
    table as :func:`aas_gym.object_grasps.rest_rotation` says, turned by the placement's yaw; a
    user's mesh the hand cannot hold anywhere is refused (``MeshError``) before its collision
    geometry is built."""
    rgba = _MATERIAL_RGBA.get(obj.material, (0.6, 0.6, 0.7, 1.0))
    common = dict(friction=OBJECT_FRICTION, solref=OBJECT_SOLREF, solimp=OBJECT_SOLIMP, rgba=rgba)
    if not obj.is_prism:
        if obj.shape == MESH_SHAPE:
            grasp_set(obj)  # a mesh the hand cannot hold: MeshError before anything is built
        solid = obj.solid()
        z = rest_height_m(solid) if placement.z_m is None else placement.z_m
        body = spec.worldbody.add_body(name=body_name, pos=[placement.x_m, placement.y_m, z],
                                       quat=yaw_rest_quat(solid, placement.yaw_rad))
        if free:
            body.add_freejoint(name=f"{body_name}_free")
        add_solid_geoms(spec, body, body_name, solid, common)
        spec.add_text(name=OBJECT_TEXT_PREFIX + body_name, data=obj.to_text())
        return body
    half = obj.half_extents_m
    z = half[2] if placement.z_m is None else placement.z_m
    body = spec.worldbody.add_body(name=body_name, pos=[placement.x_m, placement.y_m, z],
                                   quat=euler_to_quat(placement.yaw_rad, placement.pitch_rad))
    if free:
        body.add_freejoint(name=f"{body_name}_free")
    body.mass = obj.mass_kg
    body.inertia = obj.diag_inertia_kg_m2
    body.ipos = [0, 0, 0]
    body.explicitinertial = True
    if obj.shape == "bar":
        body.add_geom(name=f"{body_name}_geom", type=mujoco.mjtGeom.mjGEOM_BOX, size=half, mass=0, **common)
    else:
        prism = f"{body_name}_prism"
        spec.add_mesh(name=prism, uservert=_prism_vertices(obj.length_m, obj.outer_radius_m,
                                                           _PRISM_FACETS).ravel().tolist())
        visible = obj.shape == "rod"
        body.add_geom(name=f"{body_name}_geom", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=prism, mass=0,
                      group=0 if visible else 3, **common)
        if obj.shape == "tube":
            verts, faces = _hollow_tube_mesh(obj.length_m, obj.outer_radius_m, obj.inner_radius_m,
                                             _VISUAL_SEGMENTS)
            visual = f"{body_name}_visual"
            spec.add_mesh(name=visual, uservert=verts.ravel().tolist(), userface=faces.ravel().tolist(),
                          inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL)
            body.add_geom(name=visual, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=visual, mass=0,
                          contype=0, conaffinity=0, group=1, rgba=rgba)
    spec.add_text(name=OBJECT_TEXT_PREFIX + body_name, data=obj.to_text())
    return body


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


def object_specs_from_model(model: mujoco.MjModel) -> dict[str, ObjectSpec]:
    """Body name -> ``ObjectSpec`` for every ``aas_object:<body>`` text in ``model``."""
    out = {}
    for i in range(model.ntext):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, i) or ""
        if name.startswith(OBJECT_TEXT_PREFIX):
            body = name[len(OBJECT_TEXT_PREFIX):]
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body) < 0:
                raise ValueError(f"model describes object body {body!r} but has no such body")
            data = bytes(model.text_data[model.text_adr[i]:model.text_adr[i] + model.text_size[i]])
            out[body] = ObjectSpec.from_text(data.rstrip(b"\0").decode())
    return out
