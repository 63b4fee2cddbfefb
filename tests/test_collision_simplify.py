"""CoACD on a simplified surface (issue 30): the simplification stays closed and within its
tolerance, and the pieces decomposed from it still cover the original solid."""

import numpy as np
import pytest
import trimesh

from aas_gym.collision import COACD_OPTIONS, SIMPLIFY_ABOVE_FACES, SIMPLIFY_TOLERANCE, convex_decomposition, simplified
from convex_coverage import coverage
from sensors.objects import get_object


@pytest.fixture(scope="module")
def glass():
    surface = get_object("glass").solid().surface
    assert len(surface.faces) > SIMPLIFY_ABOVE_FACES  # the path under test
    return surface


def test_simplified_surface_is_closed_and_within_tolerance(glass):
    tol = SIMPLIFY_TOLERANCE * float(np.linalg.norm(np.ptp(glass.vertices, axis=0)))
    v, f = simplified(glass.vertices, glass.faces, tol)
    coarse = trimesh.Trimesh(v, f, process=False)
    assert coarse.is_watertight and coarse.is_winding_consistent
    assert len(f) < len(glass.faces) / 5
    # Both ways: the coarse surface near the fine one and the fine one near the coarse one.
    rng = np.random.default_rng(0)
    fine_points = trimesh.sample.sample_surface(glass, 2000, seed=rng)[0]
    coarse_points = np.concatenate([v, trimesh.sample.sample_surface(coarse, 2000, seed=rng)[0]])
    assert trimesh.proximity.closest_point(coarse, fine_points)[1].max() <= 1.5 * tol
    assert trimesh.proximity.closest_point(glass, coarse_points)[1].max() <= 1.5 * tol
    assert coarse.volume == pytest.approx(glass.volume, rel=0.02)


def test_pieces_of_a_simplified_surface_cover_the_original_solid(glass, tmp_path):
    pieces, _ = convex_decomposition(glass, cache_dir=tmp_path)
    assert 1 <= len(pieces) <= COACD_OPTIONS["max_convex_hull"]
    lo, hi = glass.bounds
    points = np.random.default_rng(1).uniform(lo, hi, size=(4000, 3))
    # In chunks: trimesh's ray test on the 30k-face glass holds every ray's candidates at once
    # (4.8 GB for 4000 points in one call, 0.8 GB in eight).
    inside = points[np.concatenate([glass.contains(chunk) for chunk in np.array_split(points, 8)])]
    covered, volume = coverage(pieces, inside)
    assert covered > 0.97, "the pieces cover the original (not only the simplified) solid"
    assert volume < 1.4 * glass.volume, "and do not bloat it (the glass's hull would close its cavity)"
    # No piece reaches more than a millimetre outside the original surface.
    outside_m = max(float(np.max(-trimesh.proximity.signed_distance(glass, p))) for p in pieces)
    assert outside_m < 1e-3
