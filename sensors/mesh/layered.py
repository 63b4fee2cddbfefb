"""Structured tet meshes of layered solids: revolved containers, extruded frames and plates.

A layered solid is a 2D template triangulation swept through ``n`` layers. Each layer keeps
only some template triangles (a container's floor keeps the whole disk, its wall only the
annulus), and every layer places the template points in 3D on its own (a bottle's radius
changes with height, a spoon's bowl is dished). The sweep and the prism-to-tet split are
:func:`sensors.mesh.prisms.extrude_to_tets`'s, whose global-number rule keeps the mesh
conforming, so switching triangles off layer by layer never leaves a hanging face.

Templates here:

* :func:`disk_template` - an O-grid disk of radius 1 (square core, the same grid
  ``rod_mesh`` uses) plus an annulus from radius 1 to 2 with ``n_wall`` rings: the cavity is the
  unit disk, the wall the annulus. :func:`revolved_mesh` maps them to radii per height.
* :func:`grid_template` - a tensor grid of a rectangle with given lines (box walls, L shapes,
  spoon planforms).

:func:`handled_cup_mesh` joins a second sweep, a D handle, to a revolved cup's wall.

Mirror planes: a template whose points and triangles mirror across a coordinate line is swept
into a mesh that mirrors across the matching plane only if the prisms' split does too. The
split follows an order of the template points (:func:`sensors.mesh.prisms.extrude_to_tets`);
:func:`mirror_split_rank` gives one that the mirrors keep, so the revolved containers (about y
and z), the mug (about z) and the box (about y and z) are mirror-symmetric meshes, vertices and
tets, and say so (``TetMesh.mirror_axes``): their modes are solved per symmetry class
(:mod:`sensors.fem.mirror`). The mug's collision surface is that of its plain split
(``handled_cup_mesh(mirror_split=False)``, see :func:`sensors.objects.everyday.mug`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .prisms import extrude_to_tets, grid_triangles, rod_mesh
from .tets import TetMesh, boundary_faces, orient_tets

__all__ = ["Template", "disk_template", "grid_template", "layered_mesh", "revolved_mesh", "handled_cup_mesh",
           "mirror_classes", "mirror_split_rank", "p2_dof_count"]

#: Template coordinates closer than this (relative to the template's extent) are one value in
#: :func:`mirror_classes` (mirrored points agree only to round-off: cos(-t) against cos(t)).
MIRROR_TOL = 1e-9


@dataclasses.dataclass(frozen=True)
class Template:
    """A 2D triangulation swept by :func:`layered_mesh`.

    Attributes:
        points: (p, 2) template coordinates.
        triangles: (t, 3) point indices.
        region: (t,) integer label per triangle (e.g. 0 = cavity disk, 1 = wall annulus).
    """

    points: np.ndarray
    triangles: np.ndarray
    region: np.ndarray


def disk_template(n_theta: int, n_wall: int) -> Template:
    """O-grid unit disk (region 0) plus the annulus 1 <= rho <= 2 (region 1).

    ``n_theta`` (a multiple of 8) points around; ``n_wall`` element rings across the annulus.
    The disk's grid is taken from :func:`sensors.mesh.prisms.rod_mesh` (its first cross-section).
    """
    if n_theta % 8:
        raise ValueError(f"n_theta must be a multiple of 8, got {n_theta}")
    # rod_mesh puts 2 ceil(r / (2 h)) core cells per side and 4 times that many points around.
    # Only its first cross-section is used: a rod one element long is enough (a unit template,
    # so the size guard does not apply).
    rod = rod_mesh(4.0 / n_theta, 1.0, element_size_m=4.0 / n_theta, max_dof=None)
    x = rod.vertices_m[:, 0]
    first = np.flatnonzero(np.isclose(x, x.min()))
    p = len(first)
    assert np.array_equal(first, np.arange(p))  # extrude_to_tets stores layer 0 first
    points = rod.vertices_m[:p, 1:].copy()
    faces, _ = boundary_faces(rod.tets)
    disk_tris = faces[(faces < p).all(axis=1)]
    rho = np.hypot(points[:, 0], points[:, 1])
    rim = np.flatnonzero(np.isclose(rho, 1.0))
    rim = rim[np.argsort(np.mod(np.arctan2(points[rim, 1], points[rim, 0]), 2 * math.pi))]
    theta = np.arctan2(points[rim, 1], points[rim, 0])
    assert len(rim) == n_theta
    rings = [rim]
    new = []
    for j in range(1, n_wall + 1):
        r = 1.0 + j / n_wall
        start = p + (j - 1) * n_theta
        new.append(np.stack([r * np.cos(theta), r * np.sin(theta)], 1))
        rings.append(start + np.arange(n_theta))
    index = np.stack(rings)
    index = np.concatenate([index, index[:, :1]], axis=1)
    wall_tris = grid_triangles(n_wall, n_theta, index)
    points = np.concatenate([points] + new)
    triangles = np.concatenate([disk_tris, wall_tris])
    region = np.concatenate([np.zeros(len(disk_tris), int), np.ones(len(wall_tris), int)])
    return Template(points, triangles, region)


def grid_template(u_lines: np.ndarray, v_lines: np.ndarray, region_of_cell) -> Template:
    """Tensor grid over ``u_lines`` x ``v_lines`` (ascending); ``region_of_cell(u_c, v_c)``
    labels each cell from its centre (a negative label drops the cell)."""
    u, v = np.asarray(u_lines, float), np.asarray(v_lines, float)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    points = np.stack([uu.ravel(), vv.ravel()], 1)
    index = np.arange(len(points)).reshape(len(u), len(v))
    tris = grid_triangles(len(u) - 1, len(v) - 1, index)
    centre = points[tris].mean(axis=1)
    region = np.asarray(region_of_cell(centre[:, 0], centre[:, 1]), dtype=int)
    keep = region >= 0
    return Template(points, tris[keep], region[keep])


def _dense_rank(values: np.ndarray, tol: float) -> np.ndarray:
    """Rank of each value among the distinct ones, values within ``tol`` of their neighbour
    in sorted order counting as one."""
    order = np.argsort(values, kind="stable")
    ranks = np.empty(len(values), np.int64)
    ranks[order] = np.concatenate([[0], np.cumsum(np.diff(values[order]) > tol)])
    return ranks


def mirror_classes(points: np.ndarray, axes) -> np.ndarray:
    """A rank per template point that mirroring across the coordinate lines ``axes`` (0 or 1:
    the line where that coordinate is 0) keeps: the order of (|coordinate| along each mirror
    axis, then the other coordinate). Points share a rank only with their own mirror images."""
    points = np.asarray(points, float)
    axes = tuple(int(a) for a in axes)
    tol = MIRROR_TOL * max(float(np.abs(points).max()), 1e-300)
    keys = [np.abs(points[:, a]) for a in axes] + [points[:, a] for a in range(points.shape[1]) if a not in axes]
    columns = [_dense_rank(k, tol) for k in keys]
    combined = np.zeros(len(points), np.int64)
    for c in columns:  # lexicographic, first key most significant
        combined = combined * (int(c.max()) + 1) + c
    return _dense_rank(combined.astype(float), 0.5)


def mirror_split_rank(classes: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distinct split ranks (for :func:`sensors.mesh.prisms.extrude_to_tets`) that order the
    template points by their mirror-invariant ``classes`` (ties by number): a prism and its
    mirror image are then split alike, so the mesh mirrors as its template does.

    Raises:
        ValueError: a triangle joins two points of one class (an edge across the mirror line:
            no split of it is mirror-invariant).
    """
    classes = np.asarray(classes)
    c = classes[np.asarray(triangles)]
    if np.any((c[:, 0] == c[:, 1]) | (c[:, 1] == c[:, 2]) | (c[:, 0] == c[:, 2])):
        raise ValueError("a template edge joins a point to its mirror image: no mirror-invariant split exists")
    order = np.lexsort((np.arange(len(classes)), classes))
    rank = np.empty(len(classes), np.int64)
    rank[order] = np.arange(len(classes))
    return rank


def _sweep(template: Template, n_layers: int, active, place, split_rank=None) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of every template point on every level (level k, point i -> row k p + i) and
    the solid tets in that numbering (before unused points are dropped)."""
    n_tri = len(template.triangles)
    if callable(active):
        active = np.stack([np.asarray(active(k), bool) for k in range(n_layers)])
    active = np.asarray(active, bool).reshape(n_layers, n_tri)
    _, tets = extrude_to_tets(template.points, template.triangles, 1.0, n_layers, split_rank)
    tets = tets[np.tile(active.ravel(), 3)]
    coords = np.concatenate([np.asarray(place(template.points, k), float) for k in range(n_layers + 1)])
    return coords, tets


def _tet_mesh(coords, tets, kind, dimensions_m, cylinder_radii_m, mirror_axes=()) -> TetMesh:
    used, inverse = np.unique(tets, return_inverse=True)
    vertices = coords[used]
    tets = orient_tets(vertices, inverse.reshape(-1, 4))
    return TetMesh(vertices, tets, kind, dict(dimensions_m or {}), tuple(cylinder_radii_m), tuple(mirror_axes))


def layered_mesh(template: Template, n_layers: int, active, place, kind: str = "mesh",
                 dimensions_m: dict | None = None, cylinder_radii_m: tuple = (), mirror_axes: tuple = ()) -> TetMesh:
    """Sweep ``template`` through ``n_layers`` layers into a conforming tet mesh.

    Args:
        active: (n_layers, t) bool, or callable(layer) -> (t,) bool: the template triangles
            that are solid in each layer.
        place: callable(points (p, 2), level) -> (p, 3): the 3D position of every template
            point on level ``0 .. n_layers`` (levels bound the layers).
        cylinder_radii_m: exact cylinders about x whose P2 mid-edge nodes
            :func:`sensors.mesh.quadratic.quadratic_mesh` curves onto them.
        mirror_axes: object axes (1 y, 2 z) whose planes through the x axis mirror the solid,
            with ``place`` putting template coordinate ``axis - 1`` along that axis (its sign
            kept) and ``active`` the same for mirrored triangles: the prisms are then split
            mirror-invariantly (:func:`mirror_split_rank`) and the mesh records the planes.
    """
    rank = None
    if mirror_axes:
        rank = mirror_split_rank(mirror_classes(template.points, [a - 1 for a in mirror_axes]), template.triangles)
    coords, tets = _sweep(template, n_layers, active, place, rank)
    return _tet_mesh(coords, tets, kind, dimensions_m, cylinder_radii_m, mirror_axes)


def _revolved(levels_x_m, inner_radius_m, outer_radius_m, floor_layers, n_theta, n_wall, angle_of=None):
    """(template, active, place) of a container about x; ``angle_of`` (theta -> theta, monotone,
    odd) moves the wall's points around the axis (faded out inside half the cavity radius)."""
    levels = np.asarray(levels_x_m, float)
    tpl = disk_template(n_theta, n_wall)
    rho_t = np.hypot(tpl.points[:, 0], tpl.points[:, 1])
    unit = tpl.points / np.where(rho_t > 0, rho_t, 1.0)[:, None]
    if angle_of is not None:
        theta = np.arctan2(unit[:, 1], unit[:, 0])
        phi = theta + (np.asarray(angle_of(theta)) - theta) * np.clip(2.0 * rho_t - 1.0, 0.0, 1.0)
        unit = np.where(rho_t[:, None] > 0, np.stack([np.cos(phi), np.sin(phi)], 1), unit)
    wall = tpl.region == 1

    def place(points, k):
        x = levels[k]
        ri, ro = float(inner_radius_m(x)), float(outer_radius_m(x))
        r = np.where(rho_t <= 1.0 + 1e-12, rho_t * ri, ri + (rho_t - 1.0) * (ro - ri))
        # Exact radii on the rings (no round-off) so quadratic_mesh recognises the cylinders.
        out = np.empty((len(points), 3))
        out[:, 0] = x
        out[:, 1:] = unit * r[:, None]
        return out

    return tpl, (lambda k: np.ones_like(wall) if k < floor_layers else wall), place


def revolved_mesh(levels_x_m: np.ndarray, inner_radius_m, outer_radius_m, floor_layers: int,
                  n_theta: int = 48, n_wall: int = 1, kind: str = "container", dimensions_m: dict | None = None,
                  cylinder_radii_m: tuple = ()) -> TetMesh:
    """A container about the x axis: solid floor, then an open wall.

    Args:
        levels_x_m: (n + 1,) ascending axial positions of the layer boundaries [m].
        inner_radius_m, outer_radius_m: callables x -> radius [m] of the wall's inner and outer
            surface (in the floor, the inner radius only places the inner grid ring).
        floor_layers: the first ``floor_layers`` layers are the solid floor.

    The mesh mirrors across the x-y and the x-z plane (``mirror_axes`` (1, 2)).
    """
    tpl, active, place = _revolved(levels_x_m, inner_radius_m, outer_radius_m, floor_layers, n_theta, n_wall)
    return layered_mesh(tpl, len(levels_x_m) - 1, active, place, kind, dimensions_m, cylinder_radii_m,
                        mirror_axes=(1, 2))


def handled_cup_mesh(levels_x_m: np.ndarray, inner_radius_m: float, outer_radius_m: float, floor_layers: int,
                     handle_levels: tuple[int, int, int, int], handle_half_angle_rad: float, n_across: int,
                     stub_m: float, n_stub: int, n_bend: int, n_theta: int = 48, n_wall: int = 1, kind: str = "mug",
                     dimensions_m: dict | None = None, mirror_split: bool = True) -> TetMesh:
    """A straight cup about x with a D handle on its +y side, structured and conforming.

    The handle is a rectangular bar swept along a path in the x-y plane: a straight stub out of
    the wall, a half circle, a stub back. Its ends are the wall's own outer faces: the wall
    points are turned about the axis so that ``n_across`` cells span exactly
    +-``handle_half_angle_rad`` (the handle is ``2 r sin(angle)`` wide in z), and the stubs
    start on the axial levels ``handle_levels`` = (k0, k1) lower stub, (k2, k3) upper stub.

    The handle is itself a layered sweep: its template is the (across, along-path) grid and its
    layers go through the thickness. Conformity at the joints follows from the split rule of
    :func:`sensors.mesh.prisms.extrude_to_tets` (a quad's diagonal joins the bottom of the higher
    split rank to the top of the lower): the handle's ranks rise with the wall's
    along the upper joint and fall along the lower one, where its layers run down the axis.
    With ``mirror_split`` both ranks are mirror-invariant (:func:`mirror_split_rank`): the mesh
    mirrors across the x-y plane (``mirror_axes`` (2,)) and its modes split into two classes.
    Without it the prisms split in template order (the same vertices, other diagonals).

    Args:
        levels_x_m: axial levels [m]; ``floor_layers`` solid floor layers first.
        inner_radius_m, outer_radius_m: the wall's radii [m].
        stub_m: length of each straight stub beyond the wall's outermost point [m].
        n_stub, n_bend: cells along a stub and along the half circle.
        n_wall: cells through the wall.
        mirror_split: split the prisms mirror-invariantly (else in template order).
    """
    levels = np.asarray(levels_x_m, float)
    k0, k1, k2, k3 = handle_levels
    if not (floor_layers <= k0 < k1 < k2 < k3 < len(levels)) or k1 - k0 != k3 - k2:
        raise ValueError(f"handle levels {handle_levels} must rise inside the wall with equal stub heights")
    if n_across % 2:
        raise ValueError(f"n_across must be even (the handle is centred on +y), got {n_across}")
    ri, ro = float(inner_radius_m), float(outer_radius_m)
    step = 2 * math.pi / n_theta
    half = n_across // 2
    if half * step >= math.pi / 2:
        raise ValueError("the handle spans more than half the cup")

    def angle_of(theta):
        # Piecewise linear, odd: the rim points at +-half steps land on +-handle_half_angle.
        a, b = half * step, handle_half_angle_rad
        t = np.abs(theta)
        return np.sign(theta) * np.where(t <= a, t * b / a, b + (t - a) * (math.pi - b) / (math.pi - a))

    tpl, active, place = _revolved(levels, lambda x: ri, lambda x: ro, floor_layers, n_theta, n_wall, angle_of)
    body_classes = mirror_classes(tpl.points, [1])  # the cup mirrors across x-y (z -> -z), handle and all
    body_xyz, body_tets = _sweep(tpl, len(levels) - 1, active, place,
                                 mirror_split_rank(body_classes, tpl.triangles) if mirror_split else None)
    p = len(tpl.points)

    # The joint's wall points: outer ring (rho = 2), ordered by angle across the handle.
    rho_t = np.hypot(tpl.points[:, 0], tpl.points[:, 1])
    outer = np.flatnonzero(np.isclose(rho_t, 2.0))
    ang = np.arctan2(tpl.points[outer, 1], tpl.points[outer, 0])
    patch = outer[np.abs(ang) <= (half + 0.5) * step]
    patch = patch[np.argsort(np.arctan2(tpl.points[patch, 1], tpl.points[patch, 0]))]
    assert len(patch) == n_across + 1
    z = body_xyz[patch, 2]
    y_wall = body_xyz[patch, 1]

    # Handle template: (n_across + 1) x (S + 1) points; row 0 at the upper joint, row S at the lower.
    S = 2 * n_stub + n_bend
    index = np.empty((n_across + 1, S + 1), int)
    rank = np.argsort(np.argsort(patch))                 # order of the wall's template numbers
    index[:, 0] = rank
    index[:, 1:S] = n_across + 1 + np.arange((n_across + 1) * (S - 1)).reshape(n_across + 1, S - 1)
    index[:, S] = (n_across + 1) * S + (n_across - rank)
    points = np.zeros(((n_across + 1) * (S + 1), 2))
    ii, ss = np.meshgrid(np.arange(n_across + 1), np.arange(S + 1), indexing="ij")
    points[index.ravel()] = np.stack([ii.ravel(), ss.ravel()], 1)
    handle = Template(points, grid_triangles(n_across, S, index), np.zeros(2 * n_across * S, int))
    col, row = points[:, 0].astype(int), points[:, 1].astype(int)
    handle_rank = None
    if mirror_split:
        # Row by row along the path, and across a row in the order of the wall points it meets
        # (reversed on the lower joint, whose layers run down the axis), so the joints' quads
        # split as the wall's do and the handle mirrors across x-y with the cup.
        across = body_classes[patch][col]
        handle_classes = row * (int(body_classes.max()) + 1) * 2 + np.where(row == S, -across, across)
        handle_rank = mirror_split_rank(handle_classes, handle.triangles)

    n_t = k3 - k2
    t_m = levels[k3] - levels[k2]
    x_c = 0.5 * (levels[k3] + levels[k0])
    r_in = 0.5 * (levels[k2] - levels[k1])
    y_c = ro + stub_m

    def place_handle(_, j):
        out = np.empty((len(points), 3))
        out[:, 2] = z[col]
        up, down = row <= n_stub, row >= n_stub + n_bend
        f_up = row / n_stub
        f_down = (S - row) / n_stub
        out[up, 0] = levels[k2 + j]
        out[up, 1] = y_wall[col[up]] + f_up[up] * (y_c - y_wall[col[up]])
        out[down, 0] = levels[k1 - j]
        out[down, 1] = y_wall[col[down]] + f_down[down] * (y_c - y_wall[col[down]])
        bend = ~(up | down)
        phi = math.pi * (row[bend] - n_stub) / n_bend
        rho = r_in + t_m * j / n_t
        out[bend, 0] = x_c + rho * np.cos(phi)
        out[bend, 1] = y_c + rho * np.sin(phi)
        return out

    handle_xyz, handle_tets = _sweep(handle, n_t, np.ones((n_t, len(handle.triangles)), bool), place_handle,
                                     handle_rank)
    # Handle vertex (layer j, template number h) -> body vertex on the joints, else a new one.
    q = len(points)
    to_global = len(body_xyz) + np.arange(len(handle_xyz))
    j = np.arange(n_t + 1)
    top_h = (j[:, None] * q + index[:, 0][None, :]).ravel()
    to_global[top_h] = ((k2 + j)[:, None] * p + patch[None, :]).ravel()
    low_h = (j[:, None] * q + index[:, S][None, :]).ravel()
    to_global[low_h] = ((k1 - j)[:, None] * p + patch[None, :]).ravel()
    coords = np.concatenate([body_xyz, handle_xyz])
    tets = np.concatenate([body_tets, to_global[handle_tets]])
    return _tet_mesh(coords, tets, kind, dimensions_m, (ri, ro), mirror_axes=(2,) if mirror_split else ())


def p2_dof_count(tet_mesh: TetMesh) -> int:
    """Degrees of freedom of the P2 model on ``tet_mesh`` (3 per corner and per edge)."""
    from .tets import P2_EDGES, row_codes

    pairs = np.sort(tet_mesh.tets[:, P2_EDGES].reshape(-1, 2), axis=1)
    codes = row_codes(pairs)
    edges = np.unique(codes) if codes is not None else np.unique(pairs, axis=0)
    return 3 * (len(np.unique(tet_mesh.tets)) + len(edges))
