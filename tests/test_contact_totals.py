"""``ContactStream.normal_force_totals_n`` (ContactFormation-v0's per-step ground truth)
against the full contact read it replaces: the same sums, bit for bit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.contacts import KINDS


def test_totals_equal_the_full_read_along_a_scripted_episode():
    env = gym.make("aas_gym/ContactFormation-v0", acoustic={"enabled": False}, disable_env_checker=True)
    env.reset(seed=0)
    u = env.unwrapped
    stream, body = u._scene.stream, u._scene.bodies[0]
    seen = set()
    for step in range(150):
        _, _, _, _, info = env.step(env.action_space.sample())
        full = stream.read(u.data)[body]
        expected = np.array([full.total_normal_force_n(k) for k in KINDS])
        np.testing.assert_array_equal(stream.normal_force_totals_n(u.data, body), expected)
        assert info["table_force_n"] == expected[KINDS.index("environment")]
        assert info["object_force_n"] == expected[KINDS.index("object")]
        seen.add(info["formation"])
    env.close()
    assert seen == {"free", "table", "object"}   # every formation was compared, not only zeros
