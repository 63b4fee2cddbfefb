"""RealGraspEnv: the simulated env's spaces, driven through RobotInterface, sensing through
the real audio path (MuJoCo-backed robot + PyAudio loopback rig)."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
import aas_gym  # noqa: E402,F401

import real  # noqa: E402
from real.env import MujocoRobot, RealGraspEnv, RobotInterface, RobotState  # noqa: E402


class _Recorder:
    """A minimal AcousticSensor for the non-audio tests: it says what it was asked."""

    def __init__(self):
        self.calls = []

    def sense(self, excitation, duration_s):
        import sensors

        self.calls.append((excitation.name, duration_s))
        return sensors.AcousticObservation(excitation.loop(duration_s), excitation.fs, excitation,
                                           metadata={"source": "test"})


@pytest.fixture(scope="module")
def robot():
    r = MujocoRobot(randomization=False)
    yield r
    r.close()


def _reach_and_grasp(env, obs, max_steps=150):
    """The scripted policy of the simulated env's tests: over the object, down, close."""
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
            for _ in range(10):  # let the grip force build up
                obs, *_ = env.step(np.array([0, 0, 0, 0, -1, 0], np.float32))
            return obs
    raise AssertionError("the scripted policy did not grasp")


def test_spaces_equal_the_simulated_env(robot):
    assert isinstance(robot, RobotInterface)
    for kwargs in ({}, {"include_waveform": True}):
        env = RealGraspEnv(robot, _Recorder(), **kwargs)
        sim = gym.make("aas_gym/AcousticGrasp-v0", sense_mode="never", **kwargs)
        assert env.observation_space == sim.observation_space
        assert env.action_space == sim.action_space
        sim.close()


def test_bad_robot_or_sensor_is_refused():
    with pytest.raises(TypeError, match="missing \\['grasp', 'open', 'state'\\]"):
        RealGraspEnv(type("R", (), {"move": lambda self, tcp, d: None})(), _Recorder())
    with pytest.raises(TypeError, match="AcousticSensor"):
        RealGraspEnv(MujocoRobot.__new__(MujocoRobot), object())


def test_episode_logic_without_audio(robot):
    sensor = _Recorder()
    env = RealGraspEnv(robot, sensor, excitation="impulse", duration_s=0.5, include_waveform=True)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and not info["grasped"]
    # sensing while not grasped: features update, no success
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, 1, 1], np.float32))
    assert sensor.calls == [("impulse", 0.5)] and not terminated and reward < 0
    assert obs["waveform"].shape == (22050,)
    obs = _reach_and_grasp(env, obs)
    assert obs["gripper"][2] == pytest.approx(40.0, rel=0.05)
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, -1, 1], np.float32))
    assert terminated and info["is_success"] and reward > 10.5
    assert env.observation_space.contains(obs)


@pytest.fixture
def audio_loopback():
    pytest.importorskip("pyaudio")
    from real import loopback

    was_running = loopback.is_running()
    lb = loopback.start_loopback()
    yield lb
    if not was_running:
        loopback.stop_loopback(lb.runtime_dir)


@pytest.mark.audio
@pytest.mark.xdist_group("real_audio")
def test_grasp_and_sense_through_the_real_audio_path(robot, audio_loopback):
    sensor = real.RealAcousticSensor(real.PyAudioRig(output_gain=0.5))
    env = RealGraspEnv(robot, sensor, excitation="linear", duration_s=1.0)
    obs, _ = env.reset(seed=1)
    obs = _reach_and_grasp(env, obs)
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, -1, 1], np.float32))
    assert terminated and info["is_success"]
    meta = info["recording_metadata"]
    assert meta["source"] == "real" and meta["complete"] and meta["sync"]["drift_samples"] == 0
    np.testing.assert_allclose(obs["acoustic"], env.last_recording.features().astype(np.float32))
    assert env.observation_space.contains(obs) and obs["acoustic"].max() > 0


def test_robot_state_fields(robot):
    robot.reset(seed=3)
    s = robot.state()
    assert isinstance(s, RobotState)
    assert s.tcp.shape == (4,) and s.object_pose.shape == (7,) and not s.grasped
    assert s.gripper_opening_m == pytest.approx(0.08, abs=1e-3)


def test_check_env_control_only(robot):
    from gymnasium.utils.env_checker import check_env

    env = RealGraspEnv(robot, _Recorder(), sense_mode="never")
    check_env(env)
