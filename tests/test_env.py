"""Gymnasium environments: registration, check_env, vectorization, rendering, bad input."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.envs.base import DomainRandomization
from scripted_policy import reach_until_grasped

ENV_IDS = ["aas_gym/AcousticGrasp-v0", "aas_gym/GraspPosition-v0", "aas_gym/ObjectRecognition-v0",
           "aas_gym/ContactFormation-v0"]
# Smallest settings that still exercise everything: 0.5 s recordings (one excitation period).
FAST = {"acoustic": {"duration_s": 0.5}}


def test_envs_are_registered_on_import():
    for env_id in ENV_IDS:
        assert env_id in gym.registry


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_check_env(env_id):
    kwargs = dict(FAST)
    if env_id == "aas_gym/ObjectRecognition-v0":
        kwargs["objects"] = ["aluminium_bar", "wood_bar"]
    env = gym.make(env_id, **kwargs)
    check_env(env.unwrapped)
    env.close()


def test_acoustic_grasp_control_only_passes_check_env_and_is_deterministic():
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never"}, scene="multi")
    check_env(env.unwrapped)
    a = env.reset(seed=7)[0]
    b = env.reset(seed=7)[0]
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reward_terms_have_fixed_keys_and_sum_to_the_reward(env_id):
    """As Gymnasium's MuJoCo envs: info["reward_terms"], the same keys every step, floats."""
    kwargs = dict(FAST, disable_env_checker=True)
    if env_id == "aas_gym/ObjectRecognition-v0":
        kwargs["objects"] = ["aluminium_bar", "wood_bar"]
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    keys = None
    for _ in range(4):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        terms = info["reward_terms"]
        keys = keys or tuple(terms)
        assert tuple(terms) == keys and all(type(v) is float for v in terms.values())
        assert reward == pytest.approx(sum(terms.values()), abs=1e-12)
        if terminated or truncated:
            env.reset()
    env.close()


def test_make_vec_async():
    envs = gym.make_vec("aas_gym/AcousticGrasp-v0", num_envs=2, vectorization_mode="async", acoustic={"cadence": "never"})
    try:
        obs, info = envs.reset(seed=[1, 2])
        assert obs["tcp"].shape == (2, 4) and obs["acoustic"].shape == (2, 140)
        for _ in range(3):
            obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
        assert reward.shape == (2,)
        assert not np.array_equal(obs["object"][0], obs["object"][1])  # different seeds, different scenes
    finally:
        envs.close()


@pytest.mark.parametrize("mode", ["rgb_array", "depth_array"])
def test_headless_rendering(mode):
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never"}, render_mode=mode, width=96, height=64)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape[:2] == (64, 96)
    if mode == "rgb_array":
        assert frame.dtype == np.uint8 and frame.std() > 5  # a picture, not a blank frame
    env.close()


def test_reach_and_grasp_by_actions_gives_reward_and_grasp():
    """A scripted policy through the public action space: move over the bar, down, close."""
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never"}, randomization=DomainRandomization.off())
    obs, _ = env.reset(seed=0)
    obs, reward, info = reach_until_grasped(env, obs, max_steps=120)  # raises unless grasped
    assert info["grasped"] and reward > 0.9
    assert obs["gripper"][2] == pytest.approx(40.0, rel=0.05)  # motor force saturated at the grip force


def test_unknown_names_raise_clear_errors():
    with pytest.raises(ValueError, match="unknown material"):
        gym.make("aas_gym/AcousticGrasp-v0", objects=["unobtainium_bar"])
    with pytest.raises(ValueError, match="unknown shape"):
        gym.make("aas_gym/AcousticGrasp-v0", objects=["steel_sphere"])
    with pytest.raises(ValueError, match="unknown excitation"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"excitation": "chirp"})
    with pytest.raises(ValueError, match="unknown randomization knobs"):
        gym.make("aas_gym/AcousticGrasp-v0", randomization={"gravity": 1.0})
    with pytest.raises(ValueError, match="scene"):
        gym.make("aas_gym/AcousticGrasp-v0", scene="cluttered")


def test_same_seed_same_acoustic_observation():
    env = gym.make("aas_gym/GraspPosition-v0", **FAST,
                   randomization=DomainRandomization(sensor_noise_std=1e-4))
    a, info_a = env.reset(seed=4)
    b, info_b = env.reset(seed=4)
    c, _ = env.reset(seed=5)
    np.testing.assert_array_equal(a["acoustic"], b["acoustic"])
    assert info_a["grasp_position_m"] == info_b["grasp_position_m"]
    assert not np.array_equal(a["acoustic"], c["acoustic"])
    assert a["acoustic"].shape == (140,) and a["acoustic"].max() > 0


def test_grasp_position_info_and_reward():
    env = gym.make("aas_gym/GraspPosition-v0", **FAST, randomization=DomainRandomization.off(),
                   action_format="metres")
    obs, info = env.reset(seed=0, options={"position_index": 4})
    assert info["grasp_position_m"] == pytest.approx(0.02) and info["grasp_success"]
    assert info["label"] == "wood_bar" and info["material"] == "wood" and info["shape"] == "bar"
    _, reward, terminated, _, step_info = env.step(np.array([0.025], np.float32))
    assert terminated and reward == pytest.approx(-0.005, abs=1e-6)
    # the default, SB3-friendly action: [-1, 1] onto 0 .. 60 mm, so 0.025 m is -1/6
    env = gym.make("aas_gym/GraspPosition-v0", **FAST, randomization=DomainRandomization.off())
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    env.reset(seed=0, options={"position_index": 4})
    _, reward, _, _, step_info = env.step(np.array([2 * 0.025 / 0.06 - 1], np.float32))
    assert step_info["estimate_m"] == pytest.approx(0.025, abs=1e-6) and reward == pytest.approx(-0.005, abs=1e-6)


def test_recognition_probe_then_answer():
    env = gym.make("aas_gym/ObjectRecognition-v0", objects=["aluminium_bar", "aluminium_tube"], **FAST,
                   action_format="dict")
    obs, info = env.reset(seed=1)
    assert obs["n_probes"][0] == 0 and not obs["acoustic"].any()
    probe = {"command": 0, "position": np.array([0.4], np.float32), "excitation": 2, "label": 0}
    obs, reward, terminated, _, pinfo = env.step(probe)
    assert reward == pytest.approx(-0.01) and not terminated and obs["acoustic"].max() > 0
    assert pinfo["grasp_success"] and pinfo["excitation"] == "exponential"
    answer = dict(probe, command=1, label=info["label_index"])
    _, reward, terminated, _, ainfo = env.step(answer)
    assert terminated and reward == 1.0 and ainfo["is_success"]


def test_recognition_box_action_decodes_like_the_dict():
    env = gym.make("aas_gym/ObjectRecognition-v0", objects=["aluminium_bar", "aluminium_tube"], **FAST)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    obs, info = env.reset(seed=1)
    # probe at 0.4 with the exponential sweep (top third of [-1, 1]), then answer the true label
    obs, reward, terminated, _, pinfo = env.step(np.array([-1.0, 0.4, 0.9, -1.0], np.float32))
    assert pinfo["excitation"] == "exponential" and not terminated and obs["acoustic"].max() > 0
    label = -0.5 if info["label_index"] == 0 else 0.5
    _, reward, terminated, _, ainfo = env.step(np.array([1.0, 0.0, 0.0, label], np.float32))
    assert terminated and reward == 1.0 and ainfo["guess"] == info["label_index"]


@pytest.mark.parametrize("env_id, n", [("aas_gym/AcousticGrasp-v0", 6), ("aas_gym/GraspPosition-v0", 1),
                                       ("aas_gym/ObjectRecognition-v0", 4)])
@pytest.mark.parametrize("bad", [np.nan, np.inf, "shape"])
def test_nonfinite_or_misshapen_actions_are_refused(env_id, n, bad):
    """max(-1, min(1, nan)) is 1: a NaN would be a full-speed move or NaN in MuJoCo's ctrl."""
    env = gym.make(env_id, **FAST, disable_env_checker=True).unwrapped
    env.reset(seed=0)
    qpos = env.data.qpos.copy()
    action = np.zeros(n + 1 if bad == "shape" else n, np.float32)
    if bad != "shape":
        action[0] = bad
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    np.testing.assert_array_equal(env.data.qpos, qpos)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_stable_baselines3_accepts_the_default_spaces(env_id):
    """SB3's own checker, warnings as errors: symmetric Box actions, no Dict action."""
    import warnings

    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, acoustic={"duration_s": 0.5, "feature_scale": "db"}).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env, warn=True)


def test_every_env_renders_human_on_reset():
    """The reset template renders for render_mode="human" in every env (headless: it warns)."""
    for env_id in ENV_IDS:
        env = gym.make(env_id, **FAST, render_mode="human", disable_env_checker=True).unwrapped
        env._warned_no_display = False
        with pytest.warns(UserWarning, match="no display"):
            env.reset(seed=0)


def test_missing_leak_file_fails_at_make(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"leak": str(tmp_path / "nope.npz")})
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip at all")
    with pytest.raises(ValueError, match="bad.npz"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"leak": str(bad)})
