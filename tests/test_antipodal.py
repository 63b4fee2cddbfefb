"""Antipodal grasps satisfy their constraints, are reproducible, and span a grasp path."""

import math

import numpy as np
import pytest
import trimesh

from aas_gym.antipodal import grasp_path, sample_antipodal_grasps
from sensors.objects import get_object
from sensors.task.grasp import MAX_OPENING_M


def check_constraints(surface, grasps, friction, up, max_tilt_rad):
    cos_cone = math.cos(math.atan(friction))
    for g in grasps:
        p1, p2 = g.contacts_m
        assert 0.002 <= g.width_m <= MAX_OPENING_M
        assert np.linalg.norm(g.axis) == pytest.approx(1.0)
        _, dist, face = trimesh.proximity.closest_point(surface, np.array([p1, p2]))
        assert dist.max() < 1e-4 * np.ptp(surface.vertices, axis=0).max()
        n1, n2 = surface.face_normals[face]
        assert -n1 @ g.axis >= cos_cone - 1e-9 and n2 @ g.axis >= cos_cone - 1e-9, "inside the friction cone"
        assert abs(g.axis @ up) <= math.sin(max_tilt_rad) + 1e-9, "grasp axis roughly horizontal"
        assert 0.0 <= g.quality <= 1.0


def test_box_grasps_only_across_the_side_that_fits_the_hand():
    surface = trimesh.creation.box((0.04, 0.12, 0.03))
    grasps = sample_antipodal_grasps(surface, np.random.default_rng(1), n_grasps=30, friction=0.3)
    assert len(grasps) == 30
    check_constraints(surface, grasps, 0.3, np.array([0, 0, 1.0]), math.radians(20))
    for g in grasps:  # the 0.12 m side is too wide, z is vertical: only across x
        assert abs(abs(g.axis[0]) - 1) < 1e-9 and g.width_m == pytest.approx(0.04)


@pytest.mark.parametrize("name", ["mug", "spoon", "l_bracket"])
def test_everyday_grasps_satisfy_constraints_and_are_reproducible(name):
    obj = get_object(name).solid()
    up = np.asarray(obj.up_axis)
    a = sample_antipodal_grasps(obj.surface, np.random.default_rng(7), n_grasps=10, friction=0.5, up=up)
    b = sample_antipodal_grasps(obj.surface, np.random.default_rng(7), n_grasps=10, friction=0.5, up=up)
    c = sample_antipodal_grasps(obj.surface, np.random.default_rng(8), n_grasps=10, friction=0.5, up=up)
    assert len(a) == 10
    check_constraints(obj.surface, a, 0.5, up, math.radians(20))
    assert all(np.array_equal(x.centre_m, y.centre_m) and x.width_m == y.width_m for x, y in zip(a, b))
    assert any(not np.array_equal(x.centre_m, y.centre_m) for x, y in zip(a, c))


def test_blocked_from_above_is_rejected():
    # A bar under a roof: its sides are reachable only if nothing is above them.
    bar = trimesh.creation.box((0.02, 0.1, 0.02))
    roof = trimesh.creation.box((0.08, 0.04, 0.005))
    roof.apply_translation([0.0, 0.0, 0.03])
    post = trimesh.creation.box((0.005, 0.04, 0.02))
    post.apply_translation([0.0, 0.0, 0.018])
    solid = trimesh.boolean.union([bar, roof, post], engine="manifold")
    grasps = sample_antipodal_grasps(solid, np.random.default_rng(0), n_grasps=10_000, friction=0.3)
    bar_grasps = [g for g in grasps if g.centre_m[2] < 0.01]
    assert bar_grasps, "the bar's free ends are graspable"
    assert all(abs(g.centre_m[1]) > 0.02 - 1e-3 for g in bar_grasps), "nothing under the roof"


def test_grasp_path_spans_the_long_axis_and_measures_positions():
    obj = get_object("spoon").solid()
    grasps = sample_antipodal_grasps(obj.surface, np.random.default_rng(3), n_grasps=40, up=obj.up_axis)
    path = grasp_path(obj.surface, grasps)
    assert abs(path.direction[0]) > 0.99, "principal axis of a spoon is its length"
    assert 0.1 < path.length_m < 0.25
    s = np.array([0.0, 0.5 * path.length_m, path.length_m])
    np.testing.assert_allclose(path.position_of(path.point(s)), s, atol=1e-12)
