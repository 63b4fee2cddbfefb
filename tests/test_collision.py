"""CoACD collision pieces: convex, covering the solid, cached; mass properties of the solid."""

import numpy as np
import pytest
import trimesh

from aas_gym.collision import collision_geometry, mass_properties
from sensors.objects import get_object


@pytest.fixture(scope="module")
def bracket_geometry(tmp_path_factory):
    obj = get_object("l_bracket").solid()
    cache = tmp_path_factory.mktemp("cache")
    return obj, cache, collision_geometry(obj.surface, obj.material, cache_dir=cache)


def test_pieces_are_convex_and_cover_the_solid(bracket_geometry):
    obj, _, geom = bracket_geometry
    hulls = [trimesh.convex.convex_hull(p) for p in geom.pieces]
    assert 1 <= len(hulls) <= 64
    for piece, hull in zip(geom.pieces, hulls):
        assert len(hull.vertices) == len(piece), "every vertex of a piece is a hull vertex"
    rng = np.random.default_rng(0)
    lo, hi = obj.surface.bounds
    pts = rng.uniform(lo, hi, size=(20000, 3))
    inside = obj.surface.contains(pts)
    covered = np.zeros(len(pts), bool)
    for hull in hulls:
        covered |= hull.contains(pts)
    assert covered[inside].mean() > 0.97, "the pieces cover the solid"
    # ... and do not bloat it (an L's convex hull would be 6x its volume).
    assert sum(h.volume for h in hulls) < 1.25 * obj.surface.volume


def test_second_call_is_a_cache_hit_with_identical_pieces(bracket_geometry):
    obj, cache, geom = bracket_geometry
    again = collision_geometry(obj.surface, obj.material, cache_dir=cache)
    assert again.build_time_s == 0.0
    assert all(np.array_equal(a, b) for a, b in zip(geom.pieces, again.pieces))
    assert len(again.mjcf_mesh_vertices()) == len(geom.pieces)


def test_mass_properties_of_a_box_match_the_closed_form():
    a, b, c, rho = 0.04, 0.03, 0.02, 2700.0
    mass, com, inertia = mass_properties(trimesh.creation.box((a, b, c)), rho)
    m = rho * a * b * c
    assert mass == pytest.approx(m)
    np.testing.assert_allclose(com, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.diag(inertia), m / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b]),
                               rtol=1e-9)
