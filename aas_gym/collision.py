"""MuJoCo collision geometry and inertia of a solid given by its closed surface.

Collision: a convex decomposition by CoACD (approximate convex decomposition with a
collision-aware concavity metric), cached on disk content-addressed like the modal models
(:mod:`sensors._infra.cache`), as convex pieces ready for MJCF ``<mesh vertex="...">`` assets
(MuJoCo takes the convex hull of each mesh asset's vertices for collision).

Mass and inertia come from the solid itself (trimesh's exact polyhedral integrals) with the
material density, not from the pieces, whose union over-covers concave regions.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import coacd
import numpy as np
import trimesh

from sensors._infra import cache as cache_mod
from sensors.materials.solids import get_material

__all__ = ["CollisionGeometry", "convex_decomposition", "decompose", "mirror_planes", "collision_geometry",
           "mass_properties"]

log = logging.getLogger(__name__)

#: CoACD settings: a concavity threshold of 3% with a shallow tree search keeps the cavities
#: of the containers and the mug's handle open with 2-48 pieces that stand 0.02 mm (bracket) to 3.5 mm
#: (bottle; box 0.2 mm, spoon 3.3 mm) outside the solid by the one-sided Hausdorff distance of
#: benchmarks/collision_fidelity.py (docs/benchmarks/everyday_objects.md; the 2% / 100-iteration search took
#: 100-180 s for the same cavities). ``max_convex_hull`` bounds the whole object's pieces (a
#: mirrored part gets its share, see :func:`decompose`); 500 samples for the concavity measure
#: (1000 before) took the whole can's CoACD from 6.6 to 4.5 s. Our surfaces are manifold already: no
#: remeshing preprocess. Seeded.
COACD_OPTIONS = dict(threshold=0.03, max_convex_hull=48, preprocess_mode="off", resolution=500,
                     mcts_iterations=20, mcts_nodes=10, mcts_max_depth=2, seed=0)
#: CoACD's time grows with the input's faces, and the FE surfaces are far finer than collision
#: needs (the mug's 30k faces took 10.7 s): surfaces above ``SIMPLIFY_ABOVE_FACES`` faces are
#: simplified first (manifold3d, which keeps the surface closed and moves it by at most the
#: tolerance, here ``SIMPLIFY_TOLERANCE`` times the bounding-box diagonal: 0.08 mm on the mug).
SIMPLIFY_ABOVE_FACES = 2000
SIMPLIFY_TOLERANCE = 5e-4
#: A mirror plane is taken when the mirrored vertices land within this fraction of the bounding-box
#: diagonal of a vertex and the mirrored solid differs from the solid by at most
#: ``MIRROR_VOLUME_TOLERANCE`` of its volume (a non-planar quad triangulated one way only, as on the
#: spoon's bowl, breaks the symmetry of the solid though not of its vertices).
MIRROR_VERTEX_TOLERANCE = 1e-9
MIRROR_VOLUME_TOLERANCE = 1e-6
#: A piece and its mirror image become one piece when the hull of the two exceeds their union by at
#: most this fraction of the union's volume (a floor quarter and its image: a half floor); fewer
#: pieces, fewer contacts with the table.
MIRROR_MERGE_TOLERANCE = 1e-4


@dataclasses.dataclass(frozen=True)
class CollisionGeometry:
    """Convex collision pieces plus the solid's rigid-body properties, in the object frame.

    Attributes:
        pieces: list of (k_i, 3) vertex arrays [m], each the vertices of a convex hull.
        mass_kg: Mass of the solid.
        center_of_mass_m: (3,) centre of mass.
        inertia_kg_m2: (3, 3) inertia tensor about the centre of mass, object axes.
        build_time_s: Time of the decomposition (0 for a cache hit).
    """

    pieces: list
    mass_kg: float
    center_of_mass_m: np.ndarray
    inertia_kg_m2: np.ndarray
    build_time_s: float = 0.0

    def mjcf_mesh_vertices(self) -> list[str]:
        """Each piece's vertices as the space-separated string of an MJCF ``<mesh vertex=>``."""
        return [" ".join(f"{v:.9g}" for v in piece.ravel()) for piece in self.pieces]

    def to_dict(self) -> dict:
        """JSON-friendly form."""
        return {"pieces": [p.tolist() for p in self.pieces], "mass_kg": self.mass_kg,
                "center_of_mass_m": self.center_of_mass_m.tolist(), "inertia_kg_m2": self.inertia_kg_m2.tolist()}


def mass_properties(surface: trimesh.Trimesh, density_kg_m3: float):
    """(mass [kg], centre of mass (3,), inertia about it (3, 3)) of the closed solid."""
    mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False)
    mesh.density = float(density_kg_m3)
    return float(mesh.mass), np.asarray(mesh.center_mass, float), np.asarray(mesh.moment_inertia, float)


def simplified(vertices: np.ndarray, faces: np.ndarray, tolerance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed surface with fewer faces, within ``tolerance_m`` of the input (manifold3d's
    edge-collapse simplification; the input must be a closed manifold)."""
    import manifold3d

    mesh = manifold3d.Mesh(vert_properties=np.asarray(vertices, np.float32), tri_verts=np.asarray(faces, np.uint32))
    out = manifold3d.Manifold(mesh).simplify(float(tolerance_m)).to_mesh()
    return (np.ascontiguousarray(out.vert_properties[:, :3], dtype=np.float64),
            np.ascontiguousarray(out.tri_verts, dtype=np.int64))


#: This module's code in the decomposition's cache key: pieces cached by an earlier decomposition
#: (other settings, no mirror planes) are never served for the current one.
_DECOMPOSITION_VERSION = cache_mod.source_version("aas_gym.collision")


def _manifold(vertices: np.ndarray, faces: np.ndarray):
    import manifold3d

    return manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(vertices, np.float32),
                                               tri_verts=np.asarray(faces, np.uint32)))


def mirror_planes(vertices: np.ndarray, faces: np.ndarray) -> list[tuple[int, float]]:
    """The solid's mirror planes among the three through its bounding-box centre normal to the
    object axes, as (axis, offset [m]): the plane ``x[axis] = offset``.

    A plane counts when the mirrored vertices coincide with vertices (within
    :data:`MIRROR_VERTEX_TOLERANCE` of the diagonal) and the mirrored solid with the solid (within
    :data:`MIRROR_VOLUME_TOLERANCE` of its volume, by an exact boolean)."""
    from scipy.spatial import cKDTree

    vertices, faces = np.asarray(vertices, float), np.asarray(faces, np.int64)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    diagonal_m = float(np.linalg.norm(hi - lo))
    tree, solid = cKDTree(vertices), None
    planes = []
    for axis in range(3):
        offset = 0.5 * float(lo[axis] + hi[axis])
        mirrored = vertices.copy()
        mirrored[:, axis] = 2.0 * offset - mirrored[:, axis]
        if tree.query(mirrored)[0].max() > MIRROR_VERTEX_TOLERANCE * diagonal_m:
            continue
        solid = solid if solid is not None else _manifold(vertices, faces)
        image = _manifold(mirrored, faces[:, ::-1])  # a mirror turns the winding inside out
        if abs((solid - image).volume()) <= MIRROR_VOLUME_TOLERANCE * solid.volume():
            planes.append((axis, offset))
    return planes


def decompose(vertices: np.ndarray, faces: np.ndarray, options: dict | None = None,
              simplify_tolerance: float = SIMPLIFY_TOLERANCE, symmetric: bool = True) -> list[np.ndarray]:
    """Convex pieces of a closed surface by CoACD (uncached): the vertices of each piece's hull.

    With ``symmetric``, CoACD decomposes only the part of the solid on one side of each of its
    :func:`mirror_planes` (a half or a quarter: a quarter of a can took 1.4 s where the whole
    took 6.8 s, with less extra volume, ``docs/benchmarks/everyday_objects.md``) and the pieces are
    mirrored back (a piece that is convex with its image joined with it); the part gets ``max_convex_hull`` over the number of copies. A part above
    :data:`SIMPLIFY_ABOVE_FACES` faces is first :func:`simplified` by ``simplify_tolerance`` of the
    whole solid's bounding-box diagonal. ``options`` override :data:`COACD_OPTIONS`."""
    opts = {**COACD_OPTIONS, **(options or {})}
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    diagonal_m = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    planes = mirror_planes(vertices, faces) if symmetric else []
    if planes:
        part = _manifold(vertices, faces)
        for axis, offset in planes:
            part = part.trim_by_plane(np.eye(3)[axis], offset)  # keeps the side x[axis] >= offset
        mesh = part.to_mesh()
        vertices = np.ascontiguousarray(mesh.vert_properties[:, :3], dtype=np.float64)
        faces = np.ascontiguousarray(mesh.tri_verts, dtype=np.int64)
        if opts["max_convex_hull"] > 0:
            opts["max_convex_hull"] = max(1, opts["max_convex_hull"] // 2 ** len(planes))
    if len(faces) > SIMPLIFY_ABOVE_FACES:
        vertices, faces = simplified(vertices, faces, simplify_tolerance * diagonal_m)
    coacd.set_log_level("error")
    pieces = [np.asarray(trimesh.Trimesh(np.asarray(v, float), np.asarray(f), process=True).convex_hull.vertices, float)
              for v, f in coacd.run_coacd(coacd.Mesh(vertices, faces), **opts)]
    for axis, offset in planes:
        pieces = _with_mirror_images(pieces, axis, offset)
    return pieces


def _with_mirror_images(pieces: list[np.ndarray], axis: int, offset: float) -> list[np.ndarray]:
    """The pieces and their images in the plane ``x[axis] = offset``; a piece whose union with its
    image is convex (within :data:`MIRROR_MERGE_TOLERANCE`) is joined with it into one piece."""
    import manifold3d

    joined, images = [], []
    for piece in pieces:
        image = piece.copy()
        image[:, axis] = 2.0 * offset - image[:, axis]
        both = np.vstack([piece, image])
        union_m3 = (manifold3d.Manifold.hull_points(piece.astype(np.float32))
                    + manifold3d.Manifold.hull_points(image.astype(np.float32))).volume()
        if manifold3d.Manifold.hull_points(both.astype(np.float32)).volume() <= (1.0 + MIRROR_MERGE_TOLERANCE) * union_m3:
            hull = trimesh.Trimesh(both).convex_hull
            joined.append(np.asarray(hull.vertices, float))
        else:
            joined.append(piece)
            images.append(image)
    return joined + images


def convex_decomposition(surface: trimesh.Trimesh, cache: bool = True, cache_dir=None, **options) -> tuple[list, float]:
    """Convex pieces of a closed surface by CoACD (:func:`decompose` with its defaults and
    ``options`` over :data:`COACD_OPTIONS`), cached; returns (pieces, build time [s])."""
    opts = {**COACD_OPTIONS, **options}
    vertices = np.ascontiguousarray(surface.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(surface.faces, dtype=np.int64)
    # This module's code is the decomposition's (_DECOMPOSITION_VERSION); the FE modules' code
    # version plays no part: an FE edit keeps every decomposition, and in a cold object build
    # CoACD's thread does not parse those modules too (aas_gym.object_build).
    key = cache_mod.content_key("coacd", coacd.__version__ if hasattr(coacd, "__version__") else "coacd",
                                _DECOMPOSITION_VERSION, vertices, faces, opts, SIMPLIFY_ABOVE_FACES,
                                SIMPLIFY_TOLERANCE, MIRROR_VERTEX_TOLERANCE, MIRROR_VOLUME_TOLERANCE, code=False)
    if cache:
        hit = cache_mod.load_arrays(key, cache_dir)
        if hit is not None:
            return np.split(hit["vertices"], hit["offsets"][1:-1]), 0.0
    start = time.perf_counter()
    pieces = decompose(vertices, faces, opts)
    elapsed = time.perf_counter() - start
    log.info("CoACD: %d pieces in %.1f s", len(pieces), elapsed)
    if cache:
        offsets = np.cumsum([0] + [len(p) for p in pieces])
        cache_mod.save_arrays(key, {"vertices": np.concatenate(pieces), "offsets": offsets}, cache_dir)
    return pieces, elapsed


def collision_geometry(surface: trimesh.Trimesh, material, cache: bool = True, cache_dir=None,
                       **options) -> CollisionGeometry:
    """Convex pieces (cached CoACD) and mass properties of a closed surface in a material.

    The surface should already have passed :func:`sensors.mesh.surface.check_surface`.
    """
    material = get_material(material)
    pieces, elapsed = convex_decomposition(surface, cache=cache, cache_dir=cache_dir, **options)
    mass, com, inertia = mass_properties(surface, material.density_kg_m3)
    return CollisionGeometry(pieces, mass, com, inertia, elapsed)
