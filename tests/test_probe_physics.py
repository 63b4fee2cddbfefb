"""The physics of a probe and of a reset in the probe envs (GraspPosition-v0,
ObjectRecognition-v0) on their fast paths against the reference paths:

- a grasp tests its fingertip forces after each chunk of steps without building the contact
  list (``ContactStream.fingertip_forces_n``): the same sums as the contact list's, bit for bit;
- the first release after a reset is replayed from the canonical settle's run
  (``aas_gym.canonical_settle.run_after_settle``); ``CANONICAL_SETTLE = False`` (settle and
  release where the objects were placed) is the reference. Tolerances: the rigid motion's
  rounding (about 1e-16 relative) grows through the squeeze's contact dynamics to at most
  3e-12 m in poses and contact points and 1e-11 relative in the grasp forces on the seven
  default objects (measured); asserted at 1e-9 m and 1e-9. The closed-form features, whose
  smallest entries are the most sensitive, came out within 4.2e-7 relative per feature:
  asserted at 1e-6 (issue 27's bound for fast paths);
- with sensing off nothing is recorded, and the physics, the contacts and whether a grasp is
  heard are those of the env with sensing on.
"""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import canonical_settle
from aas_gym.contacts import KINDS
from aas_gym.grasp import grasp_pose
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from grasp_snapshot import grasped_state


@pytest.mark.parametrize("objects, scene", [((name,), "single") for name in DEFAULT_OBJECT_NAMES]
                         + [(("wood_bar",), "multi")])
def test_fingertip_forces_equal_the_contact_list_sums(objects, scene):
    """Through a whole squeeze (free closing, impact, settling), step by step."""
    u = gym.make("aas_gym/GraspPosition-v0", objects=objects, scene=scene, disable_env_checker=True,
                 acoustic={"enabled": False}).unwrapped
    u.reset(seed=2)
    sc, m, d = u._scene, u.model, u.data
    body = sc.bodies[0]
    tcp, width = grasp_pose(m, d, body, 0.01)
    sc.hand.teleport(d, tcp, width + 0.024)
    sc.hand.command(d, opening_m=0.0)
    kinds_seen = set()
    for _ in range(60):
        mujoco.mj_step(m, d)
        c = sc.stream.read(d)[body]
        kinds_seen.update(c.kinds.tolist())
        fa, fm = sc.stream.fingertip_forces_n(d, body)
        assert (fa, fm) == (c.total_normal_force_n("actuator"), c.total_normal_force_n("mic"))
    assert {"actuator", "mic", "environment"} <= kinds_seen <= set(KINDS)
    if scene == "multi":
        assert "object" in kinds_seen


def _grasped_state(u, seed):
    """Reset (GraspPosition-v0 grasps in it) and what it left grasped, with the grasp position."""
    return grasped_state(u, seed, ("grasp_position_m",))


@pytest.mark.parametrize("name", DEFAULT_OBJECT_NAMES)
def test_probe_physics_equals_the_reference_path(name, monkeypatch):
    fast = gym.make("aas_gym/GraspPosition-v0", objects=(name,), disable_env_checker=True).unwrapped
    reference = gym.make("aas_gym/GraspPosition-v0", objects=(name,), disable_env_checker=True).unwrapped
    for seed in range(3):
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", True)
        a = _grasped_state(fast, seed)
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", False)
        b = _grasped_state(reference, seed)
        assert a["success"] and b["success"]
        assert a["grasp_position_m"] == b["grasp_position_m"]
        np.testing.assert_allclose(a["objects"], b["objects"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a["hand"], b["hand"], rtol=0, atol=1e-9)
        assert a["kinds"] == b["kinds"]
        np.testing.assert_allclose(a["points"], b["points"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a["forces"], b["forces"], rtol=1e-9, atol=0)
        np.testing.assert_allclose(a["features"], b["features"], rtol=1e-6, atol=0)
    # the first release ran once per object (canonically), the reference's every time
    releases = [k for k in fast._scene.memo._lru._entries if k[2][0] == "release"]
    assert len(releases) == 1


def _probes(u, seed, actions):
    """A reset and the given steps: the physics state after each, and each step's info."""
    u.reset(seed=seed)
    out = []
    for action in actions:
        info = u.step(action)[4]
        out.append((u.data.qpos.copy(), u.data.qvel.copy(), info))
    return out


def test_object_recognition_probes_replay_the_first_release_history_free():
    """The first probe of each episode replays the canonical release; what ran before (the
    physics cache emptied or not) changes no byte."""
    actions = [np.array([-1.0, p, -1.0, -1.0], np.float32) for p in (0.3, -0.6)]
    warm = gym.make("aas_gym/ObjectRecognition-v0", disable_env_checker=True, acoustic={"enabled": False}).unwrapped
    cold = gym.make("aas_gym/ObjectRecognition-v0", disable_env_checker=True, acoustic={"enabled": False}).unwrapped
    for seed in range(8):
        a = _probes(warm, seed, actions)
        for scene in cold._scenes.values():
            scene.memo.clear()
        b = _probes(cold, seed, actions)
        for (qa, va, _), (qb, vb, _) in zip(a, b):
            assert np.array_equal(qa, qb) and np.array_equal(va, vb)
    runs = [[k[2][0] for k in scene.memo._lru._entries] for scene in warm._scenes.values()]
    assert sum("settle" in r for r in runs) >= 2                       # several objects drawn
    assert all(r.count("release") == r.count("settle") <= 1 for r in runs), runs


@pytest.mark.parametrize("env_id, actions", [
    ("aas_gym/GraspPosition-v0", [np.array([0.2], np.float32)]),
    ("aas_gym/ObjectRecognition-v0", [np.array([-1.0, p, e, -1.0], np.float32) for p, e in ((0.4, -1.0), (-0.8, 0.0))]
     + [np.array([1.0, 0.0, 0.0, 0.5], np.float32)]),
])
def test_sensing_off_runs_the_physics_of_sensing_on(env_id, actions):
    on = gym.make(env_id, disable_env_checker=True).unwrapped
    off = gym.make(env_id, disable_env_checker=True, acoustic={"enabled": False}).unwrapped
    for seed in range(3):
        on_obs, on_info = on.reset(seed=seed)
        off_obs, off_info = off.reset(seed=seed)
        assert "acoustic" in on_obs and "acoustic" not in off_obs
        steps = [((on_obs, on_info), (off_obs, off_info))]
        for action in actions:
            a, b = on.step(action), off.step(action)
            steps.append(((a[0], a[4]), (b[0], b[4])))
            assert a[1:4] == b[1:4]
            if a[2]:
                break
        assert np.array_equal(on.data.qpos, off.data.qpos)
        for (obs_on, info_on), (obs_off, info_off) in steps:
            for key in obs_off:
                assert np.array_equal(obs_on[key], obs_off[key]), key
            if "recording_grasped" in info_on:
                assert info_on["recording_grasped"] == info_off["recording_grasped"]
            if "contacts" in info_on:
                for body, c in info_on["contacts"].items():
                    for field, value in c.items():
                        assert np.array_equal(np.asarray(value), np.asarray(info_off["contacts"][body][field])), field
