"""The scripted physics of the probe envs on its lean path (``aas_gym.grasp.LEAN_SCRIPT``: no
``mj_forward`` whose results the next step recomputes before anything reads them, a reset's
settle and first release replayed as one run, a grasp's last fingertip sums kept) against the
reference path (``LEAN_SCRIPT = False``: every forward and replay as before).

MuJoCo's step is a function of the integration state alone, so skipping a forward that nothing
reads changes no byte: asserted bit for bit on the full physics state, the derived quantities
an observation or a truth reads (poses, contacts, solver forces, actuator forces), the
observations and the infos, after every reset and step; and on the features of a sensed probe.
"""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import grasp
from aas_gym.contacts import ContactStream
from aas_gym.grasp import grasp_pose

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _physics(u) -> dict:
    """Integration state and the derived quantities read after a reset or step."""
    m, d = u.model, u.data
    state = np.empty(mujoco.mj_stateSize(m, _FULL))
    mujoco.mj_getState(m, d, state, _FULL)
    n = d.ncon
    return {"state": state, "xpos": d.xpos.copy(), "xquat": d.xquat.copy(), "actuator_force": d.actuator_force.copy(),
            "efc_force": d.efc_force[:d.nefc].copy(), "contact_pos": d.contact.pos[:n].copy(),
            "contact_geom": d.contact.geom[:n].copy(), "sensordata": d.sensordata.copy()}


def _assert_same(a, b, path=""):
    """Equal bit for bit: arrays by bytes and dtype (object arrays by entry), mappings and
    sequences entry by entry."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape, path
        if a.dtype == object:
            assert a.tolist() == b.tolist(), path
        else:
            assert a.tobytes() == b.tobytes(), path
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_same(x, y, f"{path}[{i}]")
    else:
        assert type(a) is type(b) and (a == b or (a != a and b != b)), (path, a, b)


def _episode(u, seed: int, actions, monkeypatch, lean: bool) -> list:
    """A reset and the given steps (until the episode ends) with ``LEAN_SCRIPT = lean``: each
    one's observation, info and physics."""
    monkeypatch.setattr(grasp, "LEAN_SCRIPT", lean)
    obs, info = u.reset(seed=seed)
    out = [(obs, info, _physics(u))]
    for action in actions:
        obs, reward, terminated, truncated, info = u.step(action)
        out.append((obs, info, _physics(u), reward))
        if terminated or truncated:
            break
    return out


@pytest.mark.parametrize("env_id, kwargs, actions, seeds", [
    ("aas_gym/GraspPosition-v0", {}, [np.array([0.2], np.float32)], range(4)),
    ("aas_gym/GraspPosition-v0", {"objects": ("mug",), "n_positions": 5}, [np.array([0.2], np.float32)], range(2)),
    ("aas_gym/GraspPosition-v0", {"scene": "multi"}, [np.array([0.2], np.float32)], range(2)),
    ("aas_gym/GraspPosition-v0", {"randomization": False}, [np.array([0.2], np.float32)], range(3)),
    ("aas_gym/ObjectRecognition-v0", {},
     [np.array([-1.0, p, e, -1.0], np.float32) for p, e in ((0.4, -1.0), (-0.8, 0.0), (0.1, 1.0))]
     + [np.array([1.0, 0.0, 0.0, 0.5], np.float32)], range(4)),
    ("aas_gym/FillLevel-v0", {}, [np.array([0.1], np.float32)], range(2)),
])
def test_lean_script_equals_the_reference_bit_for_bit(env_id, kwargs, actions, seeds, monkeypatch):
    lean = gym.make(env_id, disable_env_checker=True, acoustic={"enabled": False}, **kwargs).unwrapped
    reference = gym.make(env_id, disable_env_checker=True, acoustic={"enabled": False}, **kwargs).unwrapped
    for seed in seeds:
        a = _episode(lean, seed, actions, monkeypatch, True)
        b = _episode(reference, seed, actions, monkeypatch, False)
        assert len(a) == len(b)
        _assert_same(a, b, f"{env_id} seed {seed}")
    # the lean envs replayed each object's settle and first release as one run
    if env_id != "aas_gym/FillLevel-v0":
        runs = [k[2] for scene in lean._scenes.values() for k in scene.memo._lru._entries]
        assert any(r[0] == "release" and r[-1][0] == "settle" for r in runs)


def test_a_sensed_probe_hears_the_same_features(monkeypatch):
    """Sensing on: the closed-form features of a grasp are the reference's, bit for bit."""
    lean = gym.make("aas_gym/GraspPosition-v0", disable_env_checker=True).unwrapped
    reference = gym.make("aas_gym/GraspPosition-v0", disable_env_checker=True).unwrapped
    for seed in range(2):
        a = _episode(lean, seed, [], monkeypatch, True)
        b = _episode(reference, seed, [], monkeypatch, False)
        assert np.any(a[0][0]["acoustic"] != 0)
        _assert_same(a, b, f"seed {seed}")


@pytest.mark.parametrize("scene", ["single", "multi"])
def test_fingertip_sums_equal_the_contact_list_through_a_squeeze(scene):
    """``ContactStream.fingertip_forces_n`` (per geom pair tables) against the contact list
    (``read``) step by step, before the pads touch (empty sums: 0.0) and through the squeeze."""
    u = gym.make("aas_gym/GraspPosition-v0", scene=scene, disable_env_checker=True,
                 acoustic={"enabled": False}).unwrapped
    u.reset(seed=3)
    sc, m, d = u._scene, u.model, u.data
    stream = ContactStream(m, sc.bodies)            # a fresh stream: the tables built from the model
    body = sc.bodies[0]
    tcp, width = grasp_pose(m, d, body, 0.02)
    sc.hand.teleport(d, tcp, width + 0.024)
    sc.hand.command(d, opening_m=0.0)
    touched = untouched = 0
    for _ in range(50):
        mujoco.mj_step(m, d)
        c = stream.read(d)[body]
        sums = stream.fingertip_forces_n(d, body)
        assert sums == (c.total_normal_force_n("actuator"), c.total_normal_force_n("mic"))
        touched += sums[0] > 0 and sums[1] > 0
        untouched += sums == (0.0, 0.0)
    assert touched > 10 and untouched > 0
