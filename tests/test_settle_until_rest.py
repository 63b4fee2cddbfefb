"""FillLevel-v0's settle may stop once the container rests (``aas_gym.scenario.settle(...,
until_rest=True)`` with ``SETTLE_UNTIL_REST = True``, off by default) and then skip the first
release (the hand far above opening an open hand); ``SETTLE_UNTIL_REST = False`` settles the
whole 0.4 s and releases (the reference, the default).

At rest the skipped steps only tremble the container (1e-11-1e-9 m/s, a limit cycle of the soft
contacts), so the grasped state is the reference's within 4e-12-4e-10 m (seeds 0-11, measured;
asserted 1e-9 m) and the fingertip forces within 2e-9 relative (asserted 1e-6). The closed-form
features of a FillLevel-v0 grasp are far more sensitive to the settle than issue 27's 1e-6 bound:
the reference itself, settled 10 ms longer, moves single features by up to 1e-5 relative (seed
6; 42 % on seed 10, where the container's pose moves 5e-7 m). The early stop moved them by at most
5.1e-5 on seeds 0-9 (7.5e-4 on seed 10): asserted 1e-4 on seeds 0-6. (That the reference's own
sensitivity exceeds 1e-6 is not asserted: on another CPU, seeds 0-6 gave 2.3e-7, the rounding of
a chaotic contact set differing by machine.)
"""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import rest_states, scenario
from aas_gym.envs import base
from grasp_snapshot import grasped_state
from sensors.task import HOME_TCP, MAX_OPENING_M

SEEDS = range(7)


def _grasped(u, seed):
    """Reset (FillLevel-v0 grasps in it) and what it left grasped, with the fill."""
    return grasped_state(u, seed, ("fill_fraction",))


def _feature_error(a, b) -> float:
    return float(np.max(np.abs(a["features"] - b["features"]) / np.abs(b["features"])))


def test_the_settle_stops_at_rest_within_the_whole_settles_own_sensitivity(monkeypatch):
    env = lambda: gym.make("aas_gym/FillLevel-v0", disable_env_checker=True,  # noqa: E731
                           acoustic={"enabled": False}).unwrapped
    fast, reference, longer = env(), env(), env()
    steps, own = [], []
    whole = base.settle

    def counted(m, d, duration_s=0.4, until_rest=False):
        n = whole(m, d, duration_s, until_rest)
        steps.append(n)
        return n

    def settled_longer(m, d, duration_s=0.4, until_rest=False):   # the reference, 10 ms longer
        return whole(m, d, duration_s + 0.01, until_rest)

    monkeypatch.setattr(rest_states, "REST_STATES", False)   # the settles this file compares
    for seed in SEEDS:
        monkeypatch.setattr(scenario, "SETTLE_UNTIL_REST", True)
        monkeypatch.setattr(base, "settle", counted)
        a = _grasped(fast, seed)
        monkeypatch.setattr(scenario, "SETTLE_UNTIL_REST", False)
        monkeypatch.setattr(base, "settle", whole)
        b = _grasped(reference, seed)
        monkeypatch.setattr(base, "settle", settled_longer)
        c = _grasped(longer, seed)
        assert a["fill_fraction"] == b["fill_fraction"] and a["success"] and b["success"]
        for key in ("objects", "hand"):
            np.testing.assert_allclose(a[key], b[key], rtol=0, atol=1e-9)
        assert a["kinds"] == b["kinds"]
        np.testing.assert_allclose(a["points"], b["points"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a["forces"], b["forces"], rtol=1e-6, atol=0)
        assert _feature_error(a, b) <= 1e-4, seed
        own.append(_feature_error(c, b))
    # it stopped early every time (0.4 s is 200 steps), and the first release was skipped
    assert steps and max(steps) < 100, steps
    runs = [k[2] for k in fast._scene.memo._lru._entries]
    assert any(r[0] == "grasp" and r[-1] == "at rest" for r in runs)


@pytest.mark.parametrize("until_rest", [False, True])
def test_the_rest_test_waits_for_a_moving_body(until_rest, monkeypatch):
    """A body still moving at the end of the duration runs the whole duration either way; one
    at rest stops early only with until_rest and the module flag."""
    monkeypatch.setattr(scenario, "SETTLE_UNTIL_REST", True)
    u = gym.make("aas_gym/FillLevel-v0", disable_env_checker=True, acoustic={"enabled": False}).unwrapped
    u.reset(seed=0)
    sc, m, d = u._scene, u.model, u.data
    mujoco.mj_resetData(m, d)                            # the container placed upright, the hand home
    sc.hand.teleport(d, HOME_TCP, MAX_OPENING_M)
    scenario.place_objects(m, d, sc.objects, sc.free_joints, np.random.default_rng(0), u.randomization)
    placed = mujoco.MjData(m)
    mujoco.mj_copyData(placed, m, d)
    v = sc.free_joints[0][1]
    d.qvel[v + 5] = 2.0                                  # spinning about z on the table: slows, still turns
    assert scenario.settle(m, d, 0.1, until_rest=until_rest) == 50
    assert abs(d.qvel[v + 5]) > scenario.REST_SPEED
    mujoco.mj_copyData(d, m, placed)
    n = scenario.settle(m, d, 0.4, until_rest=until_rest)
    assert (n < 200) == until_rest and n >= 25
    assert np.abs(d.qvel[v:v + 6]).max() < (scenario.REST_SPEED if until_rest else 1e-6)
    monkeypatch.setattr(scenario, "SETTLE_UNTIL_REST", False)
    mujoco.mj_copyData(d, m, placed)
    assert scenario.settle(m, d, 0.4, until_rest=until_rest) == 200
