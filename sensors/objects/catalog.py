"""The catalog: every object the project names, its shape, material and modal model.

An object is an :class:`ObjectSpec`, named by :func:`get_object`:

* ``<material>_<shape>`` with a prism shape ``bar``, ``tube``, ``rod`` (the paper's sizes; main
  axis along x, centred at the origin: the frame of ``sensors.ModalModel.bar/tube/rod``) or an
  everyday shape (:mod:`sensors.objects.everyday`: ``steel_mug``), in any material of
  ``sensors.MATERIALS``;
* an everyday shape alone, in its own material (``"mug"`` = ``"ceramic_mug"``);
* ``<mesh file>:<material>[:<scale>]``, a user's closed surface (:mod:`sensors.objects.user_mesh`),
  or :meth:`ObjectSpec.from_mesh` for a ``trimesh.Trimesh``.

Its modal model is :meth:`ObjectSpec.modal_model` (built once, then loaded from the disk
cache). Nothing here imports MuJoCo: ``aas_gym`` builds scene bodies from these entries and the
real rig names its objects the same way.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
from pathlib import Path

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from ..materials.solids import MATERIALS, get_material
from .everyday import EVERYDAY_OBJECTS, EverydayObject
from .user_mesh import MESH_SUFFIXES, load_mesh_file, store_surface, user_solid

__all__ = ["ObjectSpec", "get_object", "known_material_names", "everyday_material", "PRISM_SHAPES",
           "EVERYDAY_SHAPES", "MESH_SHAPE", "ALL_SHAPES"]

#: Prisms along x, centred at the origin (the paper's objects).
PRISM_SHAPES = ("bar", "tube", "rod")
#: The shipped everyday objects (:data:`sensors.objects.everyday.EVERYDAY_OBJECTS`).
EVERYDAY_SHAPES = tuple(EVERYDAY_OBJECTS)
#: A user's closed surface.
MESH_SHAPE = "mesh"
ALL_SHAPES = PRISM_SHAPES + EVERYDAY_SHAPES + (MESH_SHAPE,)


def _material(name: str):
    """The ``sensors`` material record for ``name``; ``ValueError`` listing known names."""
    try:
        return get_material(name)
    except KeyError as exc:
        raise ValueError(exc.args[0] if exc.args else f"unknown material {name!r}") from None


def known_material_names() -> list[str]:
    """Names accepted as object materials (the keys of ``sensors.MATERIALS``)."""
    return sorted(MATERIALS)


def everyday_material(shape: str) -> str:
    """What the everyday object ``shape`` is made of: its factory's default (``"mug"`` ->
    ``"ceramic"``), read without building it."""
    return inspect.signature(EVERYDAY_OBJECTS[shape]).parameters["material"].default


@dataclasses.dataclass(frozen=True)
class ObjectSpec:
    """Shape, dimensions and material of one object.

    Prisms (main axis along x, centred at the origin): ``bar``: ``length_m`` x ``width_m``
    (y) x ``height_m`` (z). ``tube``: ``length_m``, ``outer_radius_m``, ``inner_radius_m``.
    ``rod``: ``length_m``, ``outer_radius_m``. Use the ``bar``/``tube``/``rod`` constructors.

    Surface objects (in the frame of :mod:`sensors.objects.everyday`; their dimension fields
    are unused): an everyday shape (``mug``, ``bottle``, ``can``, ``glass``, ``box``, ``spoon``,
    ``l_bracket``) in any material, or ``mesh``: a user's surface stored under ``mesh_id``
    and labelled ``<material>_<name>`` (:meth:`from_mesh`).
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
        (``name`` defaults to the file's stem, else ``mesh-<first 8 characters of its content id>``).

        The surface is checked first (watertight, outward, not degenerate or self-intersecting,
        one closed shell, at most 100,000 faces, 2 mm .. 0.5 m, walls at least 0.5 mm): each fault
        raises a ``sensors.MeshError`` subclass that says what to do, and nothing is written.
        Then it is stored in the cache folder by content, where other processes find it. Whether
        a hand can hold it is the scene's question (``aas_gym`` refuses a mesh its hand cannot grasp).
        """
        from ..mesh.surface import check_surface

        if name is not None and not isinstance(name, str):
            raise TypeError(f"name must be a string, got {type(name).__name__}")
        if not isinstance(material, str):
            raise TypeError(f"material must be a material name (a string), got {type(material).__name__}")
        material = _material(material).name  # names checked before a file is read
        from_file = isinstance(mesh, (str, Path))
        if from_file:
            name = name or Path(mesh).stem
        given = re.sub(r"[^A-Za-z0-9_-]+", "_", name or "").strip("_")
        if given in ALL_SHAPES:
            raise ValueError(f"name {given!r} is a built-in shape: choose another name for your mesh")
        if from_file:
            mesh = load_mesh_file(mesh)
        surface = check_surface(mesh, scale=scale)
        mesh_id = store_surface(surface)
        # Without a name (a Trimesh has no file stem) the content id names it: "mesh" is a shape.
        return cls(MESH_SHAPE, material, mesh_id=mesh_id, name=given or f"mesh-{mesh_id[:8]}")

    @property
    def is_prism(self) -> bool:
        """A bar, tube or rod (grasped across its main axis; leaned on in multi-object scenes)."""
        return self.shape in PRISM_SHAPES

    def solid(self) -> EverydayObject | None:
        """The :class:`~sensors.objects.everyday.EverydayObject` of a surface object (its
        surface, tet mesher, cavity; None for a prism)."""
        if self.is_prism:
            return None
        return _SOLIDS.get_or_build((self.shape, self.material, self.mesh_id, self.name), self._build_solid)

    def _build_solid(self) -> EverydayObject:
        material = get_material(self.material)
        if self.shape == MESH_SHAPE:
            return user_solid(self.mesh_id, material, self.name)
        obj = EVERYDAY_OBJECTS[self.shape]()
        return obj if obj.material.name == material.name else dataclasses.replace(obj, material=material)

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
        """``key=value`` description (a scene's ``aas_object:`` text; see ``from_text``)."""
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
        """The object's ``sensors.ModalModel``: the one way to get it (built once, then loaded
        from the disk cache). ``options`` go to ``ModalModel.bar/tube/rod`` for a prism and to
        :meth:`EverydayObject.modal_model <sensors.objects.everyday.EverydayObject.modal_model>`
        for a surface object (e.g. ``max_frequency_hz``, ``resolution``, ``cache_dir``)."""
        from ..modal.model import ModalModel

        if not self.is_prism:
            return self.solid().modal_model(**options)
        material = _material(self.material)
        if self.shape == "bar":
            return ModalModel.bar(self.length_m, self.width_m, self.height_m, material, **options)
        if self.shape == "tube":
            return ModalModel.tube(self.length_m, self.outer_radius_m, self.inner_radius_m, material, **options)
        return ModalModel.rod(self.length_m, self.outer_radius_m, material, **options)


#: Solids of surface objects in this process (their surfaces are built procedurally or read).
_SOLIDS = LRU(CACHE_SIZES["objects.solids"])


def get_object(name: str | ObjectSpec) -> ObjectSpec:
    """An object from its name (an :class:`ObjectSpec` is returned as is).

    * ``<material>_<shape>`` with a prism shape ``bar``, ``tube``, ``rod`` (paper-sized) or an
      everyday shape (``steel_mug``); any material of ``sensors.MATERIALS``;
    * an everyday shape alone, in its own material (``"mug"`` = ``"ceramic_mug"``);
    * ``<mesh file>:<material>[:<scale>]``, a user's mesh (``"parts/bracket.stl:aluminium:0.001"``
      for a file in millimetres), as :meth:`ObjectSpec.from_mesh`.
    """
    if isinstance(name, ObjectSpec):
        return name
    if not isinstance(name, str):
        raise ValueError(f"object name must look like '<material>_<shape>' (a string such as 'wood_bar'), got {name!r}")
    path, _, rest = name.partition(":")
    if path.lower().endswith(MESH_SUFFIXES):
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
        return ObjectSpec(lowered, everyday_material(lowered))
    named = [s for s in ALL_SHAPES if s != MESH_SHAPE]
    shape = next((s for s in named if lowered.endswith("_" + s)), None)
    if shape is None and "_" in lowered:
        raise ValueError(f"unknown shape {lowered.rpartition('_')[2]!r} in object name {name!r}; known shapes: "
                         f"{', '.join(named)}, or '<mesh file>:<material>'")
    if shape is None:
        raise ValueError(f"object name must look like '<material>_<shape>' (shapes: {', '.join(named)}), an "
                         f"everyday object name or '<mesh file>:<material>', got {name!r}; e.g. 'aluminium_bar', "
                         "'mug'")
    material = lowered[:-len(shape) - 1]
    try:
        _material(material)
    except ValueError:
        raise ValueError(f"unknown material {material!r} in object name {name!r}; "
                         f"known materials: {known_material_names()}") from None
    if shape in EVERYDAY_SHAPES:
        return ObjectSpec(shape, material)
    return {"bar": ObjectSpec.bar, "tube": ObjectSpec.tube, "rod": ObjectSpec.rod}[shape](material)
