"""Structured tet mesh of a cylindrical cup (flat bottom, open top) and the disc section it uses.

The cup's axis is x (like the project's tubes, so :func:`sensors.meshing.quadratic_mesh` curves
its P2 edges onto the exact cylinders); the outer bottom face is at x = 0 and the rim at
x = height. A disc cross-section (square core plus rings up to the inner radius, then the wall
rings) is extruded along x; the prisms of the cavity are left out. Because the cavity is a
subset of one conforming extrusion, :func:`cup_mesh` can also return the cavity tets, which
gives a wall + liquid mesh that conforms on the wetted surface (used by the coupled
reference solve in the tests).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .meshing import MeshError, TetMesh, _check_positive, _extrude, _grid_triangles, _orient

__all__ = ["disc_section", "cup_mesh", "CupMesh"]


def disc_section(inner_radius_m: float, n_theta: int, outer_radius_m: float | None = None, n_wall: int = 0):
    """Triangulated disc of ``inner_radius_m`` (O-grid), optionally with wall rings out to ``outer_radius_m``.

    Returns (points (p, 2), triangles (t, 3), wall (t,) bool: the triangle lies in the wall
    annulus). ``n_theta`` must be a multiple of 4; the square core has n_theta / 4 cells a side.
    """
    if n_theta % 4 or n_theta < 8:
        raise MeshError(f"n_theta must be a multiple of 4 and at least 8, got {n_theta}")
    m = n_theta // 4
    s = 0.5 * inner_radius_m
    n_ring = max(1, int(round((inner_radius_m - s) / (2 * s / m))))
    c = np.linspace(-s, s, m + 1)
    cy, cz = np.meshgrid(c, c, indexing="ij")
    core = np.stack([cy.ravel(), cz.ravel()], 1)
    core_index = np.arange(len(core)).reshape(m + 1, m + 1)
    k = np.arange(m)
    ring0 = np.concatenate([core_index[m, k], core_index[m - k, m], core_index[0, m - k], core_index[k, 0]])
    theta = -math.pi / 4 + 2 * math.pi * np.arange(n_theta) / n_theta
    unit = np.stack([np.cos(theta), np.sin(theta)], 1)
    square = core[ring0]
    radii = []
    points, rings = [core], [ring0]
    for layer in range(1, n_ring + 1):
        t = layer / n_ring
        points.append((1 - t) * square + t * inner_radius_m * unit)
    if n_wall:
        for r in np.linspace(inner_radius_m, outer_radius_m, n_wall + 1)[1:]:
            points.append(r * unit)
            radii.append(r)
    start = len(core)
    for pts in points[1:]:
        rings.append(start + np.arange(n_theta))
        start += n_theta
    points = np.concatenate(points)
    ring = np.stack(rings)
    ring = np.concatenate([ring, ring[:, :1]], axis=1)  # periodic in theta
    core_tris = _grid_triangles(m, m, core_index)
    ring_tris = _grid_triangles(n_ring + n_wall, n_theta, ring)
    tris = np.concatenate([core_tris, ring_tris])
    wall = np.zeros(len(tris), dtype=bool)
    if n_wall:
        # _grid_triangles emits the first triangle of every cell, then the second; cell (i, j)
        # with i >= n_ring lies in the wall.
        i = np.repeat(np.arange(n_ring + n_wall), n_theta)
        wall[len(core_tris):] = np.concatenate([i >= n_ring, i >= n_ring])
    return points, tris, wall


@dataclasses.dataclass
class CupMesh:
    """A cup's wall mesh plus the cavity tets of the same extrusion (conforming on the wet surface).

    Attributes:
        wall: The solid cup as a :class:`~sensors.meshing.TetMesh` (kind "cup").
        cavity_tets: (c, 4) tets filling the cavity, indices into ``wall.vertices_m`` extended by
            ``cavity_vertices_m``.
        cavity_vertices_m: Vertices used only by cavity tets (appended after the wall's).
        levels_m: The x coordinates of the extrusion layers (cavity tets fill between them).
    """

    wall: TetMesh
    cavity_tets: np.ndarray
    cavity_vertices_m: np.ndarray
    levels_m: np.ndarray


def cup_mesh(height_m: float, outer_radius_m: float, wall_thickness_m: float, bottom_thickness_m: float,
             n_theta: int | None = None, n_wall: int = 1, element_height_m: float | None = None,
             extra_levels_m=()) -> CupMesh:
    """Structured mesh of a cylindrical cup along x: bottom plate at 0..t_b, open rim at ``height_m``.

    Args:
        n_theta: Elements around (multiple of 4); default keeps curved P2 edges of the thin
            wall valid (as :func:`sensors.meshing.tube_mesh`) and at least 24.
        n_wall: Elements through the wall and through the bottom plate.
        element_height_m: Axial element size in the wall; default 2.5 times the size around.
        extra_levels_m: Extra layer positions (x, m) to include, e.g. fill heights, so that the
            cavity tets below a level fill it exactly.
    """
    _check_positive(height_m=height_m, outer_radius_m=outer_radius_m, wall_thickness_m=wall_thickness_m,
                    bottom_thickness_m=bottom_thickness_m)
    inner = outer_radius_m - wall_thickness_m
    if inner <= 0 or bottom_thickness_m >= height_m:
        raise MeshError("the cup's wall or bottom is thicker than the cup")
    if n_theta is None:
        n_min = 2 * math.pi * math.sqrt(outer_radius_m / wall_thickness_m)
        n_theta = 4 * max(6, int(math.ceil(n_min / 4)))
    h_x = element_height_m or 2.5 * 2 * math.pi * outer_radius_m / n_theta
    points, tris, wall = disc_section(inner, n_theta, outer_radius_m, n_wall)
    n_up = max(2, int(math.ceil((height_m - bottom_thickness_m) / h_x - 1e-9)))
    levels = np.concatenate([np.linspace(0.0, bottom_thickness_m, n_wall + 1),
                             np.linspace(bottom_thickness_m, height_m, n_up + 1)[1:], np.asarray(extra_levels_m, float)])
    levels = np.unique(np.round(levels, 12))
    if levels[0] < 0 or levels[-1] > height_m:
        raise MeshError("extra_levels_m must lie inside the cup")
    nx = len(levels) - 1
    vertices, tets = _extrude(points, tris, 1.0, nx)
    p = len(points)
    vertices[:, 0] = np.repeat(levels, p)
    # _extrude emits three groups of (layer, triangle) prisms, layer-major.
    idx = np.tile(np.arange(nx * len(tris)), 3)
    layer, tri = idx // len(tris), idx % len(tris)
    in_plate = levels[layer] < bottom_thickness_m - 1e-12
    solid = in_plate | wall[tri]
    tets = _orient(vertices, tets)
    used = np.unique(tets[solid])
    cav_only = np.setdiff1d(np.unique(tets[~solid]), used)
    order = np.concatenate([used, cav_only])
    new = np.empty(len(vertices), dtype=np.int64)
    new[order] = np.arange(len(order))
    wall_mesh = TetMesh(vertices[used], new[tets[solid]], "cup",
                        {"height_m": float(height_m), "outer_radius_m": float(outer_radius_m),
                         "wall_thickness_m": float(wall_thickness_m), "bottom_thickness_m": float(bottom_thickness_m)},
                        (float(inner), float(outer_radius_m)))
    return CupMesh(wall_mesh, new[tets[~solid]], vertices[cav_only], levels)

