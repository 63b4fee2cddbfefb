"""User surfaces to tet meshes: checks with errors that say what to do, a size guard, and a
pytetwild call tuned for speed.

Checks (:func:`check_surface`), each a :class:`~sensors.mesh.tets.MeshError` subclass:

* :class:`MeshScaleError` - largest extent above 2 m or below 2 mm (a unit mix-up: pass
  ``scale=``), or larger than the hand can handle (:data:`HAND_MAX_EXTENT_M`).
* :class:`MeshNotWatertightError` - open boundary or non-manifold edges.
* :class:`MeshSeveralBodiesError` - more than one closed shell (two bodies, or a shell inside a shell).
* :class:`MeshInvertedError` - faces wound inward (negative volume) or inconsistently.
* :class:`MeshDegenerateError` - zero-area faces or zero volume.
* :class:`MeshSelfIntersectingError` - faces crossing each other.
* :class:`MeshTooThinError` - walls thinner than a tet mesher can resolve.
* :class:`MeshTooLargeError` - more faces than ``max_faces`` (:data:`MAX_SURFACE_FACES`), or the
  estimated P2 model exceeds ``max_dof`` (a keyword raises it).

All checks run before anything is written, so a rejected mesh leaves nothing in the cache.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from pathlib import Path

import numpy as np
import trimesh

from .._infra import cache as cache_mod
from .intersections import count_self_intersections
from .tets import DEFAULT_MAX_DOF, MeshError, TetMesh, check_tet_quality, orient_tets

__all__ = [
    "MeshScaleError", "MeshNotWatertightError", "MeshInvertedError", "MeshDegenerateError",
    "MeshSelfIntersectingError", "MeshSeveralBodiesError", "MeshTooThinError", "MeshTooLargeError", "check_surface",
    "estimate_p2_dof",
    "check_dof", "tetrahedralize_tuned", "DEFAULT_MAX_DOF", "BYTES_PER_DOF", "MIN_EXTENT_M", "MAX_EXTENT_M",
    "HAND_MAX_EXTENT_M", "MIN_THICKNESS_M", "MAX_SURFACE_FACES", "THICKNESS_RAY_FACE_PAIRS",
]

log = logging.getLogger(__name__)

#: Extents outside [MIN_EXTENT_M, MAX_EXTENT_M] look like a unit mix-up (mm or inches as m).
MIN_EXTENT_M = 0.002
MAX_EXTENT_M = 2.0
#: The Franka hand lifts objects up to this size in the scenes (its table workspace).
HAND_MAX_EXTENT_M = 0.5
#: Thinnest wall the tet meshers resolve with at least one P2 element across.
MIN_THICKNESS_M = 0.0005
#: Largest surface :func:`check_surface` takes (``max_faces=`` or this constant changes it): its checks cost
#: time and memory in proportion (a 20k-face sphere's wall-thickness check alone took 6 s and
#: 1.4 GB before it was bounded); a scan is simplified to this first.
MAX_SURFACE_FACES = 100_000
#: Ray-face pairs the wall-thickness check tests at most (rays x faces): fewer rays on a
#: dense surface, so its cost is bounded (2000 rays up to 10,000 faces).
THICKNESS_RAY_FACE_PAIRS = 20_000_000
#: Ray-face pairs cast at once (bounds the ray tracer's candidate arrays to a few hundred MB).
_PAIRS_PER_BATCH = 2_000_000
#: Measured peak memory of assembly plus sparse LU per P2 dof on the project's meshes.
BYTES_PER_DOF = 20_000


class MeshScaleError(MeshError):
    """The mesh is too small or too large (a unit mix-up, or bigger than the hand handles)."""


class MeshNotWatertightError(MeshError):
    """The surface has holes or non-manifold edges."""


class MeshSeveralBodiesError(MeshError):
    """The surface holds more than one closed shell (separate bodies, or a cavity's shell)."""


class MeshInvertedError(MeshError):
    """The surface's faces point inward, or their winding is inconsistent."""


class MeshDegenerateError(MeshError):
    """Zero-area faces or a surface enclosing no volume."""


class MeshSelfIntersectingError(MeshError):
    """Faces of the surface cross each other."""


class MeshTooThinError(MeshError):
    """Walls too thin to tet-mesh."""


class MeshTooLargeError(MeshError):
    """The model would need more degrees of freedom (memory) than the limit allows."""


def check_surface(mesh, scale: float = 1.0, hand_max_extent_m: float = HAND_MAX_EXTENT_M,
                  max_faces: int | None = None) -> trimesh.Trimesh:
    """Validate a user's closed surface; return a scaled, merged copy. Raises a MeshError subclass.

    Args:
        mesh: ``trimesh.Trimesh`` (or anything ``trimesh.load`` reads, e.g. a path).
        scale: Multiplies the coordinates first (0.001 for a mesh in millimetres).
        max_faces: Refuse a denser surface at once (None: :data:`MAX_SURFACE_FACES`, read at
            the call, so raising that constant raises it everywhere, user objects included).
    """
    if isinstance(mesh, (str, Path)):
        mesh = trimesh.load(mesh, force="mesh")
    if not isinstance(mesh, trimesh.Trimesh):
        raise MeshError(f"expected a trimesh.Trimesh or a mesh file, got {type(mesh).__name__}")
    if isinstance(scale, bool) or not (isinstance(scale, (int, float, np.integer, np.floating))
                                       and math.isfinite(scale) and scale >= np.finfo(float).tiny):
        raise MeshScaleError(f"scale must be a positive number (a normal float), got {scale!r}")
    max_faces = MAX_SURFACE_FACES if max_faces is None else max_faces
    if len(mesh.faces) > max_faces:
        raise MeshTooLargeError(
            f"surface mesh has {len(mesh.faces):,} faces, above the limit of {max_faces:,} (its checks and tet mesh "
            f"would take minutes and GBs): simplify it first (mesh.simplify_quadric_decimation(face_count="
            f"{max_faces // 2})), or raise the limit (sensors.mesh.surface.MAX_SURFACE_FACES, or max_faces= "
            "of check_surface)")
    vertices = np.asarray(mesh.vertices, dtype=float) * scale
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0 or len(vertices) < 4:
        raise MeshDegenerateError("surface mesh is empty (no faces): pass a closed solid")
    if not np.all(np.isfinite(vertices)):
        raise MeshDegenerateError("surface mesh has non-finite (NaN or inf) vertices: fix or drop them")
    extent = float(np.ptp(vertices, axis=0).max())
    if extent > MAX_EXTENT_M or extent < MIN_EXTENT_M:
        suggestion = 10.0 ** round(math.log10(0.1 / extent)) if extent > 0 else 1.0
        raise MeshScaleError(
            f"surface mesh is {extent:.3g} m across, outside {MIN_EXTENT_M} m .. {MAX_EXTENT_M} m: is it in other "
            f"units? Pass scale= (e.g. scale={suggestion:g} for a mesh {'in millimetres' if extent > 1 else 'too small'})")
    if extent > hand_max_extent_m:
        raise MeshScaleError(
            f"surface mesh is {extent:.3g} m across, larger than the hand handles ({hand_max_extent_m} m); pass "
            "scale= to shrink it (or raise hand_max_extent_m for a scene without the hand)")
    surface = trimesh.Trimesh(vertices, faces, process=True, validate=False)
    areas = surface.area_faces
    n_zero = int((areas <= 1e-12 * extent**2).sum())
    if n_zero:
        raise MeshDegenerateError(
            f"surface mesh has {n_zero} zero-area faces: remove them (mesh.update_faces(mesh.nondegenerate_faces())) "
            "and close the holes that leaves")
    if not surface.is_watertight:
        _, counts = np.unique(surface.edges_sorted, axis=0, return_counts=True)
        raise MeshNotWatertightError(
            f"surface mesh is not watertight: {int((counts == 1).sum())} open boundary edges and "
            f"{int((counts > 2).sum())} edges shared by more than two faces; close the holes "
            "(trimesh.repair.fill_holes) or rebuild it as one closed solid")
    if not surface.is_winding_consistent:
        raise MeshInvertedError("surface mesh has inconsistently wound faces: call trimesh.repair.fix_winding(mesh)")
    volume = float(surface.volume)
    if abs(volume) <= 1e-9 * extent**3:
        raise MeshDegenerateError(f"surface mesh encloses no volume ({volume:.3g} m^3): pass a solid, not a sheet")
    if volume < 0:
        raise MeshInvertedError("surface mesh is inside out (faces wound inward, negative volume): call mesh.invert()")
    n_cross = count_self_intersections(np.asarray(surface.vertices), np.asarray(surface.faces))
    if n_cross:
        raise MeshSelfIntersectingError(
            f"surface mesh is self-intersecting ({n_cross} pairs of faces cross): merge its parts with a boolean "
            "union (trimesh.boolean.union(..., engine='manifold'))")
    n_bodies = int(surface.body_count)
    if n_bodies > 1:
        # One model carries one solid: the grasp meshes one part, MuJoCo and the sound model
        # would weigh different ones (a shell inside a shell: 1.02 kg against 0.94 kg).
        raise MeshSeveralBodiesError(
            f"surface mesh has {n_bodies} separate closed shells (several bodies, or a shell inside another): pass "
            "one solid; keep the largest part (max(mesh.split(), key=lambda m: m.volume)) or join them with a "
            "boolean union (trimesh.boolean.union(mesh.split(), engine='manifold'))")
    thickness = min_thickness_m(surface)
    if thickness < MIN_THICKNESS_M:
        raise MeshTooThinError(
            f"surface mesh has walls {thickness * 1000:.3g} mm thin, below {MIN_THICKNESS_M * 1000} mm that the tet "
            "mesher resolves: thicken the walls or pass a larger scale=")
    return surface


def min_thickness_m(surface: trimesh.Trimesh, n_samples: int = 2000, seed: int = 0) -> float:
    """Smallest wall thickness [m] found by casting rays inward from sampled surface points.

    Only hits on an opposite wall count (its normal within 60 degrees of antiparallel): a ray
    from near a concave crease grazes the neighbouring face at a distance that is no wall.
    """
    n_faces = len(surface.faces)
    n_rays = min(n_samples, max(200, THICKNESS_RAY_FACE_PAIRS // max(n_faces, 1)))
    if n_rays < n_samples:
        log.info("wall-thickness check: %d rays instead of %d on a %d-face surface (bounded at %d ray-face pairs)",
                 n_rays, n_samples, n_faces, THICKNESS_RAY_FACE_PAIRS)
    points, face = trimesh.sample.sample_surface_even(surface, n_rays, seed=seed)
    normals = surface.face_normals[face]
    # Closer than this a ray re-hits its own face; the offset is added back to the distance.
    offset = 1e-4 * float(np.ptp(surface.vertices, axis=0).max())
    origins = points - normals * offset
    batch = max(1, _PAIRS_PER_BATCH // max(n_faces, 1))
    best = float("inf")
    for start in range(0, len(origins), batch):
        o, d = origins[start:start + batch], -normals[start:start + batch]
        hit_face, ray, loc = surface.ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
        opposite = np.einsum("ij,ij->i", surface.face_normals[hit_face], -d[ray]) < -0.5
        if opposite.any():
            best = min(best, float(np.linalg.norm(loc[opposite] - o[ray[opposite]], axis=1).min()))
    return best + offset if math.isfinite(best) else best


def estimate_p2_dof(volume_m3: float, element_size_m: float) -> int:
    """P2 dofs of a pytetwild mesh with target edge length h: regular tets would fill
    6 sqrt(2) / h^3 per volume; fTetWild makes about twice as many (it refines at the surface),
    and thin-walled parts have about 1.9 P2 nodes per tet (measured on a pytetwild mug: 16k tets, 90k dof)."""
    n_tets = 2.0 * volume_m3 * 6.0 * math.sqrt(2.0) / element_size_m**3
    return int(3 * 1.9 * n_tets) + 30


def check_dof(n_dof: int, max_dof: int | None, what: str) -> None:
    """Refuse a build beyond ``max_dof`` (None: :data:`sensors.mesh.tets.DEFAULT_MAX_DOF`, the
    one default) with a clear error."""
    limit = DEFAULT_MAX_DOF if max_dof is None else int(max_dof)
    if n_dof > limit:
        raise MeshTooLargeError(
            f"{what} needs about {n_dof:,} degrees of freedom (~{n_dof * BYTES_PER_DOF / 1e9:.1f} GB), above the limit "
            f"of {limit:,}: coarsen it (larger element_size_m / lower resolution), or pass max_dof= to allow it")


def tetrahedralize_tuned(surface: trimesh.Trimesh, element_size_m: float, kind: str = "mesh",
                         dimensions_m: dict | None = None, envelope_m: float | None = None,
                         max_dof: int | None = None, cache: bool = True, cache_dir=None,
                         progress: bool | None = None) -> TetMesh:
    """pytetwild with settings chosen for speed at P2 accuracy, cached, with progress.

    fTetWild's default optimization (80 passes to an AMIPS energy of 10) is what takes minutes
    on thin parts; P2 elements tolerate the quality of a few passes to energy 20. The envelope
    (largest distance of the output surface from the input) defaults to 2% of the element
    size, so a wall about one element thick keeps its thickness within a few percent at worst
    (and far closer on average: fTetWild snaps to the input).
    """
    envelope = 0.02 * element_size_m if envelope_m is None else envelope_m

    def settings_and_key(verts, faces):
        diag = float(np.linalg.norm(np.ptp(verts, axis=0)))
        settings = dict(edge_length_abs=float(element_size_m), epsilon=envelope / diag, stop_energy=20.0,
                        num_opt_iter=20, coarsen=False)
        return settings, cache_mod.content_key("tetwild-tuned", verts, faces, settings)

    if cache and isinstance(surface, trimesh.Trimesh):
        # Keyed by the surface as given: a hit was checked when it was built, and the check
        # (self-intersections, wall thickness: seconds on a mug) is not paid again on a load.
        _, given_key = settings_and_key(np.asarray(surface.vertices, dtype=np.float64),
                                        np.asarray(surface.faces, dtype=np.int32))
        hit = cache_mod.load_arrays(given_key, cache_dir)
        if hit is not None:
            return TetMesh(hit["vertices"], hit["tets"], kind, dict(dimensions_m or {}))
    else:
        given_key = None
    surface = check_surface(surface)
    check_dof(estimate_p2_dof(float(surface.volume), element_size_m), max_dof, f"the {kind} tet mesh")
    verts = np.asarray(surface.vertices, dtype=np.float64)
    faces = np.asarray(surface.faces, dtype=np.int32)
    settings, key = settings_and_key(verts, faces)
    if cache:
        hit = cache_mod.load_arrays(key, cache_dir)
        if hit is not None:
            if given_key is not None and given_key != key:
                cache_mod.save_arrays(given_key, hit, cache_dir)
            return TetMesh(hit["vertices"], hit["tets"], kind, dict(dimensions_m or {}))
    import pytetwild  # imports pyvista (about 1 s): only when a mesh is really built

    tv, tt = _with_progress(lambda: pytetwild.tetrahedralize(verts, faces, quiet=True, num_threads=1, **settings),
                            f"tet-meshing {kind}", progress)
    tv = np.asarray(tv, dtype=np.float64)
    used, tt = np.unique(np.asarray(tt, dtype=np.int64), return_inverse=True)
    tv = tv[used]
    tt = orient_tets(tv, tt.reshape(-1, 4))
    check_tet_quality(tv, tt)
    if cache:
        for k in {key, given_key} - {None}:
            cache_mod.save_arrays(k, {"vertices": tv, "tets": tt}, cache_dir)
    return TetMesh(tv, tt, kind, dict(dimensions_m or {}))


def _with_progress(fn, desc: str, progress: bool | None):
    """Run a blocking call with an elapsed-time bar (shown after 1 s unless progress is False)."""
    from tqdm.auto import tqdm

    done = threading.Event()
    bar = tqdm(desc=desc, unit="s", disable=progress is False, delay=0.0 if progress else 1.0, leave=False,
               bar_format="{desc}: {elapsed}")

    def tick():
        while not done.wait(0.5):
            bar.update(0)
            bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    start = time.perf_counter()
    # fTetWild leaves a debug file in the working directory: remove it unless it was there before.
    debug_file = Path.cwd() / "__tracked_surface.stl"
    had_debug_file = debug_file.exists()
    try:
        return fn()
    finally:
        done.set()
        thread.join()
        bar.close()
        if not had_debug_file:
            debug_file.unlink(missing_ok=True)
        log.info("%s took %.1f s", desc, time.perf_counter() - start)
