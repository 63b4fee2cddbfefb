"""``aas_gym.touching_grasp.on_solid`` on a bar: the distance to its box (``BOX_DISTANCE``, the
default) against the faceted surface's (the reference): the same distances to rounding, the
same contacts kept, the same features of an env's probes bit for bit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import touching_grasp
from aas_gym.touching_grasp import box_distance_m, box_half_extents_m, on_solid
from sensors import Contact
from sensors.modal import with_material
from sensors.modal.damping import MAX_SURFACE_DISTANCE_M
from sensors.objects.catalog import get_object

BARS = ("aluminium_bar", "steel_bar", "wood_bar")


def _points_about_the_surface(half: np.ndarray, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Points on random faces, edges and corners, moved up to 4 mm in or out along each axis."""
    p = rng.uniform(-1.0, 1.0, (n, 3)) * half
    for k in range(n):                     # 1, 2 or 3 coordinates on a face: face, edge, corner
        axes = rng.choice(3, size=1 + k % 3, replace=False)
        p[k, axes] = np.sign(rng.uniform(-1, 1, axes.size)) * half[axes]
    return p + rng.uniform(-4e-3, 4e-3, (n, 3))


@pytest.mark.parametrize("name", BARS)
def test_box_distance_is_the_faceted_surfaces(name):
    model = get_object(name).modal_model()
    half = box_half_extents_m(model)
    # the box is the mesh's own bounds (independent of the dimensions it was read from)
    np.testing.assert_allclose(half, np.ptp(model.nodes_m, axis=0) / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(model.nodes_m.min(axis=0), -half, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(box_half_extents_m(with_material(model, "steel" if "steel" not in name
                                                                   else "aluminium")), half)
    points = _points_about_the_surface(half, np.random.default_rng(0))
    faceted = np.abs(model.surface_distance_m(points))
    box = box_distance_m(points, half)
    np.testing.assert_allclose(box, faceted, rtol=0, atol=1e-12)
    assert (faceted > MAX_SURFACE_DISTANCE_M).sum() > 20 and (faceted <= MAX_SURFACE_DISTANCE_M).sum() > 100
    contacts = [Contact(p, (0.0, 0.0, 1.0), 1.0, 0.5) for p in points]
    kept = on_solid(model, contacts)
    touching_grasp.BOX_DISTANCE = False
    try:
        reference = on_solid(model, contacts)
    finally:
        touching_grasp.BOX_DISTANCE = True
    assert [id(c) for c in kept] == [id(c) for c in reference]


def test_other_models_ask_their_surface():
    assert box_half_extents_m(get_object("aluminium_tube").modal_model()) is None


def _probe_features(n_episodes: int) -> list:
    """Each reset's probe (GraspPosition-v0 grasps and records in its reset): the features' bytes
    and whether the grasp held."""
    env = gym.make("aas_gym/GraspPosition-v0", disable_env_checker=True)
    obs, info = env.reset(seed=3)
    out = []
    for _ in range(n_episodes):
        out.append((obs["acoustic"].tobytes(), info["grasp_success"]))
        obs, info = env.reset()
    env.close()
    return out


def test_probes_hear_the_same_with_the_box_distance_and_the_surface():
    fast = _probe_features(12)
    touching_grasp.BOX_DISTANCE = False
    try:
        reference = _probe_features(12)
    finally:
        touching_grasp.BOX_DISTANCE = True
    assert sum(success for _, success in fast) >= 6     # probes that heard a grasp were compared
    assert fast == reference
