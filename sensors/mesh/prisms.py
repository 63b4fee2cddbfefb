"""Structured tet meshes of prisms: :func:`bar_mesh`, :func:`tube_mesh`, :func:`rod_mesh`.

A box, a hollow cylinder and a solid cylinder, main axis along x, centred at the origin. A 2D
cross-section triangulation is extruded along x and every prism is split into three
tetrahedra with a rule that depends only on global vertex numbers, so neighbouring prisms
always agree on the diagonal of a shared quadrilateral face (conforming mesh). The same
extrusion (:func:`extrude_to_tets`) sweeps the layered everyday shapes (:mod:`.layered`).
"""

from __future__ import annotations

import math

import numpy as np

from .tets import DEFAULT_MAX_DOF, MeshError, TetMesh, check_positive, check_size, orient_tets

__all__ = ["extrude_to_tets", "grid_triangles", "bar_mesh", "tube_mesh", "rod_mesh"]


def extrude_to_tets(points_yz: np.ndarray, triangles: np.ndarray, length_m: float,
                    nx: int, split_rank: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Extrude a 2D (y, z) triangulation along x over [-L/2, L/2] into tets (3 per prism).

    Returns (vertices (n, 3), tets (m, 4)), positively oriented. Vertices are stored layer by
    layer, the ``len(points_yz)`` of the layer at x = -L/2 first. Each prism is split by the
    order of its template points (a quadrilateral face's diagonal joins the bottom of the higher
    point to the top of the lower), so prisms sharing a quadrilateral face agree on its diagonal
    (the mesh is conforming). The order is ``split_rank`` (distinct integers per template point,
    e.g. a mirror-invariant one: :func:`sensors.mesh.layered.mirror_split_rank`), by default the
    point numbers.
    """
    p = len(points_yz)
    x = np.linspace(-0.5 * length_m, 0.5 * length_m, nx + 1)
    vertices = np.empty(((nx + 1) * p, 3))
    vertices[:, 0] = np.repeat(x, p)
    vertices[:, 1:] = np.tile(points_yz, (nx + 1, 1))
    triangles = np.asarray(triangles)
    if split_rank is None:
        tri = np.sort(triangles, axis=1)  # global order rule -> conforming diagonals
    else:
        tri = np.take_along_axis(triangles, np.argsort(np.asarray(split_rank)[triangles], axis=1), axis=1)
    layers = (np.arange(nx) * p)[:, None, None]
    b = (tri[None] + layers).reshape(-1, 3)
    t = b + p
    v0, v1, v2 = b[:, 0], b[:, 1], b[:, 2]
    w0, w1, w2 = t[:, 0], t[:, 1], t[:, 2]
    tets = np.concatenate(
        [np.stack([v0, v1, v2, w0], 1), np.stack([v1, v2, w0, w1], 1), np.stack([v2, w0, w1, w2], 1)]
    )
    return vertices, orient_tets(vertices, tets)


def grid_triangles(n_u: int, n_v: int, index: np.ndarray) -> np.ndarray:
    """Split the quads of a structured (n_u x n_v cells) grid into triangles; index[i, j] -> point."""
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="ij")
    a, b = index[i, j], index[i + 1, j]
    c, d = index[i + 1, j + 1], index[i, j + 1]
    # Alternate the diagonal in a checkerboard so the cross-section has no preferred direction.
    flip = ((i + j) % 2).astype(bool)
    t1 = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1))
    t2 = np.where(flip[..., None], np.stack([b, c, d], -1), np.stack([a, c, d], -1))
    return np.concatenate([t1.reshape(-1, 3), t2.reshape(-1, 3)])


def _divisions(extent: float, h: float, minimum: int) -> int:
    # Capped (the size guard refuses it then): extent / h can overflow to inf.
    return max(minimum, int(math.ceil(min(extent / h, 1e15) - 1e-9)))


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
    check_positive(length_m=length_m, width_m=width_m, height_m=height_m, resolution=resolution)
    h = element_size_m if element_size_m is not None else min(width_m, height_m) / 4.0
    check_positive(element_size_m=h)
    h = h / resolution
    ny, nz = _divisions(width_m, h, 2), _divisions(height_m, h, 2)
    nx = _divisions(length_m, h * 1.5, 4)  # P2 tolerates elongated cells along the beam axis
    check_size((ny + 1) * (nz + 1) * (nx + 1), max_dof, f"a {length_m:g} x {width_m:g} x {height_m:g} m bar mesh")
    y = np.linspace(-0.5 * width_m, 0.5 * width_m, ny + 1)
    z = np.linspace(-0.5 * height_m, 0.5 * height_m, nz + 1)
    yy, zz = np.meshgrid(y, z, indexing="ij")
    points = np.stack([yy.ravel(), zz.ravel()], 1)
    index = np.arange(len(points)).reshape(ny + 1, nz + 1)
    vertices, tets = extrude_to_tets(points, grid_triangles(ny, nz, index), length_m, nx)
    return TetMesh(vertices, tets, "bar", {"length_m": float(length_m), "width_m": float(width_m),
                                           "height_m": float(height_m)})


def tube_mesh(length_m: float, outer_radius_m: float, inner_radius_m: float,
              element_size_m: float | None = None, resolution: float = 1.0,
              max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Structured tet mesh of a hollow cylinder along x (annulus cross-section).

    Default: 24 elements around (curved P2 edges make that accurate), 1 through a thin wall,
    elements along x 2.5 times as long as they are wide; ``resolution`` scales all counts.
    """
    check_positive(length_m=length_m, outer_radius_m=outer_radius_m, inner_radius_m=inner_radius_m,
                    resolution=resolution)
    if inner_radius_m >= outer_radius_m:
        raise MeshError(f"inner_radius_m ({inner_radius_m}) must be smaller than outer_radius_m ({outer_radius_m})")
    wall = outer_radius_m - inner_radius_m
    if element_size_m is None:
        n_theta = 4 * max(2, int(round(6 * resolution)))
        n_r = max(1, int(math.ceil(wall / (2 * math.pi * outer_radius_m / n_theta) * 0.75 - 1e-9)))
        h_x = 2 * math.pi * outer_radius_m / n_theta * 2.5  # P2 beam modes tolerate long cells
    else:
        check_positive(element_size_m=element_size_m)
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
    vertices, tets = extrude_to_tets(points, grid_triangles(n_r, n_theta, index), length_m, nx)
    return TetMesh(vertices, tets, "tube",
                   {"length_m": float(length_m), "outer_radius_m": float(outer_radius_m),
                    "inner_radius_m": float(inner_radius_m)},
                   (float(inner_radius_m), float(outer_radius_m)))


def rod_mesh(length_m: float, radius_m: float, element_size_m: float | None = None,
             resolution: float = 1.0, max_dof: int | None = DEFAULT_MAX_DOF) -> TetMesh:
    """Structured tet mesh of a solid cylinder along x (O-grid: square core plus a ring)."""
    check_positive(length_m=length_m, radius_m=radius_m, resolution=resolution)
    if element_size_m is None:
        m = 2 * max(1, int(round(2 * resolution)))  # core cells per side (even: symmetric)
    else:
        check_positive(element_size_m=element_size_m)
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
    tris = np.concatenate([grid_triangles(m, m, core_index), grid_triangles(n_ring, n_theta, ring)])
    vertices, tets = extrude_to_tets(points, tris, length_m, _divisions(length_m, 2 * s / m * 1.5, 4))
    return TetMesh(vertices, tets, "rod", {"length_m": float(length_m), "radius_m": float(radius_m)},
                   (float(radius_m),))
