"""``TetLocator.within_surface_distance``: bounds from the nearest face centroid settle most
points, with the same decisions as the full closest-surface query (``CENTROID_BOUNDS`` False, the
reference) and as the nearest of all faces; FillLevel-v0's probes (``on_solid`` on the mug)
hear the same bit for bit with the bounds on and off."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import touching_grasp
from aas_gym.touching_grasp import on_solid
from sensors.mesh import locator as locator_mod
from sensors.mesh.locator import TetLocator
from sensors.modal import damping
from sensors.modal.damping import MAX_SURFACE_DISTANCE_M
from sensors.objects.catalog import get_object

LIMIT_M = MAX_SURFACE_DISTANCE_M


@pytest.fixture(scope="module", params=("mug", "bottle"))
def model(request):
    return get_object(request.param).modal_model()


def _points_about_the_surface(loc: TetLocator, rng: np.random.Generator, n: int = 3000) -> np.ndarray:
    """Points on random boundary faces moved up to 6 mm in random directions, and as many moved
    from their closest surface point to within 1e-12 .. 1e-6 of the limit's distance."""
    tri = loc.surface_data()["tri"]
    face = rng.integers(len(tri), size=n)
    w = rng.dirichlet(np.ones(3), size=n)
    on = np.einsum("pk,pkx->px", w, tri[face])
    step = rng.normal(size=(n, 3))
    step *= (rng.uniform(0, 6e-3, n) / np.linalg.norm(step, axis=1))[:, None]
    off = on + step
    q, _, d = TetLocator(loc.nodes_m, loc.elements).closest_surface(off)
    sign = rng.choice([-1.0, 1.0], size=n)
    target = LIMIT_M * (1 + sign * 10.0 ** rng.uniform(-12, -6, n))
    near = q + (off - q) * (target / np.where(d > 0, d, 1.0))[:, None]
    return np.concatenate([off, near[d > 1e-6]])


def _brute_force_distance_m(tri: np.ndarray, point: np.ndarray) -> float:
    """Distance from one point to the nearest of all triangles (m, 3, 3), written independently of
    the locator: the foot of the perpendicular where it falls inside a triangle, else the nearest
    point of its three edges."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    foot = point - np.einsum("ij,ij->i", point - a, n)[:, None] * n
    inside = np.ones(len(tri), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):          # the foot on the inner side of every edge
        inside &= np.einsum("ij,ij->i", np.cross(v - u, foot - u), n) >= 0
    best = np.where(inside, np.linalg.norm(point - foot, axis=1), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        t = np.clip(np.einsum("ij,ij->i", point - u, v - u) / np.einsum("ij,ij->i", v - u, v - u), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(point - (u + t[:, None] * (v - u)), axis=1))
    return float(best.min())


def test_bounds_decide_as_the_full_query(model, monkeypatch):
    loc = model.locator
    points = _points_about_the_surface(loc, np.random.default_rng(7))
    asked = []
    full = TetLocator.closest_surface

    def counted(self, p):
        asked.append(len(p))
        return full(self, p)

    monkeypatch.setattr(TetLocator, "closest_surface", counted)
    fast = TetLocator(loc.nodes_m, loc.elements).within_surface_distance(points, LIMIT_M)
    n_full = sum(asked)
    monkeypatch.setattr(locator_mod, "CENTROID_BOUNDS", False)
    reference = TetLocator(loc.nodes_m, loc.elements).within_surface_distance(points, LIMIT_M)
    np.testing.assert_array_equal(fast, reference)
    # both decisions occur near the limit, and the bounds settled most points on their own
    d = TetLocator(loc.nodes_m, loc.elements).closest_surface(points)[2]
    close = np.abs(d - LIMIT_M) < 1e-6
    assert close.sum() > 1000 and 0 < reference[close].sum() < close.sum()
    assert n_full < 0.7 * len(points)
    # against the nearest of all faces, on points where round-off cannot decide
    tri = loc.surface_data()["tri"]
    some = np.flatnonzero(np.abs(d - LIMIT_M) > 1e-10)[::20]
    brute = np.array([_brute_force_distance_m(tri, points[i]) for i in some])
    np.testing.assert_array_equal(fast[some], brute <= LIMIT_M)


def test_far_points_are_rejected_by_the_lower_bound(model, monkeypatch):
    loc = TetLocator(model.nodes_m, model.elements)
    far = np.random.default_rng(1).normal(size=(200, 3))
    far *= (np.ptp(model.nodes_m, axis=0).max() + 0.05) / np.linalg.norm(far, axis=1)[:, None]
    monkeypatch.setattr(TetLocator, "closest_surface", lambda self, p: pytest.fail("the bounds settle far points"))
    assert not loc.within_surface_distance(far, LIMIT_M).any()


def _probes(env_id: str, n_episodes: int, monkeypatch) -> tuple[list, list]:
    """An env's features and whether it heard a grasp, per seeded episode (random actions from
    a seeded action space); the contacts each ``on_solid`` call kept (their positions' bytes)."""
    kept = []

    def recorded(model, contacts):
        out = on_solid(model, contacts)
        kept.append(b"".join(np.asarray(c.position_m, dtype=float).tobytes() for c in out))
        return out

    monkeypatch.setattr(touching_grasp, "on_solid", recorded)
    env = gym.make(env_id, disable_env_checker=True)
    env.action_space.seed(3)
    obs, info = env.reset(seed=5)
    heard = []
    for _ in range(n_episodes):
        heard.append((obs["acoustic"].tobytes(), info["recording_grasped"]))
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(env.action_space.sample())
            heard.append((obs["acoustic"].tobytes(), None))
            done = terminated or truncated
        obs, info = env.reset()
    env.close()
    return heard, kept


@pytest.mark.parametrize("env_id, n_episodes", [("aas_gym/FillLevel-v0", 8), ("aas_gym/GraspPosition-v0", 3)])
def test_probes_hear_the_same_with_and_without_the_bounds(env_id, n_episodes, monkeypatch):
    """Both surface questions of a probe (``on_solid``'s and the synthesis's check) answered by
    bounds, and both by every point's full distance: the same contacts kept, the same bytes heard."""
    fast = _probes(env_id, n_episodes, monkeypatch)
    monkeypatch.setattr(locator_mod, "CENTROID_BOUNDS", False)
    monkeypatch.setattr(damping, "ASK_WITHIN", False)
    reference = _probes(env_id, n_episodes, monkeypatch)
    assert sum(bool(success) for _, success in fast[0]) >= 3 and len(fast[1]) >= n_episodes
    assert fast == reference
