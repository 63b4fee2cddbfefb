"""Randomized placements settled as one canonical run moved (``aas_gym.canonical_settle``)
against the settle simulated where the objects were placed (``CANONICAL_SETTLE = False``, the
reference): the same rest poses, grasps and features within the rounding of the rigid motion;
the same bytes whatever the physics cache held before; and one settle per object."""

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import canonical_settle
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from sensors.modal import static_correction


def _episode(u, seed):
    """Reset (it grasps), then the free bodies' poses and the grasp's float64 features."""
    _, info = u.reset(seed=seed)
    q = np.concatenate([u.data.qpos[a:a + 7] for a, _ in u._scene.free_joints])
    feats = u.sensor.sense(u.excitation, u.duration_s, variation=u._variation, rng=np.random.default_rng(0),
                           waveform=False).features()
    return q, feats, info


@pytest.mark.parametrize("objects, scene", [((name,), "single") for name in DEFAULT_OBJECT_NAMES]
                         + [(("wood_bar",), "multi")])
def test_canonical_settle_equals_the_direct_settle(objects, scene, monkeypatch):
    fast = gym.make("aas_gym/GraspPosition-v0", objects=objects, scene=scene, disable_env_checker=True).unwrapped
    reference = gym.make("aas_gym/GraspPosition-v0", objects=objects, scene=scene, disable_env_checker=True).unwrapped
    for seed in range(3):
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", True)
        q_fast, f_fast, info_fast = _episode(fast, seed)
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", False)
        q_ref, f_ref, info_ref = _episode(reference, seed)
        # poses after the settle and the grasp: metres and quaternion components
        np.testing.assert_allclose(q_fast, q_ref, rtol=0, atol=1e-9)
        assert info_fast["grasp_success"] == info_ref["grasp_success"]
        for body, c in info_ref["contacts"].items():
            assert info_fast["contacts"][body]["n_contacts"] == c["n_contacts"]
            np.testing.assert_allclose(info_fast["contacts"][body]["positions_m"], c["positions_m"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(f_fast, f_ref, rtol=1e-6, atol=0)


def test_canonical_settle_is_history_free_and_settles_once_per_object():
    """With the physics cache emptied before every reset: the same bytes (a reset never
    depends on what ran before); kept: every reset after the first of an object replays."""
    kwargs = dict(objects=("wood_bar", "abs_bar"), disable_env_checker=True)
    warm = gym.make("aas_gym/GraspPosition-v0", **kwargs).unwrapped
    cold = gym.make("aas_gym/GraspPosition-v0", **kwargs).unwrapped
    for seed in range(6):
        obs_w, _ = warm.reset(seed=seed)
        for scene in cold._scenes.values():
            scene.memo.clear()
        obs_c, _ = cold.reset(seed=seed)
        for key in obs_w:
            assert np.array_equal(obs_w[key], obs_c[key]), key
        assert np.array_equal(warm.data.qpos, cold.data.qpos)
    settles = [len([k for k in s.memo._lru._entries if k[2][0] == "settle"]) for s in warm._scenes.values()]
    assert settles == [1] * len(warm._scenes), "one canonical settle per object, whatever the placement"
    assert sum(s.memo.hits for s in warm._scenes.values()) >= 6 - len(warm._scenes)


def _probe(u, seed, positions):
    """Reset, probe at each position (impulse), then the free bodies' poses, the last grasp's
    contacts and its float64 features."""
    u.reset(seed=seed)
    for position in positions:
        _, _, _, _, info = u.step(np.array([-1.0, position, -1.0, -1.0], np.float32))
    q = np.concatenate([u.data.qpos[a:a + 7] for a, _ in u._scene.free_joints])
    feats = u.sensor.sense(u.excitations[0], u.duration_s, variation=u._variation, rng=np.random.default_rng(0),
                           waveform=False).features()
    return q, feats, info


def test_object_recognition_probes_equal_the_direct_settle_and_direct_solves(monkeypatch):
    """ObjectRecognition-v0's fast path (canonical settle, kept unit-load solves leaving out
    shape weights below 1e-9) against the direct settle and each contact set solved directly
    (``static_correction.reference_paths()``): the same poses, contacts and features."""
    fast = gym.make("aas_gym/ObjectRecognition-v0", disable_env_checker=True).unwrapped
    reference = gym.make("aas_gym/ObjectRecognition-v0", disable_env_checker=True).unwrapped
    for seed in range(3):
        positions = np.random.default_rng(seed).uniform(-1, 1, 2)
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", True)
        q_fast, f_fast, info_fast = _probe(fast, seed, positions)
        monkeypatch.setattr(canonical_settle, "CANONICAL_SETTLE", False)
        with static_correction.reference_paths():
            q_ref, f_ref, info_ref = _probe(reference, seed, positions)
        assert info_fast["label"] == info_ref["label"]
        np.testing.assert_allclose(q_fast, q_ref, rtol=0, atol=1e-9)
        for body, c in info_ref["contacts"].items():
            assert info_fast["contacts"][body]["n_contacts"] == c["n_contacts"]
            np.testing.assert_allclose(info_fast["contacts"][body]["positions_m"], c["positions_m"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(f_fast, f_ref, rtol=1e-6, atol=0)
