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

__all__ = ["CollisionGeometry", "convex_decomposition", "collision_geometry", "mass_properties"]

log = logging.getLogger(__name__)

#: CoACD settings: a concavity threshold of 5% with a shallow tree search keeps the cavities
#: of the containers and the mug's handle open with 13-32 pieces that stand 2.6 mm (mug) to 5 mm
#: (bottle, spoon) outside the solid by the one-sided Hausdorff distance of
#: benchmarks/collision_fidelity.py (docs/benchmarks/everyday_objects.md; the 2% / 100-iteration search took
#: 100-180 s for the same cavities). Our surfaces are manifold already: no remeshing
#: preprocess. Seeded.
COACD_OPTIONS = dict(threshold=0.05, max_convex_hull=32, preprocess_mode="off", resolution=1000,
                     mcts_iterations=20, mcts_nodes=10, mcts_max_depth=2, seed=0)
#: CoACD's time grows with the input's faces, and the FE surfaces are far finer than collision
#: needs (the mug's 30k faces took 10.7 s): surfaces above ``SIMPLIFY_ABOVE_FACES`` faces are
#: simplified first (manifold3d, which keeps the surface closed and moves it by at most the
#: tolerance, here ``SIMPLIFY_TOLERANCE`` times the bounding-box diagonal: 0.08 mm on the mug).
SIMPLIFY_ABOVE_FACES = 2000
SIMPLIFY_TOLERANCE = 5e-4


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


def convex_decomposition(surface: trimesh.Trimesh, cache: bool = True, cache_dir=None, **options) -> tuple[list, float]:
    """Convex pieces of a closed surface by CoACD, cached; returns (pieces, build time [s]).

    A surface above :data:`SIMPLIFY_ABOVE_FACES` faces is decomposed after :func:`simplified`
    (by :data:`SIMPLIFY_TOLERANCE` of its bounding-box diagonal)."""
    opts = {**COACD_OPTIONS, **options}
    vertices = np.ascontiguousarray(surface.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(surface.faces, dtype=np.int64)
    key = cache_mod.content_key("coacd", coacd.__version__ if hasattr(coacd, "__version__") else "coacd",
                                vertices, faces, opts, SIMPLIFY_ABOVE_FACES, SIMPLIFY_TOLERANCE)
    if cache:
        hit = cache_mod.load_arrays(key, cache_dir)
        if hit is not None:
            return np.split(hit["vertices"], hit["offsets"][1:-1]), 0.0
    start = time.perf_counter()
    if len(faces) > SIMPLIFY_ABOVE_FACES:
        diagonal_m = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
        vertices, faces = simplified(vertices, faces, SIMPLIFY_TOLERANCE * diagonal_m)
    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(vertices, faces), **opts)
    pieces = []
    for v, f in parts:
        hull = trimesh.Trimesh(np.asarray(v, float), np.asarray(f), process=True).convex_hull
        pieces.append(np.asarray(hull.vertices, float))
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
