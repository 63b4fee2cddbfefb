"""Resets from the physics cache (``aas_gym.physics_memo``) equal full resets.

The reference clears the cache before every reset, so each one simulates the settling and
the grasp; the cached env replays them. Same seed -> the same observations, info and MuJoCo
state, bit for bit.
"""

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)

DATA_FIELDS = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "sensordata", "xpos", "xquat", "efc_force")


def _same(a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, np.ndarray):
        assert np.array_equal(a, b)
    else:
        assert a == b


def _assert_same_state(ua, ub):
    for f in DATA_FIELDS:
        assert np.array_equal(getattr(ua.data, f), getattr(ub.data, f)), f
    assert ua.data.ncon == ub.data.ncon
    assert np.array_equal(ua.data.contact.pos, ub.data.contact.pos)
    assert np.array_equal(ua.model.actuator_forcerange, ub.model.actuator_forcerange)


@pytest.mark.parametrize("env_id, kwargs", [
    ("aas_gym/GraspPosition-v0", {"objects": ("wood_bar", "aluminium_bar")}),
    ("aas_gym/AcousticGrasp-v0", {}),
])
def test_cached_reset_equals_full_reset(env_id, kwargs):
    cached = gym.make(env_id, randomization=False, **kwargs).unwrapped
    full = gym.make(env_id, randomization=False, **kwargs).unwrapped
    seeds = [0, 1, 2, 3, 0, 1, 2, 3]
    for seed in seeds:
        obs_c, info_c = cached.reset(seed=seed)
        for scene in full._scenes.values():
            scene.memo.clear()
        obs_f, info_f = full.reset(seed=seed)
        _same(obs_c, obs_f)
        _same(info_c, info_f)
        _assert_same_state(cached, full)
    hits = sum(s.memo.hits for s in cached._scenes.values())
    assert hits >= len(seeds) // 2, "the repeated seeds replay from the cache"


def test_cached_probes_equal_full_probes():
    """ObjectRecognition-v0's probes (grasp + recording): an episode replayed with the same
    seed and actions replays its probes from the cache."""
    kwargs = {"randomization": False, "action_format": "box"}
    cached = gym.make("aas_gym/ObjectRecognition-v0", **kwargs).unwrapped
    full = gym.make("aas_gym/ObjectRecognition-v0", **kwargs).unwrapped
    probes = [np.array([-1, p, e, 0], np.float32) for p, e in ((0.2, -0.9), (0.6, 0.0))]
    for _ in range(2):
        out_c, out_f = cached.reset(seed=4), full.reset(seed=4)
        _same(out_c, out_f)
        for a in probes:
            out_c = cached.step(a)
            for scene in full._scenes.values():
                scene.memo.clear()
            out_f = full.step(a)
            _same(out_c, out_f)
            _assert_same_state(cached, full)
    assert cached._scene.memo.hits >= 3


def test_memo_keys_on_model_edits_and_survives_eviction():
    """A run under another body mass (FillLevel-v0's liquid) or grip force is not replayed;
    a one-entry memo recomputes after eviction and still replays exactly."""
    import mujoco

    from aas_gym.physics_memo import PhysicsMemo
    from aas_gym.scene import build_scene

    model = build_scene(["wood_bar"])
    data = mujoco.MjData(model)
    start = mujoco.MjData(model)
    mujoco.mj_copyData(start, model, data)
    memo = PhysicsMemo(model, max_size=1)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "wood_bar")

    def settle_from_start():
        mujoco.mj_copyData(data, model, start)
        return memo.run(data, ("settle",), lambda: mujoco.mj_step(model, data, nstep=50))

    def fresh(mass):
        d = mujoco.MjData(model)
        mujoco.mj_copyData(d, model, start)
        m0 = model.body_mass[bid]
        model.body_mass[bid] = mass
        mujoco.mj_step(model, d, nstep=50)
        model.body_mass[bid] = m0
        return d.qpos.copy(), d.qacc.copy()

    m0 = float(model.body_mass[bid])
    ref_light, ref_heavy = fresh(m0), fresh(3 * m0)
    settle_from_start()
    settle_from_start()
    assert memo.hits == 1 and np.array_equal(data.qacc, ref_light[1])
    model.body_mass[bid] = 3 * m0
    settle_from_start()                         # another mass: computed, evicts the light run
    assert memo.hits == 1 and np.array_equal(data.qpos, ref_heavy[0]) and np.array_equal(data.qacc, ref_heavy[1])
    model.body_mass[bid] = m0
    settle_from_start()                         # recomputed into the reused MjData
    settle_from_start()
    assert memo.hits == 2 and np.array_equal(data.qpos, ref_light[0]) and np.array_equal(data.qacc, ref_light[1])
