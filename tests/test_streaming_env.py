"""Sensing while the robot moves (issue 12): the streaming microphone on MuJoCo scenes and in
the envs, and ContactFormation-v0.

The synthesis itself is checked against scipy's lsim and for continuity in test_streaming.py;
here the physics drives it: lifting, pressing, opening the hand, a steady grasp.
"""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.envs.contact_formation import FORMATIONS
from aas_gym.grasp import Hand, planar_grasp
from aas_gym.scenario import settle
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from aas_gym.sim_stream import SimAcousticStream, span_bounds
from scripted_policy import reach_until_grasped
from sensors.modal.damping import modal_damping_matrix
from sensors.synthesis.modal_system import modal_state_matrix

STEP = 2205          # samples per env step (0.05 s)


@pytest.fixture()
def held():
    """An aluminium bar grasped at 20 mm from its centre, resting on the table."""
    m = build_scene(["aluminium_bar"], contact_signature=True)
    d = mujoco.MjData(m)
    sensor = SimAcousticSensor(m, d, on_no_grasp="silence")
    hand = Hand(m)
    settle(m, d, 0.3)
    assert planar_grasp(m, d, sensor.bodies[0], 0.02, 40.0, hand=hand).success
    return m, d, sensor, hand


def _hold(stream, steps):
    """Stream ``steps`` env steps (25 physics steps each); returns the samples."""
    return np.concatenate([stream.step_physics(25, STEP) for _ in range(steps)])


def _decay_rates(state):
    """Decay rates [1/s] of the object's modes under the contacts of a GraspState: an
    eigen-decomposition of the damped modal state matrix, independent of the synthesis."""
    model = state.model
    C = modal_damping_matrix(model, state.damping_contacts())
    lam = np.linalg.eigvals(modal_state_matrix(model.angular_frequencies_rad_s, C))
    lam = lam[lam.imag > 0]
    return -lam[np.argsort(lam.imag)].real


def test_span_bounds_share_the_samples_of_a_step():
    b = span_bounds(2205, 25)
    assert b[0] == 0 and b[-1] == 2205 and set(np.diff(b)) == {88, 89}


def test_lifting_lowers_and_pressing_raises_the_decay_rates_and_the_features_move(held):
    m, d, sensor, hand = held
    stream = SimAcousticStream(sensor, "linear", rng=0)
    home = hand.tcp(d).copy()
    states, features, repeat = {}, {}, {}
    for phase, dz in (("table", 0.0), ("lifted", 0.03), ("pressed", -0.004)):
        hand.command(d, tcp=home + np.array([0, 0, dz, 0]))
        _hold(stream, 30)                       # 1.5 s: move, settle, then whole loop periods
        states[phase] = stream.grasp_state()
        features[phase] = stream.latest_features().copy()
        # the next whole period in the same state: how much the features still move by themselves
        _hold(stream, 10)
        repeat[phase] = np.linalg.norm(stream.latest_features() - features[phase]) / np.linalg.norm(features[phase])
    table = lambda s: sum(c.force_n for c in s.others)  # noqa: E731
    assert table(states["lifted"]) == 0 and table(states["pressed"]) > 2 * table(states["table"]) > 0
    rates = {k: _decay_rates(s) for k, s in states.items()}
    # Contact damping only adds: off the table every mode decays slower, pressed faster. On
    # aluminium the material's own damping dominates; the table moves the low modes by 1-2 %.
    lifted = (rates["table"] - rates["lifted"]) / rates["table"]
    pressed = (rates["pressed"] - rates["table"]) / rates["table"]
    for change in (lifted, pressed):
        assert np.all(change > -1e-9) and np.median(change) > 1e-3 and change.max() > 0.01, change
    for phase in ("lifted", "pressed"):
        moved = np.linalg.norm(features[phase] - features["table"]) / np.linalg.norm(features["table"])
        assert moved > max(0.005, 20 * repeat[phase], 20 * repeat["table"]), (phase, moved, repeat)


def test_a_steady_grasp_reads_the_contacts_once_and_builds_one_system(held):
    m, d, sensor, hand = held
    stream = SimAcousticStream(sensor, "linear", rng=0)
    _hold(stream, 40)
    assert stream.contact_reads <= 2 and stream.stream.systems.misses == 1
    assert stream.stream.latest_features_heard == 1.0


def test_an_open_hand_hears_nothing_and_the_closed_one_hears_the_object_again(held):
    """No leak, no noise: while the fingertips are off the object the samples are zero."""
    m, d, sensor, hand = held
    stream = SimAcousticStream(sensor, "impulse", rng=0)
    assert np.abs(_hold(stream, 10)).max() > 0
    hand.command(d, opening_m=0.08)
    _hold(stream, 6)                                 # the fingers open
    assert not stream.grasp_state().closed
    assert np.abs(_hold(stream, 6)).max() == 0.0
    hand.command(d, opening_m=0.0)
    _hold(stream, 10)
    assert stream.grasp_state().closed and np.abs(_hold(stream, 10)).max() > 0


def test_streaming_scenes_alone_carry_the_signature_sensors():
    """Sensing off costs nothing: the scene of a non-streaming env has no extra sensors."""
    plain = gym.make("aas_gym/AcousticGrasp-v0", disable_env_checker=True).unwrapped
    streamed = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream"},
                        disable_env_checker=True).unwrapped
    assert streamed.model.nsensor > plain.model.nsensor == 2
    with pytest.raises(ValueError, match="contact_signature=True"):
        SimAcousticStream(plain.sensor, "linear")


def test_acoustic_grasp_streams_each_step_and_succeeds_after_a_period_heard():
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream", "feature_scale": "db"},
                   randomization=False)
    obs, _ = env.reset(seed=0)
    assert obs["audio"].shape == (STEP,) and env.observation_space.contains(obs)
    obs, _, info = reach_until_grasped(env, obs)
    hold = np.array([0, 0, 0, 0, -1, 0], np.float32)
    for _ in range(25):                              # more than one whole 0.5 s period
        obs, reward, terminated, _, info = env.step(hold)
        assert not terminated and obs["audio"].shape == (STEP,)
    assert info["heard_fraction"] == 1.0 and np.abs(obs["audio"]).max() > 0
    assert obs["acoustic"].max() > -60          # dB re 1e-6: the object is heard
    _, reward, terminated, _, info = env.step(np.array([0, 0, 0, 0, -1, 1], np.float32))
    assert terminated and info["is_success"] and reward > 9


def test_streamed_success_waits_for_a_period_recorded_after_the_grasp_was_seen():
    """Asking to stop from the first grasped step on: success comes only once the latest
    complete period began after the grasp was first seen at a step's end (the rule the real
    env uses), which the simulator's own per-sample count confirms (heard_fraction 1)."""
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream"}, randomization=False)
    obs, _ = env.reset(seed=0)
    obs, _, info = reach_until_grasped(env, obs)
    period_steps = env.unwrapped.excitation.period_samples // STEP        # 10 steps of 2205 samples
    stop = np.array([0, 0, 0, 0, -1, 1], np.float32)
    for k in range(1, 2 * period_steps + 1):
        obs, reward, terminated, _, info = env.step(stop)
        assert info["grasped"]
        if terminated:
            break
        assert reward == pytest.approx(sum(info["reward_terms"].values())) and info["reward_terms"]["success"] == 0
    assert terminated and info["is_success"] and info["heard_fraction"] == 1.0
    assert info["reward_terms"]["success"] == 10.0 and k >= period_steps


def test_probe_envs_stream_the_hold_of_each_probe():
    env = gym.make("aas_gym/GraspPosition-v0", acoustic={"cadence": "stream", "duration_s": 1.0})
    obs, info = env.reset(seed=3)
    assert obs["audio"].shape == (44100,) and info["recording_grasped"]
    assert np.abs(obs["audio"]).max() > 0 and obs["acoustic"].max() > 0


def test_streamed_steps_need_a_whole_number_of_samples():
    with pytest.raises(ValueError, match="whole number of samples"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream"}, frame_skip=1)
    with pytest.raises(ValueError, match="audio"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream", "waveform": True})


def test_contact_formation_episode_visits_formations_that_the_forces_confirm():
    env = gym.make("aas_gym/ContactFormation-v0", objects=["aluminium_bar"], plinths=["steel_bar"],
                   max_episode_steps=100)
    obs, info = env.reset(seed=2)
    assert info["grasp_success"] and info["formation"] == "table"
    seen, rewards = set(), []
    for k in range(100):
        obs, reward, terminated, truncated, info = env.step(k % 3)
        assert env.observation_space.contains(obs) and info["grasped"]
        f = info["formation"]
        assert (f == "object") == (info["object_force_n"] > 0.2)
        assert f != "table" or info["table_force_n"] > 0.2
        assert reward == float(info["formation_index"] == k % 3)
        seen.add(f)
        rewards.append(reward)
    assert truncated and len(seen) >= 2 and set(seen) <= set(FORMATIONS)


def test_contact_formation_refuses_bad_reports_and_runs_on_proprioception_alone():
    env = gym.make("aas_gym/ContactFormation-v0", acoustic={"enabled": False}, disable_env_checker=True)
    obs, _ = env.reset(seed=0)
    assert "acoustic" not in obs and "audio" not in obs
    for bad in (np.nan, 3, -1):
        with pytest.raises(ValueError):
            env.step(bad)
    with pytest.raises(ValueError, match="scene"):
        gym.make("aas_gym/ContactFormation-v0", scene="single")


def test_contact_formation_baselines_train_and_report_per_class():
    from aas_gym.experiments.contact_formation import collect, evaluate, format_table, step_band_levels

    data = collect(3, seed=5, steps=40, progress=False, objects=["aluminium_bar"], plinths=["steel_bar"])
    assert data.acoustic.shape == (120, 164) and data.proprio.shape == (120, 11)
    assert set(data.episode.tolist()) == {0, 1, 2} and np.all(np.isfinite(data.acoustic))
    results = evaluate(data, seed=0)
    assert set(results) == {"sound", "proprioception", "sound + proprioception"}
    for r in results.values():
        assert 0 <= r["accuracy"] <= 1 and sum(r["n_test"].values()) == 40   # one whole episode
    assert "| sound |" in format_table(results)
    # the band levels of a pure tone peak in its band
    tone = np.sin(2 * np.pi * 800 * np.arange(2205) / 44100)
    levels = step_band_levels(tone, 44100)
    assert levels.shape == (24,) and np.argmax(levels) == np.searchsorted(
        np.geomspace(50.0, 20000.0, 25), 800) - 1


@pytest.mark.parametrize("env_id", ["aas_gym/AcousticGrasp-v0", "aas_gym/ObjectRecognition-v0"])
def test_streaming_mode_passes_check_env(env_id):
    from gymnasium.utils.env_checker import check_env

    kwargs = {"objects": ["aluminium_bar", "wood_bar"]} if "Recognition" in env_id else {}
    env = gym.make(env_id, acoustic={"cadence": "stream", "feature_scale": "db", "duration_s": 0.5}, **kwargs)
    check_env(env.unwrapped, skip_render_check=True)
