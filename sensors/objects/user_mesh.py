"""Users' objects given by a closed surface: read from a file, checked, and stored by content.

A user's surface is stored content-addressed in the cache folder, so a scene's description
names it by its id (``mesh_id``) and any process of the user finds it again. Its solid rests on
its own -z side (+z up, as modelled) and is tet-meshed with pytetwild.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import numpy as np

from .._infra import cache as cache_mod
from ..materials.solids import Material
from ..mesh.tets import MeshError
from .everyday import EverydayObject

__all__ = ["MESH_SUFFIXES", "load_mesh_file", "store_surface", "stored_surface", "user_solid"]

#: Files ``get_object`` reads as meshes (anything trimesh loads as one solid).
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")


def load_mesh_file(path) -> "trimesh.Trimesh":  # noqa: F821
    """A closed surface from a mesh file (every part of a multi-part file concatenated)."""
    import trimesh

    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {path} does not exist")
    try:
        # Read raw first: trimesh's processing drops non-finite vertices with their faces, and
        # the hole that leaves would be reported as "not watertight" instead of the NaN.
        raw = trimesh.load(path, force="mesh", process=False)
        if isinstance(raw, trimesh.Trimesh) and not np.all(np.isfinite(np.asarray(raw.vertices, dtype=float))):
            raise MeshError(f"{path} has non-finite (NaN or inf) vertex coordinates: fix or drop them")
        mesh = trimesh.load(path, force="mesh")
    except MeshError:
        raise
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


#: Surfaces by id in this process: a registry, not a cache (a surface checked but not yet
#: persisted lives only here).
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


def user_solid(mesh_id: str, material: Material, name: str = "") -> EverydayObject:
    """The solid of a stored user surface in ``material``: its main axis the first principal axis
    of inertia trimesh gives, resting on its -z side, tet-meshed with pytetwild."""
    surface = stored_surface(mesh_id)
    axis = np.asarray(surface.principal_inertia_vectors[0], float)
    axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    mesher = functools.partial(_user_tet_mesh, mesh_id)
    return EverydayObject(name or mesh_id, material, surface, mesher, main_axis=tuple(axis), up_axis=(0.0, 0.0, 1.0))


def _user_tet_mesh(mesh_id: str, resolution: float = 1.0):
    """pytetwild mesh of a user's surface: edges a quarter of its smallest extent, at most the
    thinnest wall (one P2 element across), divided by ``resolution``."""
    from ..mesh.surface import min_thickness_m, tetrahedralize_tuned

    surface = stored_surface(mesh_id)
    extents = np.ptp(np.asarray(surface.vertices), axis=0)
    h = min(float(extents.min()) / 4.0, 1.5 * min_thickness_m(surface)) / resolution
    h = max(h, float(extents.max()) / 80.0 / resolution)  # keeps a detailed scan within the dof guard
    return tetrahedralize_tuned(surface, element_size_m=h, kind="mesh")
