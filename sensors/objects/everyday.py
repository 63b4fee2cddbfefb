"""A shipped set of everyday objects, made procedurally (no downloads), with their materials.

The catalog names them (``sensors.objects.get_object("mug")``, ``"steel_mug"``); the factories
here also make other sizes (``mug(outer_radius_m=0.04)``).

Every object is a :class:`EverydayObject`: a closed, consistently wound ``trimesh`` surface
in metres, its material, a tet mesher and, for containers, the inner cavity a liquid fills.

Object frame (the modal model's): ``main_axis`` is +x for every object.

* Containers (``can``, ``glass``, ``bottle``, ``mug``, ``box``): x is the axis from the outer
  floor (x = 0) to the opening (+x); the revolved ones are symmetric about the x axis.
  ``up_axis`` (+x) is the direction that points up when the container stands on a table.
* ``spoon``: length along x (bowl toward +x), width along y, the bowl opens toward +z
  (``up_axis``), centred on its bounding box in x and y.
* ``l_bracket``: width along x (centred), one flange along +y lying on the table (z from 0),
  the other standing up along +z (``up_axis``).

Meshing is structured wherever the shape allows (:mod:`sensors.mesh.layered`): revolved
profiles for the can, glass and bottle, a revolved cup with a swept D handle for the mug,
extruded grids for the box, the bracket and the spoon. User meshes go through pytetwild
(:mod:`sensors.mesh.surface`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np
import trimesh

from .._infra import cache as cache_mod
from ..modal import build as modal_build
from ..mesh.layered import grid_template, handled_cup_mesh, layered_mesh, p2_dof_count, revolved_mesh
from ..materials.solids import Material, get_material
from ..mesh.tets import TetMesh, boundary_faces
from ..modal.model import ModalModel
from ..mesh.surface import check_dof

__all__ = ["EverydayObject", "EVERYDAY_OBJECTS", "can", "glass", "bottle", "mug", "box", "spoon", "l_bracket"]


@dataclasses.dataclass(frozen=True)
class EverydayObject:
    """One procedural object.

    Attributes:
        name: Short name ("mug", "can", ...).
        material: Its :class:`~sensors.Material`.
        surface: Closed outward-wound surface [m] in the object frame.
        tet_mesher: callable(resolution=1.0) -> :class:`~sensors.mesh.tets.TetMesh` of the solid.
        main_axis: Unit vector of the main axis in the object frame (+x for all).
        up_axis: Object-frame direction that points up when it rests on a table.
        cavity: For containers, the closed surface of the inside up to the rim (the volume
            a liquid can fill), else None.
        inner_profile_m: For revolved containers, (k, 2) rows (x, r) of the inner surface from
            the floor (r = 0) to the rim, else None.
        dimensions_m: Named sizes.
    """

    name: str
    material: Material
    surface: trimesh.Trimesh
    tet_mesher: Callable[..., TetMesh]
    main_axis: tuple = (1.0, 0.0, 0.0)
    up_axis: tuple = (1.0, 0.0, 0.0)
    cavity: trimesh.Trimesh | None = None
    inner_profile_m: np.ndarray | None = None
    dimensions_m: dict = dataclasses.field(default_factory=dict)

    def tet_mesh(self, resolution: float = 1.0) -> TetMesh:
        """The solid's tet mesh (``resolution`` multiplies element counts per direction)."""
        return self.tet_mesher(resolution=resolution)

    def modal_model(self, resolution: float = 1.0, max_dof: int | None = None, **options):
        """This solid's :class:`~sensors.ModalModel` (cached); options as ``from_tet_mesh``. A
        catalog object's model is ``ObjectSpec.modal_model``, which calls this for its solid.

        Refuses (:class:`~sensors.mesh.surface.MeshTooLargeError`) a mesh above ``max_dof``
        P2 dofs (default :data:`~sensors.mesh.surface.DEFAULT_MAX_DOF`) before assembling.

        A cached model loads without meshing: a small alias entry, keyed by the surface, the
        mesher's source, the resolution, the material and the options, names the model's own
        (mesh-content) cache entry. Rebuilding a structured mesh only to key the cache was most
        of a cached load (bottle: 30 of 60 ms).
        """
        opts = modal_build.options(options)
        alias = None
        # Only for this module's meshers: their source is in the key (a user mesh's is not).
        if opts["cache"] and getattr(self.tet_mesher, "__module__", None) == __name__:
            alias = cache_mod.content_key("everyday-modal-alias", _MESHER_VERSION, np.asarray(self.surface.vertices),
                                          np.asarray(self.surface.faces), float(resolution), max_dof,
                                          self.material.to_dict(), modal_build.key_options(opts))
            hit = cache_mod.load_arrays(alias, opts["cache_dir"])
            if hit is not None and "modal_key" in hit:
                model = ModalModel.from_cache_key(str(hit["modal_key"]), **options)
                if model is not None:
                    return model
        tm = self.tet_mesh(resolution)
        check_dof(p2_dof_count(tm), max_dof, f"the {self.name} at resolution {resolution}")
        model = ModalModel.from_tet_mesh(tm, self.material, **options)
        if alias is not None and model.metadata.get("cache_key"):
            cache_mod.save_arrays(alias, {"modal_key": np.array(str(model.metadata["cache_key"]))}, opts["cache_dir"])
        return model

    @property
    def mass_kg(self) -> float:
        """Mass of the solid [kg] (surface volume times density)."""
        return float(self.surface.volume * self.material.density_kg_m3)

    def to_dict(self) -> dict:
        """JSON-friendly description (name, material, sizes, axes)."""
        return {"name": self.name, "material": self.material.to_dict(), "dimensions_m": dict(self.dimensions_m),
                "main_axis": list(self.main_axis), "up_axis": list(self.up_axis),
                "is_container": self.cavity is not None}


#: The source of the meshers (all structured): part of the modal alias key, so an edited mesher
#: is never served an old model through the alias (the tet meshers, sensors.mesh.tets and its
#: kin, are already in every key through cache.CODE_VERSION; user meshes, pytetwild's, take no alias).
_MESHER_VERSION = cache_mod.source_version("sensors.objects.everyday", "sensors.mesh.layered")


# ----------------------------------------------------------------------------- helpers


def surface_of(tet_mesh: TetMesh) -> trimesh.Trimesh:
    """The boundary of a tet mesh as a closed, outward-wound trimesh (its exact FE surface)."""
    faces, _ = boundary_faces(tet_mesh.tets)
    used, inverse = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(tet_mesh.vertices_m[used], inverse.reshape(-1, 3), process=True)


def _revolve_x(profile_xr: np.ndarray, sections: int = 96) -> trimesh.Trimesh:
    """Closed surface of revolution about x of a polyline (x, r) running from the axis back to it."""
    rz = np.column_stack([profile_xr[:, 1], profile_xr[:, 0]])  # trimesh revolves (r, z) about z
    mesh = trimesh.creation.revolve(rz, sections=sections)
    mesh.apply_transform(np.array([[0, 0, 1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]]))  # z -> x
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _cavity(inner_xr: np.ndarray) -> trimesh.Trimesh:
    """The closed inside of a revolved container: inner profile closed across the rim."""
    return _revolve_x(np.vstack([inner_xr, [[inner_xr[-1, 0], 0.0]]]))


def _levels(segments: list[tuple[float, float, int]]) -> np.ndarray:
    """Axial levels from (start, end, n_layers) segments that join end to start."""
    out = [segments[0][0]]
    for a, b, n in segments:
        out.extend(np.linspace(a, b, max(1, int(n)) + 1)[1:])
    return np.asarray(out)


def _n(count: float, resolution: float, minimum: int = 1) -> int:
    return max(minimum, int(math.ceil(count * resolution - 1e-9)))


def _n_theta(base: int, resolution: float) -> int:
    return 8 * max(2, int(round(base * resolution / 8)))


# ----------------------------------------------------------------------------- revolved containers


def _revolved_container(name, material, inner, outer, floor_m, height_m, segments, n_theta, dims, radii):
    """Container about x: ``inner``/``outer`` radius functions, floor thickness, axial segments."""

    def mesher(resolution: float = 1.0) -> TetMesh:
        segs = [(a, b, _n(n, resolution)) for a, b, n in segments]
        levels = _levels([(0.0, floor_m, _n(1, resolution))] + segs)
        return revolved_mesh(levels, inner, outer, _n(1, resolution), n_theta=_n_theta(n_theta, resolution),
                             kind=name, dimensions_m=dims, cylinder_radii_m=radii)

    x = np.concatenate([[floor_m], np.linspace(floor_m, height_m, 200)])
    inner_xr = np.column_stack([x, [0.0] + [float(inner(v)) for v in x[1:]]])
    surface = surface_of(mesher(2.0))
    return EverydayObject(name, get_material(material), surface, mesher, cavity=_cavity(inner_xr),
                          inner_profile_m=inner_xr, dimensions_m=dims)


def can(outer_radius_m: float = 0.033, wall_m: float = 0.002, height_m: float = 0.09, floor_m: float = 0.002,
        material="steel") -> EverydayObject:
    """An open steel can (a sturdy tin: 2 mm wall), 66 mm across: graspable across."""
    ro, ri = outer_radius_m, outer_radius_m - wall_m
    dims = dict(outer_radius_m=ro, inner_radius_m=ri, height_m=height_m, floor_m=floor_m)
    return _revolved_container("can", material, lambda x: ri, lambda x: ro, floor_m, height_m,
                               [(floor_m, height_m, 18)], 64, dims, (ri, ro))  # 48 around left a ring pair 1.8 % stiff


def glass(outer_radius_m: float = 0.034, wall_m: float = 0.003, height_m: float = 0.095, floor_m: float = 0.008,
          material="glass") -> EverydayObject:
    """A straight soda-lime tumbler with a thick floor, 68 mm across."""
    ro, ri = outer_radius_m, outer_radius_m - wall_m
    dims = dict(outer_radius_m=ro, inner_radius_m=ri, height_m=height_m, floor_m=floor_m)
    return _revolved_container("glass", material, lambda x: ri, lambda x: ro, floor_m, height_m,
                               [(floor_m, height_m, 21)], 48, dims, (ri, ro))  # 14 levels: a pair 1.19 % stiff


def bottle(body_radius_m: float = 0.032, neck_radius_m: float = 0.013, wall_m: float = 0.003,
           body_height_m: float = 0.13, shoulder_m: float = 0.035, neck_m: float = 0.045, floor_m: float = 0.004,
           material="glass") -> EverydayObject:
    """A glass bottle: cylindrical body, a smooth (cosine) shoulder, a straight open neck."""
    x1, x2 = body_height_m, body_height_m + shoulder_m
    height = x2 + neck_m

    def outer(x):
        if x <= x1:
            return body_radius_m
        if x >= x2:
            return neck_radius_m
        s = 0.5 - 0.5 * math.cos(math.pi * (x - x1) / shoulder_m)
        return body_radius_m + (neck_radius_m - body_radius_m) * s

    def inner(x):
        return outer(x) - wall_m

    dims = dict(body_radius_m=body_radius_m, neck_radius_m=neck_radius_m, wall_m=wall_m, height_m=height,
                floor_m=floor_m)
    radii = (body_radius_m - wall_m, body_radius_m, neck_radius_m - wall_m, neck_radius_m)
    # 1.5x the axial levels of the first version: at (16, 8, 6) modes sat up to 1.23 % stiff against the
    # gmsh + scikit-fem reference, now 0.81 % (64 around instead moved them less per dof).
    return _revolved_container("bottle", material, inner, outer, floor_m, height,
                               [(floor_m, x1, 24), (x1, x2, 12), (x2, height, 9)], 48, dims, radii)


# ----------------------------------------------------------------------------- mug


def mug(outer_radius_m: float = 0.038, wall_m: float = 0.0045, height_m: float = 0.095, floor_m: float = 0.007,
        handle_width_m: float = 0.012, handle_thickness_m: float = 0.008, handle_top_m: float = 0.083,
        handle_bottom_m: float = 0.022, handle_stub_m: float = 0.006, material="ceramic") -> EverydayObject:
    """A ceramic mug (76 mm across) with a D handle on the +y side.

    The handle is a ``handle_width_m`` (z) x ``handle_thickness_m`` bar: straight stubs leave
    the wall between ``handle_top_m - thickness`` and ``handle_top_m`` and between
    ``handle_bottom_m`` and ``handle_bottom_m + thickness`` (heights above the outer floor),
    reach ``handle_stub_m`` beyond the wall's outermost point and are joined by a half circle.
    The whole mug is one structured, conforming mesh
    (:func:`~sensors.mesh.layered.handled_cup_mesh`): 0.02 s where pytetwild took 26-34 s
    for the earlier torus handle.
    """
    ro, ri = outer_radius_m, outer_radius_m - wall_m
    t = handle_thickness_m
    if not floor_m < handle_bottom_m < handle_bottom_m + t < handle_top_m - t < handle_top_m < height_m:
        raise ValueError("the handle's stubs must lie on the wall, apart, below the rim")
    if not 0 < handle_width_m < ro:
        raise ValueError(f"handle_width_m must be in (0, {ro}) m, got {handle_width_m}")
    dims = dict(outer_radius_m=ro, inner_radius_m=ri, height_m=height_m, floor_m=floor_m,
                handle_width_m=handle_width_m, handle_thickness_m=t, handle_top_m=handle_top_m,
                handle_bottom_m=handle_bottom_m, handle_stub_m=handle_stub_m)

    def mesher(resolution: float = 1.0, mirror_split: bool = True) -> TetMesh:
        # 4 x 3 cells across the handle, 24 around its bend, two through the wall: every mode below
        # 10 kHz within 0.93 % of a 2.5 mm gmsh + scikit-fem reference (one through the wall:
        # ovalling modes 0.5 % stiff; 2 x 2 across and 16 around: the handle's bending 2.7 %).
        # Mirror-split (the default) its modes solve in two symmetry classes (sensors.fem.mirror).
        across, through = _n(2, resolution), _n(3, resolution)
        segments = [(0.0, floor_m, _n(1, resolution)), (floor_m, handle_bottom_m, _n(4, resolution)),
                    (handle_bottom_m, handle_bottom_m + t, through),
                    (handle_bottom_m + t, handle_top_m - t, _n(11, resolution)),
                    (handle_top_m - t, handle_top_m, through), (handle_top_m, height_m, _n(3, resolution))]
        levels = _levels(segments)
        k0 = sum(n for _, _, n in segments[:2])
        k2 = k0 + through + segments[3][2]
        return handled_cup_mesh(levels, ri, ro, segments[0][2], (k0, k0 + through, k2, k2 + through),
                                math.asin(0.5 * handle_width_m / ro), 2 * across, handle_stub_m,
                                _n(2, resolution), _n(24, resolution), n_theta=_n_theta(48, resolution),
                                n_wall=_n(2, resolution), kind="mug", dimensions_m=dims, mirror_split=mirror_split)

    x = np.concatenate([[floor_m], np.linspace(floor_m, height_m, 50)])
    inner_xr = np.column_stack([x, np.r_[0.0, np.full(len(x) - 1, ri)]])
    # The surface (collision pieces, mass) is the plain split's: the same vertices, but its
    # triangles gave CoACD 36 pieces on which the mug rests on the table (~1e-10 m/s); the
    # mirror split's gave 40 on which it trembled at ~1e-4 m/s (tests/test_settle_until_rest.py).
    return EverydayObject("mug", get_material(material), surface_of(mesher(2.0, mirror_split=False)), mesher,
                          cavity=_cavity(inner_xr), inner_profile_m=inner_xr, dimensions_m=dims)


# ----------------------------------------------------------------------------- extruded grids


def _lines(segments: list[tuple[float, float, int]]) -> np.ndarray:
    return _levels(segments)


def box(length_m: float = 0.08, width_m: float = 0.06, height_m: float = 0.045, wall_m: float = 0.004,
        material="abs") -> EverydayObject:
    """An open-top ABS box: floor at x = 0, opening at +x, footprint width (y) x length (z)."""
    dims = dict(length_m=length_m, width_m=width_m, height_m=height_m, wall_m=wall_m)
    hw, hl, t = 0.5 * width_m, 0.5 * length_m, wall_m

    def mesher(resolution: float = 1.0) -> TetMesh:
        # 16 x 20 across the walls' planes and 12 up: half of that left the thin walls' plate
        # modes up to 4.9 % stiff against the gmsh + scikit-fem reference (0.8 % now).
        ny, nz = _n(16, resolution), _n(20, resolution)
        y = _lines([(-hw, -hw + t, 1), (-hw + t, hw - t, ny), (hw - t, hw, 1)])
        z = _lines([(-hl, -hl + t, 1), (-hl + t, hl - t, nz), (hl - t, hl, 1)])
        tpl = grid_template(y, z, lambda u, v: ((np.abs(u) > hw - t) | (np.abs(v) > hl - t)).astype(int))
        levels = _levels([(0.0, t, 1), (t, height_m, _n(12, resolution))])

        def place(p, k):
            return np.column_stack([np.full(len(p), levels[k]), p])

        return layered_mesh(tpl, len(levels) - 1, lambda k: np.ones(len(tpl.triangles), bool) if k == 0
                            else tpl.region == 1, place, "box", dims, mirror_axes=(1, 2))

    inner = trimesh.creation.box([height_m - t, width_m - 2 * t, length_m - 2 * t])
    inner.apply_translation([0.5 * (height_m + t), 0.0, 0.0])
    return EverydayObject("box", get_material(material), surface_of(mesher(1.0)), mesher, cavity=inner,
                          dimensions_m=dims)


def l_bracket(flange_m: float = 0.04, thickness_m: float = 0.003, width_m: float = 0.025,
              material="aluminium") -> EverydayObject:
    """An aluminium angle bracket: flanges along +y (on the table) and +z, width along x."""
    dims = dict(flange_m=flange_m, thickness_m=thickness_m, width_m=width_m)
    t = thickness_m

    def mesher(resolution: float = 1.0) -> TetMesh:
        n = _n(12, resolution)
        lines = _lines([(0.0, t, 2), (t, flange_m, n)])
        tpl = grid_template(lines, lines, lambda u, v: np.where((u < t) | (v < t), 0, -1))
        levels = np.linspace(-0.5 * width_m, 0.5 * width_m, _n(8, resolution) + 1)

        def place(p, k):
            return np.column_stack([np.full(len(p), levels[k]), p])

        return layered_mesh(tpl, len(levels) - 1, lambda k: np.ones(len(tpl.triangles), bool), place, "l_bracket",
                            dims)

    return EverydayObject("l_bracket", get_material(material), surface_of(mesher(1.0)), mesher,
                          up_axis=(0.0, 0.0, 1.0), dimensions_m=dims)


def spoon(length_m: float = 0.25, handle_width_m: float = 0.016, bowl_width_m: float = 0.048,
          bowl_length_m: float = 0.07, handle_thickness_m: float = 0.007, bowl_thickness_m: float = 0.005,
          bowl_depth_m: float = 0.008, material="wood") -> EverydayObject:
    """A wooden spoon: a flat handle and a dished, blunt-tipped oval bowl (toward +x, opening +z).

    A structured plate: the planform grid (x along the length, y across, scaled to the local
    width) is swept through its thickness and the bowl's points are lowered into a dish.
    """
    dims = dict(length_m=length_m, handle_width_m=handle_width_m, bowl_width_m=bowl_width_m,
                bowl_length_m=bowl_length_m, bowl_depth_m=bowl_depth_m)
    x0, x1 = -0.5 * length_m, 0.5 * length_m
    a = 0.5 * bowl_length_m / 0.9  # the oval is cut at 90% of its half-length: a blunt tip
    xc = x1 - 0.9 * a

    def bowl_rho2(x, y):
        return ((x - xc) / a) ** 2 + (y / (0.5 * bowl_width_m)) ** 2

    def half_width(x):
        oval = 0.5 * bowl_width_m * np.sqrt(np.clip(1.0 - ((x - xc) / a) ** 2, 0.0, None))
        return np.maximum(0.5 * handle_width_m, oval)

    def thickness(x):
        s = np.clip((x - (xc - a)) / (0.5 * a), 0.0, 1.0)
        return handle_thickness_m + (bowl_thickness_m - handle_thickness_m) * s

    def mesher(resolution: float = 1.0) -> TetMesh:
        # 60 x 9 cells and two layers: 40 x 6 and one left modes up to 2.3 % stiff against a
        # converged gmsh + scikit-fem reference (2 and 3 mm agree to 0.25 %), now 0.6 %.
        u = np.linspace(x0, x1, _n(60, resolution) + 1)
        v = np.linspace(-1.0, 1.0, _n(9, resolution) + 1)
        tpl = grid_template(u, v, lambda uc, vc: np.zeros(len(uc), int))
        n_layers = _n(2, resolution)

        def place(p, k):
            x = p[:, 0]
            y = p[:, 1] * half_width(x)
            dish = -bowl_depth_m * np.clip(1.0 - bowl_rho2(x, y), 0.0, None) ** 2
            z = dish + thickness(x) * (k / n_layers - 0.5)
            return np.column_stack([x, y, z])

        return layered_mesh(tpl, n_layers, lambda k: np.ones(len(tpl.triangles), bool), place, "spoon", dims)

    return EverydayObject("spoon", get_material(material), surface_of(mesher(1.0)), mesher,
                          up_axis=(0.0, 0.0, 1.0), dimensions_m=dims)


#: name -> factory of the shipped everyday set (default sizes; each factory's ``material`` default
#: is what the object is made of). The catalog (:mod:`sensors.objects.catalog`) names them.
EVERYDAY_OBJECTS: dict[str, Callable[..., EverydayObject]] = {
    "mug": mug, "bottle": bottle, "can": can, "glass": glass, "box": box, "spoon": spoon, "l_bracket": l_bracket,
}
