"""A new upright fill in milliseconds: a container's wet model interpolated over the fill height.

Everything a fill adds to the container's basis (:mod:`sensors.fluid.filled_model`) is a smooth
function of the liquid's height h as long as the liquid's mesh keeps its topology: the added
mass M_a(h) and wall slip S(h) (per unit density), and the liquid's Laplacian H(h), mass Q0(h)
and wall load C(h) on the mesh, whose layer count ``ceil(h / element size)`` changes only at
multiples of the element size. So, per container, liquid and layer count (a *segment* of
heights), a :class:`FillTable` holds, at a uniform grid of heights, the exact M_a and S and the
liquid's matrices reduced onto one Ritz basis V of the segment (the liquid's acoustic modes at
the grid's heights, in the mesh's reference coordinates, where a column of liquid keeps its
modes' shape as it rises): V^T H V, V^T Q0 V, V^T C. A new fill interpolates these entrywise
(cubic Lagrange on the four nearest heights), solves the small liquid eigenproblem for its
acoustic modes and then the coupled one, exactly as the exact path does with its own matrices.

The grid is chosen by measured error: a segment starts with 3 intervals; the wet frequencies
interpolated at the midpoints between the grid heights (both liquid models) are compared with
exact solves there, and the intervals are halved until every one is within :data:`GRID_RTOL`;
a segment that does not get there within :data:`MAX_INTERVALS`, or whose error does not halve
when its intervals do (not an interpolation error then), keeps the exact solve
(:attr:`FillTable.exact_ranges_m`).
The cost is bounded before anything is solved (:data:`MAX_TABLE_SOLVES`,
:class:`FillTableCostError`). Tables are cached on disk with the container's static
correction, keyed by its content, the liquid's density and speed of sound and this code.

Covered: axisymmetric cavities standing upright, from 0.01 % of the liquid's element height to
the rim (lower fills, tilts and surface cavities take the exact path in :func:`sensors.fluid.filled`).
Films below 1 % of the element height (the first layer segment's start) have a segment of their
own (:attr:`FillTable.film`), refined the same way: without it a FillLevel-v0 fill drawn there
(0.17 % of the mug's default range) paid an exact solve of about 0.4 CPU s.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math

import numpy as np
import scipy.linalg
import scipy.sparse

from .._infra import cache as cache_mod
from .acoustic import LIQUID_MODES_BAND_FACTOR, MAX_LIQUID_MODES, liquid_mass_matrix, liquid_modes
from .added_mass import unit_potential_flow, wall_coupling
from .cavity import AxisymmetricCavity, p2_mass_properties
from .filled_model import FilledModalModel
from .liquid_body import LiquidBody

log = logging.getLogger(__name__)

__all__ = ["FillTable", "FillTableCostError", "fill_table", "GRID_RTOL", "MAX_TABLE_SOLVES", "MAX_INTERVALS"]

#: Largest relative difference of any wet frequency between the table and the exact solve at the
#: midpoints of the grid (both liquid models) that ends a segment's refinement.
GRID_RTOL = 2e-4
#: Intervals per segment at most (3, 6, 12, 24): a segment that needs more raises.
MAX_INTERVALS = 24
#: Exact fill solves one table may take at most (``max_solves=`` of :func:`fill_table`).
MAX_TABLE_SOLVES = 1200
#: The liquid's modes are sampled up to this factor times the kept cut (in frequency), so that
#: modes entering the cut between grid heights are in the Ritz basis.
MODE_MARGIN = 1.15
#: Ritz basis: directions whose singular value is below this fraction of the largest are dropped.
RITZ_RTOL = 1e-2
#: The first layer segment starts at this fraction of the liquid's element height (thinner films
#: are the film segment's).
FIRST_HEIGHT_FRACTION = 0.01
#: The film segment starts at this fraction of the liquid's element height (thinner films take
#: the exact path). On the mug its midpoints are within 2e-11 of the exact solve at 3 intervals.
FILM_HEIGHT_FRACTION = 1e-4

#: Whether a table's fill (:meth:`FillTable.filled`) interpolates the wall's matrices and solves
#: the liquid's modes when the model's modes are first read (True, fast for a fill that is never
#: heard: FillLevel-v0 with sensing off carries only the liquid's mass, 1.4 of its 10 ms per
#: episode went into those matrices) or at once (False, the reference).  The same numbers, later:
#: the same interpolation and solve (``tests/test_lazy_fill.py``).  Read at each call.
LAZY_WET_MATRICES = True


class FillTableCostError(ValueError):
    """A fill table would take more exact solves than allowed."""


@dataclasses.dataclass
class _Solve:
    """One exact fill at a height: what the table keeps and what its Ritz basis is made of."""

    height_m: float
    volume_m3: float
    ma: np.ndarray          # (nb, nb) added mass per unit density [m^3 / kg]
    slip: np.ndarray        # (nb, nb) wall slip [m^2 / kg]
    laplace: object         # (n_free, n_free) sparse H
    mass: object            # (n_free, n_free) sparse Q0
    load: np.ndarray        # (n_free, nb) C on the free nodes
    modes: np.ndarray       # (n_free, m) Q0-normalized liquid modes, k^2 up to the margin
    k2: np.ndarray          # (m,) their wavenumbers squared [1/m^2]
    centre_m: np.ndarray    # (3,) the liquid mesh's centre of mass
    inertia_per_kg: np.ndarray  # (3, 3) its inertia per unit mass [m^2]
    free: np.ndarray        # free-node indices (the mesh's topology)


def _solve(container, height_m: float, k2_sample: float) -> _Solve:
    cav = container.cavity
    volume = cav.volume_below_m3(height_m)
    mesh = container.liquid_mesh(volume)
    # per unit density; its Laplacian and wall load on the free nodes, sliced once
    flow = unit_potential_flow(wall_coupling(mesh.nodes_m, mesh.tets, mesh.free_surface, container.basis_shapes_at))
    ma, slip, lu, free = flow.added_mass(1.0), flow.slip, flow.lu, flow.free
    H = flow.laplace_free.tocsr()
    Q0 = liquid_mass_matrix(mesh.nodes_m, mesh.tets)[free][:, free].tocsr()
    if k2_sample > 0.0:
        # c = 1 m/s: eigenvalues are k^2 and the modes Q0-normalized; a fixed start vector keeps
        # the table's bytes independent of what ARPACK ran before in this process.
        k2, psi = liquid_modes(H, Q0, 1.0, math.sqrt(k2_sample) / (2 * math.pi), lu, v0=np.ones(H.shape[0]),
                               max_modes=MAX_LIQUID_MODES * MODE_MARGIN**3)  # sampled past the cut
    else:
        k2, psi = np.zeros(0), np.zeros((H.shape[0], 0))
    mass, centre, inertia = p2_mass_properties(mesh.nodes_m, mesh.tets, 1.0)
    return _Solve(height_m, volume, ma, slip, H, Q0, np.ascontiguousarray(flow.load_free), psi, k2,
                  centre, inertia / mass, free)


def _lagrange_weights(x: float, nodes: np.ndarray) -> tuple[int, np.ndarray]:
    """(first index, 4 weights) of the cubic through the four grid heights nearest ``x``."""
    n = len(nodes) - 1  # intervals (>= 3)
    step = (nodes[-1] - nodes[0]) / n
    i = int(np.clip(math.floor((x - nodes[0]) / step), 0, n - 1))
    j0 = min(max(i - 1, 0), n - 3)
    xs = nodes[j0:j0 + 4]
    w = np.ones(4)
    for a in range(4):
        for b in range(4):
            if a != b:
                w[a] *= (x - xs[b]) / (xs[a] - xs[b])
    return j0, w


#: A segment's interpolated matrices, in :meth:`_Segment.at`'s order.
_MATRICES = ("ma", "slip", "laplace", "mass", "load", "centre_m", "inertia_per_kg")
#: What the liquid's body (mass, centre of mass, inertia) needs of them.
_BODY = ("centre_m", "inertia_per_kg")


@dataclasses.dataclass
class _Segment:
    """The table of one layer count: grid heights and the matrices at each."""

    heights_m: np.ndarray   # (n + 1,) uniform grid
    ma: np.ndarray          # (n + 1, nb, nb)
    slip: np.ndarray        # (n + 1, nb, nb)
    laplace: np.ndarray     # (n + 1, r, r) h V^T H V (the axial gradients scale as 1 / h: smooth in h)
    mass: np.ndarray        # (n + 1, r, r) V^T Q0 V / h
    load: np.ndarray        # (n + 1, r, nb) V^T C
    centre_m: np.ndarray    # (n + 1, 3)
    inertia_per_kg: np.ndarray  # (n + 1, 3, 3)

    @classmethod
    def of(cls, solves: list[_Solve]) -> "_Segment":
        if len({len(s.free) for s in solves}) != 1 or len({s.laplace.shape for s in solves}) != 1:
            raise AssertionError("a segment's liquid meshes differ in topology")
        cols = [s.modes / np.linalg.norm(s.modes, axis=0) for s in solves if s.modes.shape[1]]
        if cols:
            U, sv, _ = np.linalg.svd(np.concatenate(cols, axis=1), full_matrices=False)
            V = U[:, sv > RITZ_RTOL * sv[0]]
        else:
            V = np.zeros((solves[0].laplace.shape[0], 0))
        return cls(np.array([s.height_m for s in solves]), np.stack([s.ma for s in solves]),
                   np.stack([s.slip for s in solves]), np.stack([s.height_m * (V.T @ (s.laplace @ V)) for s in solves]),
                   np.stack([V.T @ (s.mass @ V) / s.height_m for s in solves]), np.stack([V.T @ s.load for s in solves]),
                   np.stack([s.centre_m for s in solves]), np.stack([s.inertia_per_kg for s in solves]))

    @classmethod
    def empty(cls, lo: float, hi: float, like: "_Segment") -> "_Segment":
        """A segment the table does not cover (its heights take the exact solve): only its ends."""
        return cls(np.array([lo, hi]), *(np.zeros((0,) + getattr(like, f.name).shape[1:])
                                         for f in dataclasses.fields(cls)[1:]))

    def at(self, height_m: float, names=_MATRICES) -> dict:
        """The matrices ``names`` (default every one) interpolated to ``height_m`` (each on its
        own: a subset's are the same numbers as in the whole set)."""
        j0, w = _lagrange_weights(height_m, self.heights_m)
        out = {name: np.tensordot(w, getattr(self, name)[j0:j0 + 4], axes=1) for name in names}
        if "laplace" in out:
            out["laplace"] /= height_m
        if "mass" in out:
            out["mass"] *= height_m
        return out

    def arrays(self, prefix: str) -> dict:
        return {prefix + f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


class FillTable:
    """Per container and liquid: the wet model of any upright fill from interpolated matrices.

    Build with :func:`fill_table` (memoized, disk-cached). :meth:`filled` gives the
    :class:`~sensors.fluid.FilledModalModel` of a fill within :data:`GRID_RTOL` (measured at the
    grid's midpoints) of the exact solve's wet frequencies.
    """

    def __init__(self, liquid, segments: list[_Segment], element_height_m: float, depth_m: float,
                 grid_error: float, film: _Segment):
        self.liquid = liquid
        #: The segments by layer count (2, 3, ...), from ``FIRST_HEIGHT_FRACTION`` of an element height up.
        self.segments = segments
        #: The films below the first segment, down to ``FILM_HEIGHT_FRACTION`` of an element height
        #: (a table's cache key hashes this code: no table without one loads).
        self.film = film
        #: The cavity's depth [m] (the highest fill).
        self.depth_m = float(depth_m)
        #: The largest wet-frequency error measured at the grid's midpoints (both liquid models).
        self.grid_error = float(grid_error)
        #: The liquid mesh's axial element size [m]: segment k holds the heights of k layers.
        self.element_height_m = float(element_height_m)

    @property
    def all_segments(self) -> list[_Segment]:
        """The film segment and the layer segments, from the lowest heights up."""
        return [self.film, *self.segments]

    @property
    def min_height_m(self) -> float:
        """The lowest fill height [m] the table covers."""
        return float(self.all_segments[0].heights_m[0])

    @property
    def grid_heights_m(self) -> np.ndarray:
        """Every grid height [m] of the table (exact solves)."""
        return np.concatenate([s.heights_m for s in self.all_segments])

    def covers(self, height_m: float) -> bool:
        """Whether a fill ``height_m`` high is in the table (outside: the exact solve)."""
        return (self.min_height_m <= height_m <= self.depth_m * (1 + 1e-12)
                and len(self._segment(height_m).ma) > 0)

    @property
    def exact_ranges_m(self) -> list[tuple[float, float]]:
        """Height ranges [m] the table leaves to the exact solve (its grid did not reach
        :data:`GRID_RTOL` within :data:`MAX_INTERVALS`)."""
        return [(float(s.heights_m[0]), float(s.heights_m[-1])) for s in self.all_segments if len(s.ma) == 0]

    def _segment(self, height_m: float) -> _Segment:
        if height_m < self.segments[0].heights_m[0]:
            return self.film
        k = max(2, math.ceil(height_m / self.element_height_m - 1e-9))
        return self.segments[min(k - 2, len(self.segments) - 1)]

    def filled(self, container, liquid, volume_m3: float, *, compressible: bool = True) -> FilledModalModel:
        """The wet model of ``volume_m3`` of ``liquid`` (of the table's density and speed of sound;
        its viscosity is its own) in ``container`` (the one the table was made for), upright."""
        if (liquid.density_kg_m3, liquid.speed_of_sound_m_per_s) != (self.liquid.density_kg_m3,
                                                                      self.liquid.speed_of_sound_m_per_s):
            raise ValueError(f"{liquid.name} is not the liquid of this table ({self.liquid.name})")
        height = container.cavity.height_below_m(volume_m3)
        if not self.covers(height):
            raise ValueError(f"a fill {height * 1e3:.4g} mm high is outside the table's "
                             f"{self.min_height_m * 1e3:.4g} mm .. {self.depth_m * 1e3:.4g} mm")
        segment = self._segment(height)
        if LAZY_WET_MATRICES:
            body = _liquid_body(container, liquid, segment.at(height, _BODY), volume_m3, height)
            wet = FilledModalModel.pending(container, body, compressible,   # a partial: picklable
                                           functools.partial(_segment_matrices, container, liquid, segment, height,
                                                             compressible))
        else:
            wet = wet_model(container, liquid, segment.at(height), volume_m3, height, compressible)
        wet.metadata["wet_solve"] = "interpolated"  # the exact path's models carry no such entry
        return wet


def _k2_cut(container, liquid) -> float:
    """The liquid's wavenumber^2 cut [1/m^2]: modes up to twice the band limit (as the exact path)."""
    c = liquid.speed_of_sound_m_per_s
    if not math.isfinite(c):
        return 0.0
    return (2 * math.pi * LIQUID_MODES_BAND_FACTOR * container.band_limit_hz / c) ** 2


def _liquid_body(container, liquid, m: dict, volume_m3: float, height_m: float) -> LiquidBody:
    """The liquid's :class:`LiquidBody` of interpolated (or exact) ``m`` (``centre_m``, ``inertia_per_kg``)."""
    cav = container.cavity
    up = container.up_axis
    mass = liquid.density_kg_m3 * volume_m3
    offset = float(up @ cav.origin_m) + float(cav.axial_m[0]) + height_m
    return LiquidBody(liquid, volume_m3, mass, np.asarray(m["centre_m"], float), mass * m["inertia_per_kg"], up.copy(),
                      offset)


def wet_model(container, liquid, m: dict, volume_m3: float, height_m: float, compressible: bool) -> FilledModalModel:
    """The :class:`FilledModalModel` of interpolated (or exact) matrices ``m`` (as :meth:`_Segment.at`)."""
    body = _liquid_body(container, liquid, m, volume_m3, height_m)
    ma, slip, coupling, eigenvalues = _wall_matrices(container, liquid, m, compressible)
    return FilledModalModel(container, body, ma, slip, liquid_coupling=coupling, liquid_eigenvalues=eigenvalues,
                            compressible=compressible)


def _segment_matrices(container, liquid, segment: _Segment, height_m: float, compressible: bool) -> tuple:
    """:func:`_wall_matrices` of ``segment`` interpolated to ``height_m``."""
    return _wall_matrices(container, liquid, segment.at(height_m), compressible)


def _wall_matrices(container, liquid, m: dict, compressible: bool) -> tuple:
    """``(added_mass, slip, liquid_coupling, liquid_eigenvalues)`` of ``m`` as
    :class:`FilledModalModel` takes them (the last two None for an incompressible liquid)."""
    rho = liquid.density_kg_m3
    ma = rho * m["ma"]
    ma = 0.5 * (ma + ma.T)
    slip = 0.5 * (m["slip"] + m["slip"].T)
    if not compressible:
        return ma, slip, None, None
    k2, B = liquid_coupling(m["laplace"], m["mass"], m["load"], _k2_cut(container, liquid))
    c = liquid.speed_of_sound_m_per_s
    return ma, slip, math.sqrt(rho) * B, c * c * k2


def liquid_coupling(laplace_r, mass_r, load_r, k2_cut: float):
    """The liquid's modes on the Ritz basis up to ``k2_cut``: (k^2 (m,), B0 (nb, m) = C^T psi / k)."""
    nb = load_r.shape[1]
    if k2_cut <= 0.0 or laplace_r.shape[0] == 0:
        return np.zeros(0), np.zeros((nb, 0))
    k2, Y = scipy.linalg.eigh(0.5 * (laplace_r + laplace_r.T), 0.5 * (mass_r + mass_r.T))
    keep = (k2 > 0.0) & (k2 <= k2_cut)
    k2, Y = k2[keep], Y[:, keep]
    return k2, (load_r.T @ Y) / np.sqrt(k2)[None, :]


def _exact(container, liquid, s: _Solve, compressible: bool) -> FilledModalModel:
    """The exact wet model of a solve (the same numbers as the exact path's)."""
    m = {"ma": s.ma, "slip": s.slip, "centre_m": s.centre_m, "inertia_per_kg": s.inertia_per_kg}
    if not compressible:
        return wet_model(container, liquid, m, s.volume_m3, s.height_m, False)
    keep = s.k2 <= _k2_cut(container, liquid)
    k2, psi = s.k2[keep], s.modes[:, keep]
    rho, c = liquid.density_kg_m3, liquid.speed_of_sound_m_per_s
    B = math.sqrt(rho) * (s.load.T @ psi) / np.sqrt(k2)[None, :] if len(k2) else np.zeros((s.ma.shape[0], 0))
    body = wet_model(container, liquid, m, s.volume_m3, s.height_m, False).liquid
    return FilledModalModel(container, body, rho * s.ma, s.slip, liquid_coupling=B, liquid_eigenvalues=c * c * k2,
                            compressible=True)


def frequency_error(a: FilledModalModel, b: FilledModalModel) -> float:
    """Largest relative difference of the wet frequencies both models keep."""
    n = min(a.n_modes, b.n_modes)
    if n == 0:
        return 0.0
    return float(np.max(np.abs(a.frequencies_hz[:n] - b.frequencies_hz[:n]) / b.frequencies_hz[:n]))


def _grid(lo: float, hi: float, n: int) -> np.ndarray:
    return lo + (hi - lo) * np.arange(n + 1) / n


def _refined_segment(container, liquid, lo: float, hi: float, k2_sample: float, progress, what: str):
    """(segment, its midpoint error) of the heights ``lo`` .. ``hi`` (one liquid-mesh topology):
    intervals halved from 3 until the wet frequencies at the midpoints are within
    :data:`GRID_RTOL` of the exact solve (both liquid models); an empty segment (the exact solve)
    if that takes more than :data:`MAX_INTERVALS` or the error does not halve."""
    n, prev_err = 3, math.inf
    solves = {}
    while True:
        heights = _grid(lo, hi, n)
        for h in heights:
            if h not in solves:
                solves[h] = _solve(container, float(h), k2_sample)
        seg = _Segment.of([solves[h] for h in heights])
        err = 0.0
        for h in _grid(lo, hi, 2 * n)[1::2]:  # the midpoints, as the next grid spells them
            s = solves[h] = solves.get(h) or _solve(container, float(h), k2_sample)
            m = seg.at(float(h))
            for comp in (False, True):
                fast = wet_model(container, liquid, m, s.volume_m3, s.height_m, comp)
                err = max(err, frequency_error(fast, _exact(container, liquid, s, comp)))
        if progress:
            progress(f"fill table {container.name}: {what}, {n} intervals, error {err:.2e}")
        if err <= GRID_RTOL:
            return seg, err
        # A cubic's error falls ~16x per halving; one that does not halve is not the grid's
        # (the wall load's kinks where the surface crosses small dry elements, a bottle's neck).
        if 2 * n > MAX_INTERVALS or err > 0.5 * prev_err:
            # Not smooth enough here (a liquid mode crossing the cut, a kink of the profile):
            # these heights keep the exact solve rather than a table outside its tolerance.
            if progress:
                progress(f"fill table {container.name}: {what} left to the exact solve")
            return _Segment.empty(lo, hi, seg), err
        n, prev_err = 2 * n, err


def _build(container, liquid, max_solves: int, progress=None) -> FillTable:
    cav = container.cavity
    depth = cav.depth_m
    h_el = container.liquid_element_size_m or 2 * math.pi * float(cav.radius_m.max()) / container.liquid_n_theta
    n_segments = max(1, math.ceil(depth / h_el - 1e-9) - 1)
    # Worst case per segment (and the films') at MAX_INTERVALS: its grid and the checks at its midpoints.
    worst = (n_segments + 1) * (2 * MAX_INTERVALS + 1)
    if worst > max_solves:
        raise FillTableCostError(
            f"the fill table of {container.name} would take up to {worst} exact fill solves ({n_segments} layer "
            f"counts and the films x up to {2 * MAX_INTERVALS + 1}, liquid element height {h_el * 1e3:.3g} mm), above the limit "
            f"of {max_solves}: raise max_solves= of sensors.fluid.fill_table.fill_table (default "
            f"MAX_TABLE_SOLVES), give a larger liquid_element_size_m, or fill with interpolated=False")
    # Once per container and liquid (then from disk): say why the first fill waits.
    log.info("building the fill table of %s (once, cached on disk): up to %d exact fill solves; "
             "interpolated=False (FillLevel-v0: interpolated_fill=False) solves each fill instead",
             container.name, worst)
    k2_cut = _k2_cut(container, liquid)
    k2_sample = k2_cut * MODE_MARGIN**2
    segments, worst_err = [], 0.0
    for k in range(2, n_segments + 2):
        lo = FIRST_HEIGHT_FRACTION * h_el if k == 2 else (k - 1 + 1e-6) * h_el
        hi = min(k * h_el, depth)
        if k == n_segments + 1:
            hi = depth
        seg, err = _refined_segment(container, liquid, lo, hi, k2_sample, progress, f"{k} layers")
        if len(seg.heights_m) > 2:
            worst_err = max(worst_err, err)
        segments.append(seg)
    # after the layer segments, so that their bytes are those of a table without films
    film, err = _refined_segment(container, liquid, FILM_HEIGHT_FRACTION * h_el, FIRST_HEIGHT_FRACTION * h_el,
                                 k2_sample, progress, "films")
    if len(film.heights_m) > 2:
        worst_err = max(worst_err, err)
    return FillTable(liquid, segments, h_el, depth, worst_err, film)


def _key(container, liquid) -> str:
    return cache_mod.content_key(
        "fluid fill table", container.cache_key, container.liquid_n_theta, container.liquid_element_size_m,
        container.band_limit_hz, liquid.density_kg_m3, str(liquid.speed_of_sound_m_per_s), GRID_RTOL, MAX_INTERVALS,
        MODE_MARGIN, RITZ_RTOL, FIRST_HEIGHT_FRACTION, FILM_HEIGHT_FRACTION,
        cache_mod.source_version("sensors.fluid.fill_table", "sensors.fluid.acoustic", "sensors.fluid.added_mass",
                                 "sensors.fluid.cavity", "sensors.fluid.filled_model", "sensors.fluid.container"))


def fill_table(container, liquid, *, max_solves: int = MAX_TABLE_SOLVES, progress=None) -> FillTable:
    """The :class:`FillTable` of an axisymmetric ``container`` and a
    :class:`~sensors.materials.liquids.Liquid` (memoized in ``container.fill_tables``, disk-cached
    unless the container was made with ``cache=False``).

    Raises:
        FillTableCostError: the build could take more than ``max_solves`` exact fill solves
            (estimated before any).
        TypeError: the container's cavity is not axisymmetric.
    """
    if not isinstance(container.cavity, AxisymmetricCavity):
        raise TypeError("a fill table needs an axisymmetric cavity")

    def load() -> FillTable:
        key = _key(container, liquid)
        h_el = container.liquid_element_size_m or (
            2 * math.pi * float(container.cavity.radius_m.max()) / container.liquid_n_theta)
        hit = cache_mod.load_arrays(key, container.cache_dir) if container.cache else None
        if hit is None and container.cache:
            with cache_mod.build_lock(key, container.cache_dir):
                hit = cache_mod.load_arrays(key, container.cache_dir)
                if hit is None:
                    table = _build(container, liquid, max_solves, progress)
                    arrays = {"grid_error": np.array(table.grid_error)}
                    for i, seg in enumerate(table.segments):
                        arrays.update(seg.arrays(f"s{i}_"))
                    arrays.update(table.film.arrays("film_"))
                    cache_mod.save_arrays(key, arrays, container.cache_dir)
                    hit = arrays
        if hit is None:
            return _build(container, liquid, max_solves, progress)
        def segment(prefix: str) -> _Segment:
            return _Segment(**{f.name: np.asarray(hit[prefix + f.name]) for f in dataclasses.fields(_Segment)})

        segments, i = [], 0
        while f"s{i}_heights_m" in hit:
            segments.append(segment(f"s{i}_"))
            i += 1
        return FillTable(liquid, segments, h_el, container.cavity.depth_m, float(hit["grid_error"]), segment("film_"))

    return container.fill_tables.get_or_build((liquid.density_kg_m3, liquid.speed_of_sound_m_per_s), load)
