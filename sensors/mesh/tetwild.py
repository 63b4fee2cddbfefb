"""Any watertight surface to a tet mesh with pytetwild (fTetWild), at its accurate settings.

:func:`validate_surface` repairs what it can (winding, zero-area faces) and refuses the rest;
:func:`tetrahedralize_surface` meshes with a tight envelope and caches the result on disk
(fTetWild gives a different mesh on every run). :mod:`.surface` holds the strict checks for
users' meshes and a call tuned for speed.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

from .intersections import count_self_intersections
from .tets import DEFAULT_MAX_DOF, MeshError, TetMesh, check_positive, check_size, check_tet_quality, orient_tets

__all__ = ["validate_surface", "tetrahedralize_surface"]

log = logging.getLogger(__name__)


def validate_surface(mesh) -> "trimesh.Trimesh":  # noqa: F821
    """Check a surface mesh is a valid solid boundary; return a copy with outward winding.

    Raises :class:`MeshError` naming the problem: non-finite vertices, no faces, not
    watertight (open boundary edges), inconsistent winding, zero volume, self-intersections.
    """
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise MeshError(f"expected a trimesh.Trimesh, got {type(mesh).__name__}")
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces)
    if len(faces) == 0 or len(vertices) < 4:
        raise MeshError("surface mesh is empty (no faces)")
    if not np.all(np.isfinite(vertices)):
        raise MeshError(f"surface mesh has {int((~np.isfinite(vertices)).any(axis=1).sum())} non-finite vertices (NaN or inf)")
    mesh = trimesh.Trimesh(vertices, faces, process=True, validate=False)
    extent = float(np.ptp(mesh.vertices, axis=0).max())
    if extent <= 0:
        raise MeshError("surface mesh has zero extent (all vertices coincide)")
    areas = mesh.area_faces
    if (areas <= 1e-14 * extent**2).any():
        mesh.update_faces(areas > 1e-14 * extent**2)
        mesh.remove_unreferenced_vertices()
    if not mesh.is_watertight:
        edges = mesh.edges_sorted
        _, counts = np.unique(edges, axis=0, return_counts=True)
        n_open = int((counts == 1).sum())
        n_multi = int((counts > 2).sum())
        raise MeshError(
            f"surface mesh is not watertight: {n_open} open boundary edges and {n_multi} edges shared by "
            "more than two faces; close the holes (e.g. trimesh.repair.fill_holes) first"
        )
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
        if not mesh.is_winding_consistent:
            raise MeshError("surface mesh has inconsistent face winding that could not be repaired")
    volume = float(mesh.volume)
    if not math.isfinite(volume) or abs(volume) <= 1e-9 * extent**3:
        raise MeshError(f"surface mesh encloses zero volume ({volume:.3g} m^3 for extent {extent:.3g} m)")
    if volume < 0:  # inside-out winding
        mesh.invert()
    n_cross = count_self_intersections(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    if n_cross:
        raise MeshError(f"surface mesh is self-intersecting: {n_cross} pairs of faces cross each other")
    return mesh


def tetrahedralize_surface(mesh, element_size_m: float | None = None, resolution: float = 1.0,
                           cache: bool = True, cache_dir=None, max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Tetrahedralize a watertight surface with pytetwild (fTetWild), cached on disk.

    The envelope is set so the output boundary stays within 0.1% of the smallest
    bounding-box extent of the input (fTetWild's default can thicken a 10 mm bar by 0.1 mm).

    Args:
        mesh: ``trimesh.Trimesh`` of a closed solid, in metres.
        element_size_m: Target edge length [m]; default a quarter of the smallest
            bounding-box extent divided by ``resolution``.
        cache: Reuse an earlier tetrahedralization of the same input (fTetWild is not
            deterministic, so caching also makes builds reproducible).
    """
    from .._infra import cache as cache_mod

    surface = validate_surface(mesh)
    verts = np.asarray(surface.vertices, dtype=np.float64)
    faces = np.asarray(surface.faces, dtype=np.int32)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    extents = hi - lo
    diag = float(np.linalg.norm(extents))
    if element_size_m is None:
        element_size_m = float(extents.min()) / 4.0
    check_positive(element_size_m=element_size_m, resolution=resolution)
    h = element_size_m / resolution
    # a tet mesh of edge h has about 1.7 vertices per h^3 of volume (regular tets of h^3 / 8.5)
    check_size(int(1.7 * abs(float(surface.volume)) / h ** 3), max_dof,
               f"a {extents[0]:.3g} x {extents[1]:.3g} x {extents[2]:.3g} m surface meshed at {h:.3g} m")
    epsilon = max(1e-3 * float(extents.min()) / diag, 1e-6)
    key = cache_mod.content_key("tetwild", verts, faces, h, epsilon)
    if cache:
        hit = cache_mod.load_arrays(key, cache_dir)
        if hit is not None:
            return TetMesh(hit["vertices"], hit["tets"], "mesh", {})
    import pytetwild  # imports pyvista at import time: keep it lazy

    start = time.perf_counter()
    log.info("pytetwild: %d faces, edge length %.3g m, envelope %.2g", len(faces), h, epsilon)
    # fTetWild leaves a debug file "__tracked_surface.stl" in the working directory: remove it
    # unless it was there before (the user's own file).
    debug_file = Path.cwd() / "__tracked_surface.stl"
    had_debug_file = debug_file.exists()
    try:
        tv, tt = pytetwild.tetrahedralize(verts, faces, edge_length_abs=h, epsilon=epsilon, quiet=True,
                                          num_threads=1)
    finally:
        if not had_debug_file:
            debug_file.unlink(missing_ok=True)
    tv = np.asarray(tv, dtype=np.float64)
    tt = np.asarray(tt, dtype=np.int64)
    if len(tt) == 0:
        raise MeshError("pytetwild returned no tetrahedra for this surface")
    used, tt = np.unique(tt, return_inverse=True)
    tt = tt.reshape(-1, 4)
    tv = tv[used]
    tt = orient_tets(tv, tt)
    check_tet_quality(tv, tt)
    out_lo, out_hi = tv.min(axis=0), tv.max(axis=0)
    dev = float(np.max(np.maximum(np.abs(out_lo - lo), np.abs(out_hi - hi)) / np.maximum(extents, 1e-300)))
    if dev > 1e-3:
        log.warning("pytetwild changed the bounding box by %.3g%% of an extent", 100 * dev)
    log.info("pytetwild: %d tets in %.1f s", len(tt), time.perf_counter() - start)
    if cache:
        cache_mod.save_arrays(key, {"vertices": tv, "tets": tt}, cache_dir)
    return TetMesh(tv, tt, "mesh", {})
