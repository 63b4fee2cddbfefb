"""The scripted reach-and-grasp policy shared by the env tests (simulated and real env)."""

import numpy as np


def reach_until_grasped(env, obs, max_steps=150):
    """The scripted policy of the simulated env's tests: over the object, down, close.

    Returns ``(obs, reward, info)`` of the first step that reports ``info["grasped"]``."""
    for _ in range(max_steps):
        target, tcp = obs["object"][:3].astype(float), obs["tcp"].astype(float)
        err = target - tcp[:3]
        above = np.linalg.norm(err[:2]) > 0.003
        goal_z = target[2] + (0.06 if above else 0.0)
        action = np.zeros(6, np.float32)
        action[:2] = np.clip(err[:2] / 0.01, -1, 1)
        action[2] = np.clip((goal_z - tcp[2]) / 0.01, -1, 1)
        action[4] = 1.0 if abs(goal_z - tcp[2]) > 0.002 or above else -1.0
        obs, reward, terminated, truncated, info = env.step(action)
        assert not terminated
        if info["grasped"]:
            return obs, reward, info
    raise AssertionError("the scripted policy did not grasp")


def reach_and_grasp(env, obs, max_steps=150):
    """``reach_until_grasped``, then hold the grasp while the grip force builds up."""
    obs, _, _ = reach_until_grasped(env, obs, max_steps)
    for _ in range(10):  # let the grip force build up
        obs, *_ = env.step(np.array([0, 0, 0, 0, -1, 0], np.float32))
    return obs
