"""A container's inner cavity and the tet mesh of the liquid filling it up to a free surface.

The free surface is the plane ``up . p = d`` normal to gravity (``up = -gravity``); the liquid is
the part of the cavity below it. A fill is given as a volume, so a tilted container keeps its
volume and gets a tilted surface.

Two cavity kinds:

* :class:`AxisymmetricCavity` - an inner profile R(s) about an axis with a flat bottom. The
  liquid gets a structured P2 mesh: a unit disc O-grid extruded over [0, 1] and mapped column
  by column from the bottom to the (possibly tilted) free surface, with mid-edge nodes on the
  exact wall. A new fill level or tilt is only a new map: fast and deterministic.
* :class:`SurfaceCavity` - any closed ``trimesh.Trimesh`` of the inside. It is cut by the free
  surface plane (capped) and tetrahedralized with pytetwild (slower; cached on disk).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.optimize

from .._infra.lru import CACHE_SIZES, LRU
from ..fem.assembly import QUADRATURE, shape_functions, shape_gradients_ref
from ..mesh.layered import disk_template
from ..mesh.prisms import extrude_to_tets
from ..mesh.quadratic import quadratic_mesh
from ..mesh.tets import MeshError, TetMesh
from ..mesh.tetwild import tetrahedralize_surface, validate_surface

__all__ = ["LiquidMesh", "AxisymmetricCavity", "SurfaceCavity", "LiquidSpillError", "cavity_of", "p2_volume_m3",
           "unit", "MAX_LIQUID_NODES"]

#: Default limit on the P2 nodes of a revolved cavity's liquid mesh (``liquid_max_nodes=`` of
#: ``filled``/``Container`` changes it): the added-mass solve holds a few kB per node (a mug
#: meshed at 10 um, 3.7 million nodes, peaked at 14.4 GB), so this bounds it near 1 GB.
MAX_LIQUID_NODES = 200_000
#: P2 nodes per layer of the liquid's disc, by elements around (the size check before meshing).
_LAYER_NODES = LRU(CACHE_SIZES["fluid.layer_nodes"])


class LiquidSpillError(ValueError):
    """The liquid asked for does not fit below the rim at this tilt (it would spill)."""


def unit(v) -> np.ndarray:
    """``v`` as a unit 3-vector (raises for a zero or non-finite vector)."""
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(v))
    if not (math.isfinite(n) and n > 0):
        raise ValueError(f"direction must be a finite non-zero 3-vector, got {v.tolist()}")
    return v / n


def p2_volume_m3(nodes_m: np.ndarray, tets: np.ndarray) -> float:
    """Volume of a (curved) P2 tet mesh by the degree-5 rule (exact for its geometry)."""
    return p2_mass_properties(nodes_m, tets, 1.0)[0]


def p2_mass_properties(nodes_m: np.ndarray, tets: np.ndarray, density_kg_m3: float):
    """(mass [kg], centre of mass (3,) [m], inertia tensor about the centre of mass (3, 3)
    [kg m^2]) of a uniform P2 tet mesh, by the degree-5 rule."""
    xi, w = QUADRATURE["deg5"]
    dN = shape_gradients_ref(xi, "p2")
    N = shape_functions(np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1), "p2")
    X = nodes_m[tets]
    dm = density_kg_m3 * np.linalg.det(np.einsum("mai,qak->mqik", X, dN)) * w  # (m, q)
    x = np.einsum("qa,mai->mqi", N, X)
    mass = float(dm.sum())
    centre = np.einsum("mq,mqi->i", dm, x) / mass
    r = x - centre
    second = np.einsum("mq,mqi,mqj->ij", dm, r, r)
    return mass, centre, np.trace(second) * np.eye(3) - second


@dataclasses.dataclass
class LiquidMesh:
    """P2 tet mesh of the liquid.

    Attributes:
        nodes_m: (n, 3) nodes in the object frame.
        tets: (m, 10) quadratic tets (VTK order), positively oriented.
        free_surface: (n,) True for nodes on the free surface (phi = 0 there).
        volume_m3: The liquid volume asked for (the mesh's own volume is within its
            discretization error of it).
        up: Unit normal of the free surface, against gravity.
        surface_offset_m: d in ``up . p = d``.
    """

    nodes_m: np.ndarray
    tets: np.ndarray
    free_surface: np.ndarray
    volume_m3: float
    up: np.ndarray
    surface_offset_m: float


def _perpendicular_basis(a: np.ndarray):
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = unit(np.cross(a, helper))
    return e1, np.cross(a, e1)


@dataclasses.dataclass
class AxisymmetricCavity:
    """Cavity of revolution: radius ``radius_m`` at axial positions ``axial_m`` (piecewise linear).

    The bottom is flat at ``axial_m[0]``, the rim at ``axial_m[-1]``; axial positions are
    measured from ``origin_m`` along ``axis`` (bottom to top), all in the object frame.
    """

    axial_m: np.ndarray
    radius_m: np.ndarray
    origin_m: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        self.axial_m = np.asarray(self.axial_m, dtype=np.float64)
        self.radius_m = np.asarray(self.radius_m, dtype=np.float64)
        if self.axial_m.ndim != 1 or len(self.axial_m) < 2 or self.axial_m.shape != self.radius_m.shape:
            raise ValueError("axial_m and radius_m must be 1-D arrays of the same length >= 2")
        if np.any(np.diff(self.axial_m) <= 0) or np.any(self.radius_m <= 0):
            raise ValueError("axial_m must increase and radius_m be positive")
        self.origin_m = np.asarray(self.origin_m, dtype=np.float64).reshape(3)
        self.axis = unit(self.axis)
        self._e1, self._e2 = _perpendicular_basis(self.axis)
        # Cumulative integral of R^2 (exact for piecewise-linear R) for column volumes.
        s = np.linspace(self.axial_m[0], self.axial_m[-1], 4001)
        r2 = self.radius(s) ** 2
        self._s, self._cum_r2 = s, np.concatenate([[0.0], np.cumsum(0.5 * (r2[1:] + r2[:-1]) * np.diff(s))])

    def radius(self, s):
        """Inner radius [m] at axial position s [m]."""
        return np.interp(s, self.axial_m, self.radius_m)

    @property
    def volume_m3(self) -> float:
        """Volume of the whole cavity (bottom to rim)."""
        s, r = self.axial_m, self.radius_m
        return float(np.pi * np.sum(np.diff(s) * (r[:-1] ** 2 + r[:-1] * r[1:] + r[1:] ** 2) / 3.0))

    @property
    def depth_m(self) -> float:
        """Depth from the bottom to the rim."""
        return float(self.axial_m[-1] - self.axial_m[0])

    @classmethod
    def from_profile(cls, profile_xr, axis=(1.0, 0.0, 0.0)) -> "AxisymmetricCavity":
        """The cavity of an inner profile: rows (x, r) [m] from the floor to the rim, x measured
        along ``axis`` from the object origin (the ``inner_profile_m`` of
        :class:`~sensors.objects.everyday.EverydayObject`). Rows on the axis (r = 0, closing the
        profile at the floor or the rim) are dropped."""
        prof = np.asarray(profile_xr, dtype=np.float64)
        if prof.ndim != 2 or prof.shape[1] != 2:
            raise ValueError(f"profile_xr must have shape (k, 2), got {prof.shape}")
        prof = prof[prof[:, 1] > 0]
        x0 = float(prof[0, 0])
        return cls(prof[:, 0] - x0, prof[:, 1], origin_m=x0 * unit(axis), axis=axis)

    @property
    def upright_up(self) -> np.ndarray:
        """The ``up`` direction of the container standing upright (its axis)."""
        return self.axis.copy()

    def _local(self, points_m):
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64)) - self.origin_m
        s = p @ self.axis
        r = np.linalg.norm(p - s[:, None] * self.axis, axis=-1)
        return s, r

    def wall_distance_m(self, points_m) -> np.ndarray:
        """Distance [m] from each point to the wetted boundary (the side wall up to the rim and
        the floor), (n,); the opening is not part of it."""
        s, r = self._local(points_m)
        sc = np.clip(s, self.axial_m[0], self.axial_m[-1])
        # Piecewise-linear profile: the radial offset at the clamped axial position bounds the
        # distance to the side wall closely for the gentle profiles of containers.
        wall = np.hypot(r - self.radius(sc), s - sc)
        floor = np.hypot(s - self.axial_m[0], np.maximum(r - self.radius_m[0], 0.0))
        return np.minimum(wall, floor)

    @property
    def size_m(self) -> float:
        """A length scale of the cavity: its bounding box diagonal [m]."""
        return float(math.hypot(self.depth_m, 2.0 * self.radius_m.max()))

    def rim_points_m(self, n: int = 256) -> np.ndarray:
        """(n, 3) points on the rim circle."""
        t = 2 * math.pi * np.arange(n) / n
        return (self.origin_m + self.axial_m[-1] * self.axis
                + self.radius_m[-1] * (np.cos(t)[:, None] * self._e1 + np.sin(t)[:, None] * self._e2))

    def max_volume_m3(self, up) -> float:
        """The most liquid the cavity holds with its free surface normal to ``up`` (up to the
        lowest point of the rim; more spills)."""
        up = unit(up)
        if float(up @ self.axis) <= 1e-6:
            return 0.0
        volume = self._volume_for_offset(up, float((self.rim_points_m() @ up).min()))
        return self.volume_m3 if volume >= self.volume_m3 * (1 - 1e-9) else volume

    def volume_below_m3(self, fill_height_m: float) -> float:
        """Upright volume up to ``fill_height_m`` above the bottom."""
        s = self.axial_m[0] + float(np.clip(fill_height_m, 0.0, self.depth_m))
        return float(np.pi * np.interp(s, self._s, self._cum_r2))

    def height_below_m(self, volume_m3: float) -> float:
        """Upright height above the bottom [m] that holds ``volume_m3`` (the inverse of
        :meth:`volume_below_m3`)."""
        s = float(np.interp(volume_m3 / math.pi, self._cum_r2, self._s))
        return s - float(self.axial_m[0])

    def _surface_axial(self, y, z, up, d):
        """Axial position where the column through unit-disc point (y, z) meets up . p = d."""
        alpha = float(up @ self.axis)
        if alpha <= 1e-6:
            raise MeshError("the free surface is parallel to the container axis or the container is upside down")
        beta = float(up @ self._e1) * y + float(up @ self._e2) * z
        c = d - float(up @ self.origin_m)
        s = np.full(np.shape(y), c / alpha)
        for _ in range(50):  # fixed point; one step when R is constant
            s_new = (c - self.radius(s) * beta) / alpha
            if np.max(np.abs(s_new - s)) <= 1e-13 * max(self.depth_m, 1e-12):
                return s_new
            s = s_new
        raise MeshError("the free surface's column map did not converge (profile too steep for this tilt)")

    def _volume_for_offset(self, up, d, n_r=24, n_t=64):
        x, w = np.polynomial.legendre.leggauss(n_r)
        rho = 0.5 * (x + 1.0)
        t = 2 * np.pi * np.arange(n_t) / n_t
        rr, tt = np.meshgrid(rho, t, indexing="ij")
        s = np.clip(self._surface_axial(rr * np.cos(tt), rr * np.sin(tt), up, d), self.axial_m[0], self.axial_m[-1])
        col = np.interp(s, self._s, self._cum_r2)  # integral of R^2 ds from the bottom
        return float(np.sum(col * rr * (0.5 * w)[:, None]) * (2 * np.pi / n_t))

    def surface_offset_m(self, volume_m3: float, up) -> float:
        """Offset d of the free surface ``up . p = d`` that holds ``volume_m3`` of liquid."""
        up = unit(up)
        corners = np.array([self.origin_m + s * self.axis + sgn * r * e for s, r in zip(self.axial_m, self.radius_m)
                            for e in (self._e1, self._e2) for sgn in (-1, 1)])
        lo, hi = float((corners @ up).min()), float((corners @ up).max())
        if volume_m3 >= self._volume_for_offset(up, hi):  # full to the top (round-off of the two volumes)
            return hi
        if volume_m3 <= self._volume_for_offset(up, lo):  # at most the quadrature's error in a dry corner
            raise self._dry_floor_error(volume_m3, up)
        return scipy.optimize.brentq(lambda d: self._volume_for_offset(up, d) - volume_m3, lo, hi,
                                     xtol=1e-12 * (hi - lo))

    def _dry_floor_error(self, volume_m3: float, up) -> MeshError:
        """The error for a free surface that would leave part of the floor dry, saying how much covers it."""
        if float(up @ self.axis) >= 1.0 - 1e-12:
            return MeshError(f"{volume_m3 * 1e6:.3g} ml is too little liquid to mesh (a film of under 1e-9 of the "
                             "cavity's depth): give more, or 0 for an empty container")
        tilt = math.sqrt(float(up @ self._e1) ** 2 + float(up @ self._e2) ** 2)
        covered = self._volume_for_offset(up, float(up @ self.origin_m) + self.radius_m[0] * tilt)
        return MeshError(f"{volume_m3 * 1e6:.4g} ml leaves part of the bottom dry at this tilt (the liquid covers "
                         f"the bottom from {covered * 1e6:.4g} ml, a fill fraction of "
                         f"{covered / self.volume_m3:.3g}): give "
                         "more liquid or a smaller tilt (a revolved cavity's structured mesh needs a wet floor)")

    def check_fill(self, volume_m3: float, up, n_theta: int = 16) -> None:
        """Raise what :meth:`liquid_mesh` would for this fill (:class:`LiquidSpillError`, ``MeshError``
        for a dry floor) without meshing; an upright fill is checked without the surface's solve."""
        up = unit(up)
        if float(up @ self.axis) >= 1.0 - 1e-12:  # level surface: only a film too thin to mesh fails
            if self.height_below_m(volume_m3) <= 1e-9 * self.depth_m:
                raise self._dry_floor_error(volume_m3, up)
            return
        self.free_surface(volume_m3, up, n_theta)

    def free_surface(self, volume_m3: float, up, n_theta: int = 16):
        """The free surface's offset d and its axial heights at 4 ``n_theta`` points on the rim
        circle; raises :class:`LiquidSpillError` if it spills, ``MeshError`` if the floor is partly dry."""
        up = unit(up)
        d = self.surface_offset_m(volume_m3, up)
        # Surface heights on the rim decide validity and the number of layers.
        rim = np.linspace(0, 2 * math.pi, 4 * n_theta, endpoint=False)
        s_rim = self._surface_axial(np.cos(rim), np.sin(rim), up, d)
        if s_rim.min() <= self.axial_m[0] + 1e-9 * self.depth_m:
            raise self._dry_floor_error(volume_m3, up)
        if s_rim.max() > self.axial_m[-1] + 1e-9 * self.depth_m:
            raise LiquidSpillError(f"{volume_m3 * 1e6:.4g} ml would spill over the rim at this tilt (it holds "
                                   f"{self.max_volume_m3(up) * 1e6:.4g} ml)")
        return d, s_rim

    def liquid_mesh_nodes(self, n_theta: int = 16, element_size_m: float | None = None) -> int:
        """The most P2 nodes :meth:`liquid_mesh` makes (liquid up to the rim) with these settings."""
        h = element_size_m or 2 * math.pi * float(self.radius_m.max()) / n_theta
        return _p2_nodes_per_layer(n_theta) * (2 * max(2, math.ceil(self.depth_m / h)) + 1)

    def check_liquid_mesh_size(self, n_theta: int = 16, element_size_m: float | None = None,
                               max_nodes: int | None = MAX_LIQUID_NODES) -> None:
        """Refuse (:class:`~sensors.mesh.surface.MeshTooLargeError`), before meshing, a liquid mesh
        above ``max_nodes`` (None: no limit)."""
        if max_nodes is None:
            return
        from ..mesh.surface import MeshTooLargeError  # imports trimesh: only when refusing

        n = self.liquid_mesh_nodes(n_theta, element_size_m)
        if n > max_nodes:
            raise MeshTooLargeError(
                f"the liquid mesh would have up to {n:,} nodes (element size {element_size_m} m, {n_theta} around), "
                f"above the limit of {int(max_nodes):,} (a few kB each in the added-mass solve): give a larger "
                "liquid_element_size_m or a smaller liquid_n_theta, or raise liquid_max_nodes=")

    def liquid_mesh(self, volume_m3: float, up, n_theta: int = 16, element_size_m: float | None = None,
                    max_nodes: int | None = MAX_LIQUID_NODES) -> LiquidMesh:
        """Structured P2 mesh of ``volume_m3`` of liquid with its free surface normal to ``up``.

        Args:
            n_theta: Elements around (a multiple of 8).
            element_size_m: Axial element size; default the size around the wall.
            max_nodes: Refuse a larger mesh before building it (:meth:`check_liquid_mesh_size`).
        """
        up = unit(up)
        self.check_liquid_mesh_size(n_theta, element_size_m, max_nodes)
        d, s_rim = self.free_surface(volume_m3, up, n_theta)
        r_max = float(self.radius_m.max())
        h = element_size_m or 2 * math.pi * r_max / n_theta
        template = disk_template(n_theta, 0)  # the O-grid unit disk of the container meshes
        pts, tris = template.points, template.triangles
        nz = max(2, int(math.ceil((s_rim.max() - self.axial_m[0]) / h - 1e-9)))
        v, t = extrude_to_tets(pts, tris, 1.0, nz)
        nodes, tets = quadratic_mesh(TetMesh(v, t, "liquid", {}, (1.0,)))
        xi = nodes[:, 0] + 0.5
        y, z = nodes[:, 1], nodes[:, 2]
        s_top = self._surface_axial(y, z, up, d)
        s = self.axial_m[0] + xi * (s_top - self.axial_m[0])
        r = self.radius(s)
        phys = self.origin_m + s[:, None] * self.axis + r[:, None] * (y[:, None] * self._e1 + z[:, None] * self._e2)
        tets = _orient_p2(phys, tets)
        free = np.abs(xi - 1.0) < 1e-12
        return LiquidMesh(phys, tets, free, float(volume_m3), up, float(d))


def _p2_nodes_per_layer(n_theta: int) -> int:
    """P2 nodes of one layer of the liquid's O-grid disc: its vertices and edges (Euler)."""
    def count():
        template = disk_template(n_theta, 0)
        return 2 * len(template.points) + len(template.triangles) - 1
    return _LAYER_NODES.get_or_build(n_theta, count)


def _orient_p2(nodes_m, tets10):
    """Make P2 tets positively oriented (the axis map may mirror them)."""
    p = nodes_m[tets10[:, :4]]
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    neg = vol < 0
    if np.any(neg):
        tets10 = tets10.copy()
        # Swapping corners 1 and 2 swaps edges (0,1)<->(0,2) and (1,3)<->(2,3); edge (1,2) stays.
        perm = np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])
        tets10[neg] = tets10[neg][:, perm]
    return tets10


@dataclasses.dataclass
class SurfaceCavity:
    """Any closed surface (``trimesh.Trimesh``, metres, object frame) bounding the cavity."""

    mesh: object

    def __post_init__(self):
        self.mesh = validate_surface(self.mesh)

    @property
    def volume_m3(self) -> float:
        """Volume of the whole cavity."""
        return float(self.mesh.volume)

    @property
    def size_m(self) -> float:
        """A length scale of the cavity: its bounding box diagonal [m]."""
        return float(np.linalg.norm(np.ptp(self.mesh.vertices, axis=0)))

    def wall_distance_m(self, points_m) -> np.ndarray:
        """Distance [m] from each point to the cavity's closed surface (opening included), (n,)."""
        import trimesh  # only this cavity kind needs trimesh's proximity queries

        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        return np.asarray(trimesh.proximity.closest_point(self.mesh, p)[1], dtype=np.float64)

    def max_volume_m3(self, up) -> float:
        """The whole cavity (a closed surface has no known opening: spilling is not modelled)."""
        return self.volume_m3

    def _sliced(self, up, d):
        import trimesh  # only this cavity kind needs trimesh's slicing

        return trimesh.intersections.slice_mesh_plane(self.mesh, plane_normal=-up, plane_origin=d * up, cap=True)

    def surface_offset_m(self, volume_m3: float, up) -> float:
        up = unit(up)
        proj = np.asarray(self.mesh.vertices) @ up
        lo, hi = float(proj.min()), float(proj.max())

        def excess(d):
            if d <= lo:
                return -volume_m3
            if d >= hi:
                return self.volume_m3 - volume_m3
            return float(self._sliced(up, d).volume) - volume_m3

        return scipy.optimize.brentq(excess, lo, hi, xtol=1e-9 * (hi - lo))

    def check_liquid_mesh_size(self, *_, **__) -> None:
        """pytetwild's own size guard (``max_dof``) refuses a too fine liquid mesh before meshing."""

    def liquid_mesh(self, volume_m3: float, up, element_size_m: float | None = None, **_) -> LiquidMesh:
        """pytetwild mesh of the cavity below the free surface (straight P2 elements)."""
        up = unit(up)
        d = self.surface_offset_m(volume_m3, up)
        sliced = self._sliced(up, d)
        tm = tetrahedralize_surface(sliced, element_size_m=element_size_m)
        nodes, tets = quadratic_mesh(tm)
        extent = float(np.ptp(nodes, axis=0).max())
        free = np.abs(nodes @ up - d) <= 1e-4 * extent
        return LiquidMesh(nodes, tets, free, float(volume_m3), up, float(d))


def cavity_of(obj) -> "AxisymmetricCavity | SurfaceCavity":
    """The cavity of a container: an :class:`~sensors.objects.everyday.EverydayObject` (its inner profile
    when it is revolved, else its closed cavity surface), or a cavity itself."""
    if isinstance(obj, (AxisymmetricCavity, SurfaceCavity)):
        return obj
    profile = getattr(obj, "inner_profile_m", None)
    if profile is not None:
        return AxisymmetricCavity.from_profile(profile, axis=getattr(obj, "main_axis", (1.0, 0.0, 0.0)))
    surface = getattr(obj, "cavity", None)
    if surface is not None:
        return SurfaceCavity(surface)
    raise TypeError(f"{getattr(obj, 'name', type(obj).__name__)!r} is not a container (it has no cavity)")
