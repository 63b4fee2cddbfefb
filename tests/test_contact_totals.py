"""``ContactStream.normal_force_totals_n`` (ContactFormation-v0's per-step ground truth) and
``fingertip_forces_n`` (the grasp's per-chunk test), both read through a per-geom-pair table,
against the full contact read they replace and against an independent sum over MuJoCo's own
contact forces (``mj_contactForce``) with each contact's kind from the body names."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.contacts import KINDS


def _independent_forces(model, data, body: str, plinth: str) -> list[tuple[str, float]]:
    """(kind, normal force [N]) of each contact of ``body`` in contact order, from
    ``mj_contactForce`` and the names of the bodies touching it."""
    kind_of = {"left_fingertip": "actuator", "right_fingertip": "mic", "table": "environment", plinth: "object"}
    force = np.zeros(6)
    out = []
    for i in range(data.ncon):
        bodies = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))
                  for g in data.contact.geom[i]]
        if body not in bodies:
            continue
        other = bodies[1 - bodies.index(body)]
        mujoco.mj_contactForce(model, data, i, force)
        out.append((kind_of.get(other, "hand"), max(float(force[0]), 0.0)))
    return out


def test_totals_equal_the_full_read_and_mujocos_contact_forces_along_a_scripted_episode():
    env = gym.make("aas_gym/ContactFormation-v0", acoustic={"enabled": False}, disable_env_checker=True)
    env.reset(seed=0)
    env.action_space.seed(0)
    u = env.unwrapped
    stream, body, plinth = u._scene.stream, u._scene.bodies[0], u._scene.bodies[1]
    seen = set()
    for step in range(150):
        _, _, _, _, info = env.step(env.action_space.sample())
        full = stream.read(u.data)[body]
        expected = np.array([full.total_normal_force_n(k) for k in KINDS])
        totals = stream.normal_force_totals_n(u.data, body)
        np.testing.assert_array_equal(totals, expected)
        # independent: MuJoCo's forces summed in contact order per kind, as bincount sums
        independent = np.zeros(len(KINDS))
        forces = _independent_forces(u.model, u.data, body, plinth)
        for kind, f in forces:
            independent[KINDS.index(kind)] += f
        np.testing.assert_array_equal(totals, independent)
        tips = stream.fingertip_forces_n(u.data, body)
        assert tips == tuple(float(np.sum([f for k, f in forces if k == side], dtype=float))
                             for side in ("actuator", "mic"))
        assert info["table_force_n"] == expected[KINDS.index("environment")]
        assert info["object_force_n"] == expected[KINDS.index("object")]
        seen.add(info["formation"])
    env.close()
    assert seen == {"free", "table", "object"}   # every formation was compared, not only zeros
