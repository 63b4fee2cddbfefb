"""Scene composition: objects (bars, tubes, rods of any material), a table and the Franka hand.

Objects lie with their main axis along the body's x axis, centred at the body origin: the
frame of ``sensors.ModalModel.bar/tube/rod``, so contact points in the body frame are directly
points of the modal model. Every sensed object is described inside the compiled model by a
custom text element ``aas_object:<body name>`` (``ObjectSpec.to_text``), which is how
``aas_gym.SimAcousticSensor`` finds shapes and materials in our scenes without extra input.

Tubes and rods collide through a convex prism mesh (flat facets at the true outer radius):
MuJoCo 4.0.0's cylinder-edge multicontact bug is avoided and a flat fingertip gets a stable
face contact. Tubes are drawn hollow by a separate visual-only mesh.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from aas_gym.assets import HAND_XML, OBJECTS_DIR, SCENES_DIR
from aas_gym.object_names import DEFAULT_OBJECT_NAMES  # noqa: F401  (re-exported)

#: Prisms along x, centred at the origin (the paper's objects).
SHAPES = ("bar", "tube", "rod")
#: Shapes given by a closed surface: the shipped everyday set and ``"mesh"`` (a user's).
EVERYDAY_SHAPES = ("mug", "bottle", "can", "glass", "box", "spoon", "l_bracket")
MESH_SHAPE = "mesh"
ALL_SHAPES = SHAPES + EVERYDAY_SHAPES + (MESH_SHAPE,)
#: Each everyday object in what it is made of (``get_object("mug")`` = ``"ceramic_mug"``).
EVERYDAY_MATERIALS = {"mug": "ceramic", "bottle": "glass", "can": "steel", "glass": "glass", "box": "abs",
                      "spoon": "wood", "l_bracket": "aluminium"}
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
# Objects: stiff contacts like the fingertips so the grasp does not sink; moderate friction.
_OBJECT_SOLREF = (0.004, 1.0)
_OBJECT_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
_OBJECT_FRICTION = (0.5, 0.005, 0.0001)
TABLE_HALF_SIZE_M = (0.45, 0.45, 0.02)
#: Fingertip pads (20 mm wide) stay this far from a prism's ends.
END_MARGIN_M = 0.02


def _material(name: str):
    """The ``sensors`` material record for ``name``; ``ValueError`` listing known names."""
    from sensors.materials.solids import get_material

    try:
        return get_material(name)
    except KeyError as exc:
        raise ValueError(exc.args[0] if exc.args else f"unknown material {name!r}") from None


def known_material_names() -> list[str]:
    """Names accepted as object materials (the keys of ``sensors.MATERIALS``)."""
    from sensors.materials.solids import MATERIALS

    return sorted(MATERIALS)


@dataclass(frozen=True)
class ObjectSpec:
    """Shape, dimensions and material of one sensed object.

    Prisms (main axis along x, centred at the origin): ``bar``: ``length_m`` x ``width_m``
    (y) x ``height_m`` (z). ``tube``: ``length_m``, ``outer_radius_m``, ``inner_radius_m``.
    ``rod``: ``length_m``, ``outer_radius_m``. Use the ``bar``/``tube``/``rod`` constructors.

    Surface objects (in the frame of ``sensors.objects.everyday``; their dimension fields are unused):
    an everyday shape (``mug``, ``bottle``, ``can``, ``glass``, ``box``, ``spoon``,
    ``l_bracket``) in any material, or ``mesh``: a user's surface stored under ``mesh_id``
    and labelled ``<material>_<name>`` (``ObjectSpec.from_mesh``).
    """

    shape: str
    material: str
    length_m: float = 0.2
    width_m: float = 0.025
    height_m: float = 0.025
    outer_radius_m: float = 0.0125
    inner_radius_m: float = 0.0095
    mesh_id: str = ""
    name: str = ""

    def __post_init__(self) -> None:
        if self.shape not in ALL_SHAPES:
            raise ValueError(f"unknown shape {self.shape!r}; known shapes: {list(ALL_SHAPES)}")
        if (self.shape == MESH_SHAPE) != bool(self.mesh_id):
            raise ValueError("a mesh object needs mesh_id= (use ObjectSpec.from_mesh), and only a mesh object has one")
        if self.shape == MESH_SHAPE and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_-]*", self.name or ""):
            raise ValueError(f"a mesh object needs a name of letters, digits, '_' and '-', got {self.name!r}")
        # Canonical name (aliases such as "aluminum" resolve); clear error for unknown names.
        object.__setattr__(self, "material", _material(str(self.material)).name)
        dims = [self.length_m, self.width_m, self.height_m, self.outer_radius_m]
        if not all(np.isfinite(dims)) or min(dims) <= 0:
            raise ValueError(f"object dimensions must be positive and finite, got {self}")
        if self.shape == "tube" and not 0 < self.inner_radius_m < self.outer_radius_m:
            raise ValueError("a tube needs 0 < inner_radius_m < outer_radius_m")

    @classmethod
    def bar(cls, material: str, length_m: float = 0.2, width_m: float = 0.025, height_m: float = 0.025):
        """A rectangular bar (paper default 200 x 25 x 25 mm)."""
        return cls("bar", material, length_m=length_m, width_m=width_m, height_m=height_m)

    @classmethod
    def tube(cls, material: str, length_m: float = 0.2, outer_radius_m: float = 0.0125, inner_radius_m: float = 0.0095):
        """A round tube (paper default 200 mm long, 25 mm OD, 19 mm ID)."""
        return cls("tube", material, length_m=length_m, outer_radius_m=outer_radius_m, inner_radius_m=inner_radius_m)

    @classmethod
    def rod(cls, material: str, length_m: float = 0.2, radius_m: float = 0.0125):
        """A solid round rod."""
        return cls("rod", material, length_m=length_m, outer_radius_m=radius_m)

    @classmethod
    def from_mesh(cls, mesh, material: str, name: str | None = None, scale: float = 1.0) -> "ObjectSpec":
        """A user's object from a closed surface (``trimesh.Trimesh`` or a mesh file) in metres
        (``scale=1e-3`` for millimetres), made of ``material``; labelled ``<material>_<name>``
        (``name`` defaults to the file's stem).

        The surface is checked first (watertight, outward, not degenerate or self-intersecting,
        2 mm .. 0.5 m, walls at least 0.5 mm): each fault raises a ``sensors.MeshError``
        subclass that says what to do, and nothing is written. It rests on the table as
        modelled (+z up) and is grasped where the hand reaches it from above.
        """
        from aas_gym import mesh_objects
        from sensors.mesh.surface import check_surface

        if isinstance(mesh, (str, Path)):
            name = name or Path(mesh).stem
            mesh = mesh_objects.load_mesh_file(mesh)
        name = re.sub(r"[^A-Za-z0-9_-]+", "_", name or "mesh").strip("_") or "mesh"
        if name in ALL_SHAPES:
            raise ValueError(f"name {name!r} is a built-in shape: choose another name for your mesh")
        material = _material(material).name
        surface = check_surface(mesh, scale=scale)
        mesh_id = mesh_objects.store_surface(surface, persist=False)
        spec = cls(MESH_SHAPE, material, mesh_id=mesh_id, name=name)
        mesh_objects.grasp_set(spec.shape, spec.material, mesh_id, name)  # no grasp: MeshError, nothing written
        mesh_objects.store_surface(surface)
        return spec

    @property
    def is_prism(self) -> bool:
        """A bar, tube or rod (grasped across its main axis; leaned on in multi-object scenes)."""
        return self.shape in SHAPES

    def solid(self):
        """The ``sensors.objects.everyday.EverydayObject`` of a surface object (None for a prism)."""
        if self.is_prism:
            return None
        from aas_gym.mesh_objects import solid_of

        return solid_of(self.shape, self.material, self.mesh_id, self.name)

    @property
    def grasp_span_m(self) -> tuple[float, float]:
        """Grasp positions [m] the hand can take: along the main axis from the centre for a
        prism (pads 20 mm from the ends), along the grasp path from its start otherwise."""
        if self.is_prism:
            half = self.length_m / 2 - END_MARGIN_M
            return -half, half
        from aas_gym.mesh_objects import grasp_set

        return grasp_set(self.shape, self.material, self.mesh_id, self.name).span_m

    @property
    def label(self) -> str:
        """Class label used by datasets and the recognition env, e.g. ``aluminium_tube``."""
        return f"{self.material}_{self.name if self.shape == MESH_SHAPE else self.shape}"

    @property
    def half_extents_m(self) -> np.ndarray:
        """Half sizes of the bounding box in the object frame (x = main axis; for a surface
        object, half the extents of its surface, whose origin need not be the centre)."""
        if not self.is_prism:
            return np.ptp(np.asarray(self.solid().surface.vertices), axis=0) / 2
        if self.shape == "bar":
            return np.array([self.length_m, self.width_m, self.height_m]) / 2
        return np.array([self.length_m / 2, self.outer_radius_m, self.outer_radius_m])

    @property
    def density_kg_m3(self) -> float:
        return float(_material(self.material).density_kg_m3)

    @property
    def cross_section_area_m2(self) -> float:
        if self.shape == "bar":
            return self.width_m * self.height_m
        inner = self.inner_radius_m if self.shape == "tube" else 0.0
        return math.pi * (self.outer_radius_m**2 - inner**2)

    @property
    def mass_kg(self) -> float:
        if not self.is_prism:
            return self.solid().mass_kg
        return self.density_kg_m3 * self.cross_section_area_m2 * self.length_m

    @property
    def diag_inertia_kg_m2(self) -> np.ndarray:
        """Principal inertia about the centroid (exact for the ideal shape)."""
        m, length = self.mass_kg, self.length_m
        if self.shape == "bar":
            w, h = self.width_m, self.height_m
            return m / 12 * np.array([w**2 + h**2, length**2 + h**2, length**2 + w**2])
        ri = self.inner_radius_m if self.shape == "tube" else 0.0
        r2 = self.outer_radius_m**2 + ri**2
        return np.array([m / 2 * r2, m / 12 * (3 * r2 + length**2), m / 12 * (3 * r2 + length**2)])

    def to_text(self) -> str:
        """``key=value`` description stored in the model's custom text (see ``from_text``)."""
        keys = {"bar": ("length_m", "width_m", "height_m"),
                "tube": ("length_m", "outer_radius_m", "inner_radius_m"),
                "rod": ("length_m", "outer_radius_m"),
                MESH_SHAPE: ("mesh_id", "name")}.get(self.shape, ())
        if self.shape == MESH_SHAPE:
            return " ".join([f"shape={self.shape}", f"material={self.material}"]
                            + [f"{k}={getattr(self, k)}" for k in keys])
        return " ".join([f"shape={self.shape}", f"material={self.material}"]
                        + [f"{k}={getattr(self, k)!r}" for k in keys])

    @classmethod
    def from_text(cls, text: str) -> "ObjectSpec":
        """Parse ``to_text`` output; raises ``ValueError`` naming the bad field."""
        fields = {}
        for item in text.split():
            key, sep, value = item.partition("=")
            if not sep:
                raise ValueError(f"bad object description item {item!r} in {text!r}")
            fields[key] = value
        if "shape" not in fields or "material" not in fields:
            raise ValueError(f"object description {text!r} needs shape= and material=")
        allowed = {f.name for f in dataclasses.fields(cls)}
        unknown = set(fields) - allowed
        if unknown:
            raise ValueError(f"unknown object description keys {sorted(unknown)} in {text!r}")
        kwargs = {k: (v if k in ("shape", "material", "mesh_id", "name") else float(v)) for k, v in fields.items()}
        return cls(**kwargs)

    def modal_model(self, **options):
        """Build (or load from the disk cache) the ``sensors.ModalModel`` of this object;
        ``options`` go to ``ModalModel.bar/tube/rod`` (e.g. ``max_frequency_hz``)."""
        from sensors.modal.model import ModalModel

        if not self.is_prism:
            return self.solid().modal_model(**options)
        material = _material(self.material)
        if self.shape == "bar":
            return ModalModel.bar(self.length_m, self.width_m, self.height_m, material, **options)
        if self.shape == "tube":
            return ModalModel.tube(self.length_m, self.outer_radius_m, self.inner_radius_m, material, **options)
        return ModalModel.rod(self.length_m, self.outer_radius_m, material, **options)


def get_object(name: str | ObjectSpec) -> ObjectSpec:
    """An object from its name.

    * ``<material>_<shape>`` with a prism shape ``bar``, ``tube``, ``rod`` (paper-sized) or an
      everyday shape (``steel_mug``); any material of ``sensors.MATERIALS``;
    * an everyday shape alone, in its own material (``"mug"`` = ``"ceramic_mug"``);
    * ``<mesh file>:<material>[:<scale>]``, a user's mesh (``"parts/bracket.stl:aluminium:0.001"``
      for a file in millimetres), as ``ObjectSpec.from_mesh``.
    """
    if isinstance(name, ObjectSpec):
        return name
    if not isinstance(name, str):
        raise ValueError(f"object name must look like '<material>_<shape>' (a string such as 'wood_bar'), got {name!r}")
    path, _, rest = name.partition(":")
    if path.lower().endswith(_mesh_suffixes()):
        material, _, scale = rest.partition(":")
        if not material:
            raise ValueError(f"a mesh object needs its material: '{path}:<material>[:<scale>]', "
                             f"known materials: {known_material_names()}")
        try:
            scale_value = float(scale) if scale else 1.0
        except ValueError:
            raise ValueError(f"bad scale {scale!r} in {name!r}: a number such as 0.001") from None
        return ObjectSpec.from_mesh(path, material, scale=scale_value)
    lowered = name.lower()
    if lowered in EVERYDAY_SHAPES:
        return ObjectSpec(lowered, EVERYDAY_MATERIALS[lowered])
    shape = next((s for s in ALL_SHAPES if s != MESH_SHAPE and lowered.endswith("_" + s)), None)
    if shape is None and "_" in lowered:
        raise ValueError(f"unknown shape {lowered.rpartition('_')[2]!r} in object name {name!r}; known shapes: "
                         f"{', '.join(s for s in ALL_SHAPES if s != MESH_SHAPE)}, or '<mesh file>:<material>'")
    if shape is None:
        raise ValueError(f"object name must look like '<material>_<shape>' (shapes: "
                         f"{', '.join(s for s in ALL_SHAPES if s != MESH_SHAPE)}), an everyday object name or "
                         f"'<mesh file>:<material>', got {name!r}; defaults: {list(DEFAULT_OBJECT_NAMES)}")
    material = lowered[:-len(shape) - 1]
    try:
        _material(material)
    except ValueError:
        raise ValueError(f"unknown material {material!r} in object name {name!r}; "
                         f"known materials: {known_material_names()}") from None
    if shape in EVERYDAY_SHAPES:
        return ObjectSpec(shape, material)
    return {"bar": ObjectSpec.bar, "tube": ObjectSpec.tube, "rod": ObjectSpec.rod}[shape](material)


def _mesh_suffixes() -> tuple[str, ...]:
    from aas_gym.mesh_objects import MESH_SUFFIXES

    return MESH_SUFFIXES


def default_objects() -> list[ObjectSpec]:
    """The paper's seven objects."""
    return [get_object(n) for n in DEFAULT_OBJECT_NAMES]


@dataclass(frozen=True)
class FingertipSpec:
    """A replaceable fingertip: pad half sizes along the object axis and vertical, contact
    parameters. The pad's contact face stays on the finger's joint origin so the gripper
    tendon length remains the opening between the faces."""

    half_width_m: float = 0.010
    half_height_m: float = 0.008
    friction: tuple[float, float, float] = (1.0, 0.01, 0.0005)
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    rgba: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 1.0)


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
    table as ``aas_gym.mesh_objects.rest_rotation`` says, turned by the placement's yaw."""
    rgba = _MATERIAL_RGBA.get(obj.material, (0.6, 0.6, 0.7, 1.0))
    common = dict(friction=_OBJECT_FRICTION, solref=_OBJECT_SOLREF, solimp=_OBJECT_SOLIMP, rgba=rgba)
    if not obj.is_prism:
        from aas_gym import mesh_objects

        solid = obj.solid()
        z = mesh_objects.rest_height_m(solid) if placement.z_m is None else placement.z_m
        body = spec.worldbody.add_body(name=body_name, pos=[placement.x_m, placement.y_m, z],
                                       quat=mesh_objects.yaw_rest_quat(solid, placement.yaw_rad))
        if free:
            body.add_freejoint(name=f"{body_name}_free")
        mesh_objects.add_solid_geoms(spec, body, body_name, solid, common)
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


def add_table(spec: mujoco.MjSpec) -> None:
    """A wooden table whose top surface is the world plane z = 0, with a floor below."""
    hx, hy, hz = TABLE_HALF_SIZE_M
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.1],
                            pos=[0, 0, -0.75], rgba=[0.35, 0.37, 0.4, 1], contype=0, conaffinity=0)
    table = spec.worldbody.add_body(name="table", pos=[0, 0, -hz])
    table.add_geom(name="table_top", type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, hz],
                   rgba=[0.55, 0.42, 0.3, 1], friction=[0.5, 0.005, 0.0001],
                   solref=_OBJECT_SOLREF, solimp=_OBJECT_SOLIMP)
    leg_h = (0.75 - 2 * hz) / 2
    for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        table.add_geom(name=f"table_leg{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, leg_h],
                       pos=[sx * (hx - 0.03), sy * (hy - 0.03), -hz - leg_h], rgba=[0.45, 0.33, 0.22, 1],
                       contype=0, conaffinity=0, group=1)


def _add_stage(spec: mujoco.MjSpec) -> None:
    """Light, cameras and a sky colour for pictures."""
    spec.visual.global_.offwidth = 640
    spec.visual.global_.offheight = 480
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.55, 0.65, 0.8], rgb2=[0.1, 0.1, 0.15], width=256, height=256)
    spec.worldbody.add_light(name="key", pos=[0.3, -0.4, 1.2], dir=[-0.25, 0.35, -1], diffuse=[0.8, 0.8, 0.8])
    spec.worldbody.add_light(name="fill", pos=[-0.5, 0.5, 1.0], dir=[0.4, -0.4, -1], diffuse=[0.3, 0.3, 0.3])
    spec.worldbody.add_camera(name="overview", pos=[0.5, -0.5, 0.5], xyaxes=_look_at([0.5, -0.5, 0.5], [0, 0, 0.1]))
    # Low side view: sees the fingertips and the object under the hand body.
    spec.worldbody.add_camera(name="closeup", pos=[0.2, -0.24, 0.08],
                              xyaxes=_look_at([0.2, -0.24, 0.08], [0, 0, 0.035]))


def _look_at(pos, target) -> list[float]:
    """MuJoCo camera ``xyaxes`` looking from ``pos`` at ``target`` with world z up."""
    back = np.asarray(pos, float) - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return [*right, *up]


def unique_body_names(objects: Sequence[ObjectSpec]) -> list[str]:
    """Body names from labels, suffixed ``_1``, ``_2`` ... for repeated objects."""
    names, seen = [], {}
    for obj in objects:
        k = seen.get(obj.label, 0)
        names.append(obj.label if k == 0 else f"{obj.label}_{k}")
        seen[obj.label] = k + 1
    return names


def build_scene_spec(objects: Iterable[str | ObjectSpec] = ("aluminium_bar",),
                     placements: Sequence[Placement] | None = None,
                     fingertip: FingertipSpec | None = None,
                     table: bool = True, contact_signature: bool = False) -> mujoco.MjSpec:
    """Compose hand, table and objects into an ``MjSpec`` (compile it with ``.compile()``).

    Without ``placements`` objects lie on the table side by side along y, 80 mm apart.
    ``contact_signature`` adds the sensors a streaming microphone watches every physics step
    (:func:`add_contact_signature_sensors`); scenes without streaming do not pay for them.
    """
    objs = [get_object(o) for o in objects]
    if placements is None:
        placements = [Placement(0.0, 0.08 * (i - (len(objs) - 1) / 2)) for i in range(len(objs))]
    if len(placements) != len(objs):
        raise ValueError(f"{len(objs)} objects but {len(placements)} placements")
    spec = mujoco.MjSpec.from_file(str(HAND_XML))
    spec.modelname = "aas_scene"
    if fingertip is not None:
        replace_fingertips(spec, fingertip)
    _add_stage(spec)
    if table:
        add_table(spec)
    for obj, name, place in zip(objs, unique_body_names(objs), placements):
        add_object(spec, obj, name, place)
        add_touch_sensors(spec, name)
    if contact_signature:
        add_contact_signature_sensors(spec, unique_body_names(objs), table=table)
    return spec


#: Fingertip bodies carrying the actuator and microphone sites in the aas_gym hand.
FINGERTIP_BODIES = {"actuator": "left_fingertip", "mic": "right_fingertip"}


def touch_sensor_name(body: str, side: str) -> str:
    """Name of the contact sensor between ``body`` and the ``side`` ("actuator"/"mic") tip."""
    return f"{body}_touch_{side}"


def add_touch_sensors(spec: mujoco.MjSpec, body: str) -> None:
    """Two MuJoCo contact sensors (number of contacts of ``body`` with each sensor fingertip):
    a grasp test computed in C during the step, so environments can check it every step
    without walking the contact list in Python."""
    for side, tip in FINGERTIP_BODIES.items():
        spec.add_sensor(name=touch_sensor_name(body, side), type=mujoco.mjtSensor.mjSENS_CONTACT,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=tip,
                        reftype=mujoco.mjtObj.mjOBJ_BODY, refname=body,
                        intprm=[1, 0, 1])  # data "found" (contact count), no reduction, 1 slot


#: Data of one signature sensor: contact count, net force (3), force-weighted point (3).
SIGNATURE_WIDTH = 7


def signature_partners(bodies: Sequence[str], body: str, table: bool = True) -> list[str]:
    """The partner bodies whose contacts with ``body`` its signature sensors sum up, in order:
    actuator fingertip, microphone fingertip, the table (if any), the other objects."""
    return ([FINGERTIP_BODIES["actuator"], FINGERTIP_BODIES["mic"]] + (["table"] if table else [])
            + [b for b in bodies if b != body])


def signature_sensor_name(body: str, partner: str) -> str:
    """Name of the signature sensor of ``body``'s contacts with ``partner`` (``"*"``: any)."""
    return f"{body}_signature_{partner}"


def add_contact_signature_sensors(spec: mujoco.MjSpec, bodies: Sequence[str], table: bool = True) -> None:
    """Per object and partner body (:func:`signature_partners`), one MuJoCo contact sensor
    with the contact count, the net contact force and its force-weighted point (world
    frame), then one count of all the object's contacts. Computed in C during the step, they
    let a streaming microphone see in a few microseconds whether the contacts changed since it
    last read the contact list (``aas_gym.sim_stream``)."""
    found, force, pos, netforce = 1, 2, 16, 3
    for body in bodies:
        for partner in signature_partners(bodies, body, table):
            spec.add_sensor(name=signature_sensor_name(body, partner), type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body,
                            reftype=mujoco.mjtObj.mjOBJ_BODY, refname=partner,
                            intprm=[found | force | pos, netforce, 1])
        spec.add_sensor(name=signature_sensor_name(body, "*"), type=mujoco.mjtSensor.mjSENS_CONTACT,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body, intprm=[found, 0, 1])


def build_scene(objects: Iterable[str | ObjectSpec] = ("aluminium_bar",), **kwargs) -> mujoco.MjModel:
    """Compiled model of ``build_scene_spec(objects, **kwargs)``."""
    return build_scene_spec(objects, **kwargs).compile()


def replace_fingertips(spec: mujoco.MjSpec, fingertip: FingertipSpec) -> None:
    """Swap both fingertip pads of a hand spec for ``fingertip``."""
    for side in ("left", "right"):
        geom = spec.geom(f"{side}_fingertip")
        if geom is None:
            raise ValueError(f"spec has no geom '{side}_fingertip' (not an aas_gym hand?)")
        thickness = geom.size[1]
        geom.size = [fingertip.half_width_m, thickness, fingertip.half_height_m]
        geom.friction = fingertip.friction
        geom.solref = fingertip.solref
        geom.solimp = fingertip.solimp
        geom.rgba = fingertip.rgba
        geom.material = ""


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


def write_asset_files(objects_dir: Path = OBJECTS_DIR, scenes_dir: Path = SCENES_DIR) -> list[Path]:
    """Write the generated MJCF files shipped in ``assets/``: a bar and a tube of every
    material (``objects/<label>.xml``: the object alone, with its description), a
    single-object, a multi-object and an all-default-objects scene with the hand.
    Regenerate after changing this module."""
    objects_dir.mkdir(parents=True, exist_ok=True)
    scenes_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for obj in [get_object(f"{m}_{shape}") for m in known_material_names() for shape in ("bar", "tube")]:
        spec = mujoco.MjSpec()
        spec.modelname = obj.label
        add_object(spec, obj, obj.label)
        path = objects_dir / f"{obj.label}.xml"
        path.write_text(spec.to_xml())
        written.append(path)
    scenes = {
        "single_object.xml": build_scene_spec(["aluminium_bar"]),
        "multi_object.xml": build_scene_spec(
            ["aluminium_bar", "wood_bar", "aluminium_tube"],
            placements=[Placement(0.0, 0.0), Placement(-0.06, 0.09, None, math.pi / 2 - 0.3),
                        Placement(0.0, -0.06)]),
        "all_objects.xml": build_scene_spec(DEFAULT_OBJECT_NAMES),
    }
    for name, spec in scenes.items():
        path = scenes_dir / name
        path.write_text(spec.to_xml())
        written.append(path)
    return written


if __name__ == "__main__":
    for p in write_asset_files():
        print(p)
