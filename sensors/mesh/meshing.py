"""Tetrahedral meshes for the modal analysis.

Two routes:

* :func:`bar_mesh`, :func:`tube_mesh`, :func:`rod_mesh` - a deterministic structured mesher
  for a box, a hollow cylinder and a solid cylinder, main axis along x, centred at the origin.
  A 2D cross-section triangulation is extruded along x and every prism is split into three
  tetrahedra with a rule that depends only on global vertex numbers, so neighbouring prisms
  always agree on the diagonal of a shared quadrilateral face (conforming mesh).
* :func:`tetrahedralize_surface` - pytetwild (fTetWild) for any watertight ``trimesh.Trimesh``,
  with input validation, orientation fix, a tight envelope and an on-disk cache (fTetWild gives
  a different mesh on every run).

:func:`quadratic_mesh` turns a linear mesh into 10-node (P2) tetrahedra; for the structured
cylinders the mid-edge nodes of boundary edges are moved onto the exact circle (isoparametric
geometry), which removes the O(h^2) polygon error of the cross-section.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import math
import time
from pathlib import Path

import numpy as np

__all__ = [
    "MeshError",
    "TetMesh",
    "bar_mesh",
    "tube_mesh",
    "rod_mesh",
    "tetrahedralize_surface",
    "validate_surface",
    "quadratic_mesh",
    "check_tet_quality",
    "tet_volumes",
    "boundary_faces",
    "P2_EDGES",
]

log = logging.getLogger(__name__)

#: Local vertex pairs of the six edges of a tetrahedron, in VTK quadratic-tetra order
#: (mid-edge node 4 + i sits on edge P2_EDGES[i]).
P2_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])


class MeshError(ValueError):
    """The input geometry or the tetrahedral mesh is unusable; the message says why."""


@dataclasses.dataclass
class TetMesh:
    """A linear tetrahedral mesh (corner vertices only) plus what P2 needs to curve it.

    Attributes:
        vertices_m: (n, 3) vertex coordinates [m].
        tets: (m, 4) vertex indices, positively oriented.
        kind: "bar", "tube", "rod" or "mesh".
        dimensions_m: Shape parameters (e.g. length_m, width_m, ...), empty for "mesh".
        cylinder_radii_m: Radii of exact cylindrical surfaces about the x axis; mid-edge nodes
            of edges lying on them are projected onto them by :func:`quadratic_mesh`.
    """

    vertices_m: np.ndarray
    tets: np.ndarray
    kind: str = "mesh"
    dimensions_m: dict = dataclasses.field(default_factory=dict)
    cylinder_radii_m: tuple = ()

    @property
    def n_tets(self) -> int:
        return int(self.tets.shape[0])

    def volume_m3(self) -> float:
        return float(tet_volumes(self.vertices_m, self.tets).sum())

    def digest(self) -> str:
        """Content hash of the geometry (for cache keys)."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices_m, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(self.tets, dtype=np.int64).tobytes())
        h.update(repr((self.kind, sorted(self.dimensions_m.items()), tuple(self.cylinder_radii_m))).encode())
        return h.hexdigest()


# ----------------------------------------------------------------------------- geometry helpers


def tet_volumes(vertices: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes of tetrahedra (positive for right-handed vertex order) [m^3]."""
    p = vertices[tets[:, :4]]
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0


def _orient(vertices: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Swap two vertices of every negatively oriented tet (fTetWild returns them that way)."""
    tets = np.array(tets, dtype=np.int64, copy=True)
    neg = tet_volumes(vertices, tets) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2], tets[neg, 1].copy()
    return tets


def check_tet_quality(vertices: np.ndarray, tets: np.ndarray, min_quality: float = 1e-6) -> None:
    """Raise :class:`MeshError` for non-finite vertices, inverted, degenerate or disconnected tets.

    Quality is the volume relative to that of a regular tet with the same RMS edge length
    (1 for a regular tet, 0 for a flat one); below ``min_quality`` a tet is called degenerate.
    """
    vertices = np.asarray(vertices, dtype=float)
    tets = np.asarray(tets)
    if tets.ndim != 2 or tets.shape[1] < 4 or len(tets) == 0:
        raise MeshError(f"tetrahedral mesh has no tets (tets array shape {tets.shape})")
    if not np.all(np.isfinite(vertices)):
        raise MeshError(f"tetrahedral mesh has {int((~np.isfinite(vertices)).any(axis=1).sum())} non-finite vertices")
    if tets.min() < 0 or tets.max() >= len(vertices):
        raise MeshError("tetrahedral mesh references vertices that do not exist")
    vol = tet_volumes(vertices, tets)
    p = vertices[tets[:, :4]]
    edges = p[:, P2_EDGES[:, 1]] - p[:, P2_EDGES[:, 0]]
    l_rms = np.sqrt(np.mean(np.einsum("ijk,ijk->ij", edges, edges), axis=1))
    quality = vol / (l_rms**3 / (6.0 * math.sqrt(2.0)))
    n_inv = int((quality < -min_quality).sum())
    n_flat = int((np.abs(quality) <= min_quality).sum())
    if n_inv or n_flat:
        raise MeshError(
            f"tetrahedral mesh has {n_inv} inverted and {n_flat} zero-volume tets out of {len(tets)} "
            f"(worst quality {quality.min():.3g})"
        )
    import scipy.sparse.csgraph  # ~0.2 s to import: only a model build needs it

    n = len(vertices)
    t = tets[:, :4]
    rows = np.repeat(t[:, 0], 3)
    cols = t[:, 1:].ravel()
    graph = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    used = np.unique(t)
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    n_comp_used = len(np.unique(labels[used]))
    if n_comp_used != 1:
        raise MeshError(
            f"tetrahedral mesh has {n_comp_used} disconnected parts; a modal model needs one solid "
            "(each extra part adds six rigid-body modes)"
        )


def row_codes(rows: np.ndarray) -> np.ndarray | None:
    """One int64 code per row of non-negative ints (equal rows, equal codes), or None if the
    codes would overflow. np.unique on the codes is several times faster than on rows."""
    rows = np.asarray(rows, dtype=np.int64)
    n = int(rows.max()) + 1 if rows.size else 1
    if rows.ndim != 2 or n ** rows.shape[1] >= 2**63:
        return None
    codes = np.zeros(len(rows), dtype=np.int64)
    for column in rows.T:
        codes = codes * n + column
    return codes


def boundary_faces(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles of a tet mesh, oriented outward, and the tet each belongs to.

    Returns (faces (f, 3), owner_tet (f,)).
    """
    t = np.asarray(tets)[:, :4]
    # Faces opposite to vertex 0..3, ordered so the normal points away from that vertex for a
    # positively oriented tet.
    local = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    faces = t[:, local].reshape(-1, 3)
    owner = np.repeat(np.arange(len(t)), 4)
    key = np.sort(faces, axis=1)
    codes = row_codes(key)
    _, inverse, counts = (np.unique(codes, return_inverse=True, return_counts=True) if codes is not None
                          else np.unique(key, axis=0, return_inverse=True, return_counts=True))
    single = counts[inverse.ravel()] == 1
    return faces[single], owner[single]


# ----------------------------------------------------------------------------- structured meshes


def _extrude(points_yz: np.ndarray, triangles: np.ndarray, length_m: float, nx: int) -> tuple[np.ndarray, np.ndarray]:
    """Extrude a 2D (y, z) triangulation along x over [-L/2, L/2] into tets (3 per prism)."""
    p = len(points_yz)
    x = np.linspace(-0.5 * length_m, 0.5 * length_m, nx + 1)
    vertices = np.empty(((nx + 1) * p, 3))
    vertices[:, 0] = np.repeat(x, p)
    vertices[:, 1:] = np.tile(points_yz, (nx + 1, 1))
    tri = np.sort(triangles, axis=1)  # global order rule -> conforming diagonals
    layers = (np.arange(nx) * p)[:, None, None]
    b = (tri[None] + layers).reshape(-1, 3)
    t = b + p
    v0, v1, v2 = b[:, 0], b[:, 1], b[:, 2]
    w0, w1, w2 = t[:, 0], t[:, 1], t[:, 2]
    tets = np.concatenate(
        [np.stack([v0, v1, v2, w0], 1), np.stack([v1, v2, w0, w1], 1), np.stack([v2, w0, w1, w2], 1)]
    )
    return vertices, _orient(vertices, tets)


def _grid_triangles(n_u: int, n_v: int, index: np.ndarray) -> np.ndarray:
    """Split the quads of a structured (n_u x n_v cells) grid into triangles; index[i, j] -> point."""
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="ij")
    a, b = index[i, j], index[i + 1, j]
    c, d = index[i + 1, j + 1], index[i, j + 1]
    # Alternate the diagonal in a checkerboard so the cross-section has no preferred direction.
    flip = ((i + j) % 2).astype(bool)
    t1 = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1))
    t2 = np.where(flip[..., None], np.stack([b, c, d], -1), np.stack([a, c, d], -1))
    return np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])


def _check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value > 0):
            raise MeshError(f"{name} must be a finite positive number, got {value!r}")


#: Default limit on the degrees of freedom of a P2 model (3 per node): about 1 GB for K and M
#: and several times that for the eigensolver, tens of minutes on two cores. ``max_dof=``
#: raises it (or ``None`` removes it).
DEFAULT_MAX_DOF = 300_000
#: P2 degrees of freedom per vertex of a linear tet mesh (a vertex has about six edges, each
#: carrying a mid-edge node: 3 (1 + 6) ~ 20; measured 18-22 on the project's meshes).
P2_DOF_PER_VERTEX = 20


def check_size(n_vertices: int, max_dof: int | None, what: str) -> None:
    """Refuse, before building it, a mesh whose P2 model would exceed ``max_dof``."""
    dof = P2_DOF_PER_VERTEX * int(n_vertices)
    if max_dof is not None and dof > max_dof:
        gb = dof * 90 * 2 * 12 / 1e9      # ~90 nonzeros per row of K and of M, 12 bytes each
        raise MeshError(f"{what} would have about {dof:,} degrees of freedom (limit {max_dof:,}; K and M "
                        f"alone ~{gb:.1f} GB, the eigensolver several times that): coarsen it with "
                        "element_size_m= or a smaller resolution=, or raise the limit with max_dof=")


def _divisions(extent: float, h: float, minimum: int) -> int:
    return max(minimum, int(math.ceil(extent / h - 1e-9)))


def bar_mesh(length_m: float, width_m: float, height_m: float, element_size_m: float | None = None,
             resolution: float = 1.0, max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Structured tet mesh of a box: length along x, width along y, height along z.

    Args:
        element_size_m: Target edge length [m]; default: a quarter of the smaller
            cross-section side divided by ``resolution`` (4 P2 elements across: torsion and
            the higher bending modes of a 25 mm ABS bar below 10 kHz within 1%).
        resolution: Multiplies the number of elements in every direction.
        max_dof: refuse (``MeshError``) a mesh whose P2 model would be larger (see
            :func:`check_size`).
    """
    _check_positive(length_m=length_m, width_m=width_m, height_m=height_m, resolution=resolution)
    h = element_size_m if element_size_m is not None else min(width_m, height_m) / 4.0
    _check_positive(element_size_m=h)
    h = h / resolution
    ny, nz = _divisions(width_m, h, 2), _divisions(height_m, h, 2)
    nx = _divisions(length_m, h * 1.5, 4)  # P2 tolerates elongated cells along the beam axis
    check_size((ny + 1) * (nz + 1) * (nx + 1), max_dof, f"a {length_m:g} x {width_m:g} x {height_m:g} m bar mesh")
    y = np.linspace(-0.5 * width_m, 0.5 * width_m, ny + 1)
    z = np.linspace(-0.5 * height_m, 0.5 * height_m, nz + 1)
    yy, zz = np.meshgrid(y, z, indexing="ij")
    points = np.stack([yy.ravel(), zz.ravel()], 1)
    index = np.arange(len(points)).reshape(ny + 1, nz + 1)
    vertices, tets = _extrude(points, _grid_triangles(ny, nz, index), length_m, nx)
    return TetMesh(vertices, tets, "bar", {"length_m": float(length_m), "width_m": float(width_m),
                                           "height_m": float(height_m)})


def tube_mesh(length_m: float, outer_radius_m: float, inner_radius_m: float,
              element_size_m: float | None = None, resolution: float = 1.0,
              max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Structured tet mesh of a hollow cylinder along x (annulus cross-section).

    Default: 24 elements around (curved P2 edges make that accurate), 1 through a thin wall,
    elements along x 2.5 times as long as they are wide; ``resolution`` scales all counts.
    """
    _check_positive(length_m=length_m, outer_radius_m=outer_radius_m, inner_radius_m=inner_radius_m,
                    resolution=resolution)
    if inner_radius_m >= outer_radius_m:
        raise MeshError(f"inner_radius_m ({inner_radius_m}) must be smaller than outer_radius_m ({outer_radius_m})")
    wall = outer_radius_m - inner_radius_m
    if element_size_m is None:
        n_theta = 4 * max(2, int(round(6 * resolution)))
        n_r = max(1, int(math.ceil(wall / (2 * math.pi * outer_radius_m / n_theta) * 0.75 - 1e-9)))
        h_x = 2 * math.pi * outer_radius_m / n_theta * 2.5  # P2 beam modes tolerate long cells
    else:
        _check_positive(element_size_m=element_size_m)
        h = element_size_m / resolution
        n_theta = 4 * max(2, int(math.ceil(2 * math.pi * outer_radius_m / h / 4 - 1e-9)))
        n_r = _divisions(wall, h, 1)
        h_x = 1.5 * h
    # Curving the P2 edges onto the circle moves mid-nodes by the sagitta r (pi/n)^2 / 2; keep
    # it below 1/8 of the wall or thin-walled elements invert.
    n_min = 4 * int(math.ceil(2 * math.pi * math.sqrt(outer_radius_m / wall) / 4))
    if n_theta < n_min:
        n_theta = n_min
        h_x = max(h_x, 2 * math.pi * outer_radius_m / n_theta * 3.0)
    nx = _divisions(length_m, h_x, 4)
    check_size((n_r + 1) * n_theta * (nx + 1), max_dof,
               f"a {length_m:g} m tube mesh (radii {outer_radius_m:g} / {inner_radius_m:g} m)")
    theta = 2 * math.pi * np.arange(n_theta) / n_theta
    r = np.linspace(inner_radius_m, outer_radius_m, n_r + 1)
    rr, tt = np.meshgrid(r, theta, indexing="ij")
    points = np.stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()], 1)
    index = np.arange(len(points)).reshape(n_r + 1, n_theta)
    index = np.concatenate([index, index[:, :1]], axis=1)  # periodic in theta
    vertices, tets = _extrude(points, _grid_triangles(n_r, n_theta, index), length_m, nx)
    return TetMesh(vertices, tets, "tube",
                   {"length_m": float(length_m), "outer_radius_m": float(outer_radius_m),
                    "inner_radius_m": float(inner_radius_m)},
                   (float(inner_radius_m), float(outer_radius_m)))


def rod_mesh(length_m: float, radius_m: float, element_size_m: float | None = None,
             resolution: float = 1.0, max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Structured tet mesh of a solid cylinder along x (O-grid: square core plus a ring)."""
    _check_positive(length_m=length_m, radius_m=radius_m, resolution=resolution)
    if element_size_m is None:
        m = 2 * max(1, int(round(2 * resolution)))  # core cells per side (even: symmetric)
    else:
        _check_positive(element_size_m=element_size_m)
        m = 2 * max(1, int(math.ceil(radius_m / (element_size_m / resolution) / 2 - 1e-9)))
    n_theta = 4 * m
    s = 0.5 * radius_m  # half-width of the square core
    n_ring = max(1, int(round((radius_m - s) / (2 * s / m))))
    check_size(((m + 1) ** 2 + n_ring * n_theta) * (_divisions(length_m, 2 * s / m * 1.5, 4) + 1), max_dof,
               f"a {length_m:g} m rod mesh (radius {radius_m:g} m)")
    # Core grid.
    c = np.linspace(-s, s, m + 1)
    cy, cz = np.meshgrid(c, c, indexing="ij")
    core = np.stack([cy.ravel(), cz.ravel()], 1)
    core_index = np.arange(len(core)).reshape(m + 1, m + 1)
    # Square boundary walked counter-clockwise from corner (s, -s), matching circle angles.
    k = np.arange(m)
    ring0 = np.concatenate([
        core_index[m, k], core_index[m - k, m], core_index[0, m - k], core_index[k, 0]])
    theta = -math.pi / 4 + 2 * math.pi * np.arange(n_theta) / n_theta
    circle = radius_m * np.stack([np.cos(theta), np.sin(theta)], 1)
    points = [core]
    ring_index = [ring0]
    square = core[ring0]
    for layer in range(1, n_ring + 1):
        t = layer / n_ring
        pts = (1 - t) * square + t * circle
        start = sum(len(p) for p in points)
        points.append(pts)
        ring_index.append(start + np.arange(n_theta))
    points = np.concatenate(points)
    ring = np.stack(ring_index)  # (n_ring + 1, n_theta)
    ring = np.concatenate([ring, ring[:, :1]], axis=1)
    tris = np.concatenate([_grid_triangles(m, m, core_index), _grid_triangles(n_ring, n_theta, ring)])
    vertices, tets = _extrude(points, tris, length_m, _divisions(length_m, 2 * s / m * 1.5, 4))
    return TetMesh(vertices, tets, "rod", {"length_m": float(length_m), "radius_m": float(radius_m)},
                   (float(radius_m),))


# ----------------------------------------------------------------------------- quadratic elements


def quadratic_mesh(mesh: TetMesh) -> tuple[np.ndarray, np.ndarray]:
    """10-node tets (VTK order: 4 corners, then mid-edge nodes of :data:`P2_EDGES`).

    Returns (nodes (n, 3), tets10 (m, 10)); the first ``len(mesh.vertices_m)`` nodes are the
    corner vertices. Mid-edge nodes of edges lying on one of ``mesh.cylinder_radii_m`` are
    projected radially onto that cylinder.
    """
    v, t = mesh.vertices_m, mesh.tets
    edges = np.sort(t[:, P2_EDGES].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = 0.5 * (v[unique[:, 0]] + v[unique[:, 1]])
    if mesh.cylinder_radii_m:
        r_v = np.hypot(v[:, 1], v[:, 2])
        for radius in mesh.cylinder_radii_m:
            on = np.abs(r_v - radius) <= 1e-9 * radius
            both = on[unique[:, 0]] & on[unique[:, 1]]
            r_mid = np.hypot(mid[both, 1], mid[both, 2])
            mid[both, 1:] *= (radius / r_mid)[:, None]
    nodes = np.concatenate([v, mid])
    tets10 = np.concatenate([t, len(v) + inverse.reshape(-1, 6)], axis=1)
    return nodes, tets10


# ----------------------------------------------------------------------------- arbitrary surfaces


def _segment_triangle_hits(p0, p1, a, b, c, eps=1e-12):
    """Vectorized test: does segment p0-p1 cross the interior of triangle abc (Moller-Trumbore)."""
    d = p1 - p0
    e1, e2 = b - a, c - a
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(d, axis=1)
    ok = np.abs(det) > eps * scale
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = p0 - a
    u = np.einsum("ij,ij->i", s, pv) * inv
    q = np.cross(s, e1)
    w = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    tol = 1e-9
    return ok & (u > tol) & (w > tol) & (u + w < 1 - tol) & (t > tol) & (t < 1 - tol)


def _self_intersections(vertices: np.ndarray, faces: np.ndarray, max_pairs: int = 5_000_000) -> int:
    """Count pairs of non-adjacent triangles whose edges cross each other (0 if clean)."""
    from scipy.spatial import cKDTree

    tri = vertices[faces]
    centre = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centre[:, None], axis=2).max(axis=1)
    tree = cKDTree(centre)
    pairs = tree.query_pairs(2.0 * radius.max() + 1e-12, output_type="ndarray")
    if len(pairs) > max_pairs:
        log.warning("self-intersection check skipped: %d candidate triangle pairs", len(pairs))
        return 0
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(centre[i] - centre[j], axis=1) <= radius[i] + radius[j]
    i, j = i[near], j[near]
    shared = (faces[i][:, :, None] == faces[j][:, None, :]).any(axis=(1, 2))
    i, j = i[~shared], j[~shared]
    hit = np.zeros(len(i), dtype=bool)
    for (x, y) in ((i, j), (j, i)):
        for k0, k1 in ((0, 1), (1, 2), (2, 0)):
            hit |= _segment_triangle_hits(vertices[faces[x, k0]], vertices[faces[x, k1]],
                                          vertices[faces[y, 0]], vertices[faces[y, 1]], vertices[faces[y, 2]])
    return int(hit.sum())


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
    n_cross = _self_intersections(np.asarray(mesh.vertices), np.asarray(mesh.faces))
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
    _check_positive(element_size_m=element_size_m, resolution=resolution)
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
    tt = _orient(tv, tt)
    check_tet_quality(tv, tt)
    out_lo, out_hi = tv.min(axis=0), tv.max(axis=0)
    dev = float(np.max(np.maximum(np.abs(out_lo - lo), np.abs(out_hi - hi)) / np.maximum(extents, 1e-300)))
    if dev > 1e-3:
        log.warning("pytetwild changed the bounding box by %.3g%% of an extent", 100 * dev)
    log.info("pytetwild: %d tets in %.1f s", len(tt), time.perf_counter() - start)
    if cache:
        cache_mod.save_arrays(key, {"vertices": tv, "tets": tt}, cache_dir)
    return TetMesh(tv, tt, "mesh", {})
