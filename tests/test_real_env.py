"""RealGraspEnv: the simulated env's spaces, driven through RobotInterface, sensing through
the MuJoCo-backed robot. The end-to-end test through the real audio path lives in
test_real_audio.py, the one file that uses the sound server."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
import aas_gym  # noqa: E402,F401

from aas_gym.robot import MujocoRobot  # noqa: E402
from real.env import RealGraspEnv, RobotInterface, RobotState  # noqa: E402
from scripted_policy import reach_and_grasp, reach_until_grasped  # noqa: E402


class Recorder:
    """A minimal AcousticSensor for the non-audio tests: it says what it was asked."""

    def __init__(self):
        self.calls = []

    def sense(self, excitation, duration_s):
        import sensors

        self.calls.append((excitation.name, duration_s))
        return sensors.AcousticObservation(excitation.loop(duration_s), excitation.sample_rate_hz, excitation,
                                           metadata={"source": "test"})


@pytest.fixture(scope="module")
def robot():
    r = MujocoRobot(randomization=False)
    yield r
    r.close()


def test_spaces_equal_the_simulated_env(robot):
    assert isinstance(robot, RobotInterface)
    for acoustic in ({}, {"waveform": True}):
        env = RealGraspEnv(robot, Recorder(), acoustic=acoustic)
        sim = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never", **acoustic})
        assert env.observation_space == sim.observation_space
        assert env.action_space == sim.action_space
        sim.close()


def test_bad_robot_or_sensor_is_refused():
    with pytest.raises(TypeError, match="missing \\['grasp', 'open', 'state'\\]"):
        RealGraspEnv(type("R", (), {"move": lambda self, tcp, d: None})(), Recorder())
    with pytest.raises(TypeError, match="AcousticSensor"):
        RealGraspEnv(MujocoRobot.__new__(MujocoRobot), object())


def test_episode_logic_without_audio(robot):
    sensor = Recorder()
    env = RealGraspEnv(robot, sensor, acoustic={"excitation": "impulse", "duration_s": 0.5, "waveform": True})
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and not info["grasped"]
    # sensing while not grasped: features update, no success
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, 1, 1], np.float32))
    assert sensor.calls == [("impulse", 0.5)] and not terminated and reward < 0
    assert obs["waveform"].shape == (22050,)
    obs = reach_and_grasp(env, obs)
    assert obs["gripper"][2] == pytest.approx(40.0, rel=0.05)
    obs, reward, terminated, truncated, info = env.step(np.array([0, 0, 0, 0, -1, 1], np.float32))
    assert terminated and info["is_success"] and reward > 10.5
    assert env.observation_space.contains(obs)


def test_the_simulated_and_the_real_env_share_the_task_rules(robot):
    """One episode, the same actions, through aas_gym/AcousticGrasp-v0 and through
    RealGraspEnv on the MuJoCo robot: the same trajectory, reward terms and success step
    (the object pose differs by MuJoCo's one-step lag of body positions, micrometres)."""
    sim = gym.make("aas_gym/AcousticGrasp-v0", randomization=False, acoustic={"duration_s": 0.5})
    env = RealGraspEnv(robot, Recorder(), acoustic={"duration_s": 0.5})

    class Log:  # the scripted policy's actions on the simulated env
        actions = []

        def step(self, a):
            self.actions.append(np.array(a, np.float32))
            return sim.step(a)

    obs, _ = sim.reset(seed=0)
    reach_until_grasped(Log(), obs)
    actions = Log.actions + [np.array([0, 0, 0, 0, -1, 0], np.float32)] * 10 + [np.array([0, 0, 0, 0, -1, 1], np.float32)]
    sim.reset(seed=0)
    env.reset(seed=0)
    for a in actions:
        s_obs, s_reward, s_done, _, s_info = sim.step(a)
        r_obs, r_reward, r_done, _, r_info = env.step(a)
        np.testing.assert_array_equal(s_obs["tcp"], r_obs["tcp"])
        assert s_info["grasped"] == r_info["grasped"] and s_done == r_done
        s_terms, r_terms = s_info["reward_terms"], r_info["reward_terms"]
        assert s_terms.keys() == r_terms.keys() and s_terms["grasp"] == r_terms["grasp"]
        assert s_terms["success"] == r_terms["success"] and s_terms["reach"] == pytest.approx(r_terms["reach"], abs=1e-5)
    assert s_done and r_info["is_success"] and r_reward == pytest.approx(s_reward, abs=1e-5) and r_reward > 10.5
    sim.close()


def test_robot_state_fields(robot):
    robot.reset(seed=3)
    s = robot.state()
    assert isinstance(s, RobotState)
    assert s.tcp.shape == (4,) and s.object_pose.shape == (7,) and not s.grasped
    assert s.gripper_opening_m == pytest.approx(0.08, abs=1e-3)


def test_check_env_control_only(robot):
    from gymnasium.utils.env_checker import check_env

    env = RealGraspEnv(robot, Recorder(), acoustic={"cadence": "never"})
    check_env(env)


class CommandLog:
    """A user's robot driver as RealGraspEnv sees it: it records every command it receives."""

    def __init__(self):
        self.commands = []

    def move(self, tcp, duration_s):
        self.commands.append(("move", np.asarray(tcp, float).copy()))

    def grasp(self, force_n):
        self.commands.append(("grasp", force_n))

    def open(self):
        self.commands.append(("open",))

    def state(self):
        return RobotState(np.zeros(4), np.zeros(4), 0.08, 0.0, 0.0, np.array([0.1, 0, 0, 1, 0, 0, 0.0]), False)


@pytest.mark.parametrize("bad", [[np.nan, 0, 0, 0, 0, 0], [0, 0, np.inf, 0, 0, 0], [0, 0, 0, 0, 0], [[0] * 6] * 2])
def test_nonfinite_or_misshapen_action_never_reaches_the_robot(bad):
    robot = CommandLog()
    env = RealGraspEnv(robot, Recorder())
    env.reset(seed=0)
    sent = len(robot.commands)
    with pytest.raises(ValueError, match="action"):
        env.step(np.array(bad, dtype=float))
    assert len(robot.commands) == sent


def test_acoustic_config_and_its_dict_agree():
    from sensors.task import AcousticConfig

    a = RealGraspEnv(CommandLog(), Recorder(), acoustic={"waveform": True, "duration_s": 0.5, "cadence": "every_step"})
    b = RealGraspEnv(CommandLog(), Recorder(), acoustic=AcousticConfig(waveform=True, duration_s=0.5,
                                                                         cadence="every_step"))
    assert a.acoustic == b.acoustic and a.observation_space == b.observation_space
    c = RealGraspEnv(CommandLog(), Recorder(), acoustic={"feature_scale": "db"})
    obs, _ = c.reset(seed=0)
    obs, *_ = c.step(np.array([0, 0, 0, 0, 1, 1], np.float32))
    assert c.observation_space.contains(obs) and obs["acoustic"].max() > 0  # dB re 1e-6: tens of dB
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="contradicts"):
        RealGraspEnv(CommandLog(), Recorder(), acoustic={"waveform": False}, include_waveform=True)


def test_streaming_needs_the_rig():
    with pytest.raises(TypeError, match="cadence 'stream' needs a real.RealAcousticSensor"):
        RealGraspEnv(CommandLog(), Recorder(), acoustic={"cadence": "stream"})
