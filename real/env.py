"""``RealGraspEnv``: the ``aas_gym/AcousticGrasp-v0`` task on a real robot and rig.

Same action and observation spaces as the simulated environment, so a policy or classifier
moves between them unchanged. The robot comes in through :class:`RobotInterface`, which a
user implements for their driver (e.g. franka_ros / libfranka); :class:`MujocoRobot` is an
implementation backed by the aas_gym MuJoCo scene, used to test the env's logic end to end
(with the real audio rig or with the scene's simulated sensor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sensors import AcousticSensor, Excitation

N_FEATURES = 140
HOME_TCP = (0.0, 0.0, 0.3, 0.0)
# Largest TCP change per step for action 1 (as in AcousticGrasp-v0): 10 mm, 0.05 rad.
MAX_DELTA = (0.01, 0.01, 0.01, 0.05)


@dataclass(frozen=True)
class RobotState:
    """What the env observes of the robot.

    Attributes:
        tcp: x, y, z [m], yaw [rad] of the tool centre point in the task frame.
        tcp_velocity: their rates [m/s, rad/s].
        gripper_opening_m: distance between the fingertip faces.
        gripper_speed_m_s: its rate.
        gripper_force_n: force the gripper motor applies (the grip force when squeezing).
        object_pose: target object position [m] and quaternion (w, x, y, z) in the task frame,
            from whatever tracks it (motion capture, vision, a fixture); zeros if unknown.
        grasped: both sensor fingertips press the object.
    """

    tcp: np.ndarray
    tcp_velocity: np.ndarray
    gripper_opening_m: float
    gripper_speed_m_s: float
    gripper_force_n: float
    object_pose: np.ndarray
    grasped: bool


@runtime_checkable
class RobotInterface(Protocol):
    """The robot as :class:`RealGraspEnv` drives it. Commands are set-points; ``move``
    is the one that lets time pass (one control period per env step).

    Optional: ``reset(seed=None)`` to bring the robot (and scene) to the start of an episode;
    without it the env opens the gripper and moves home.
    """

    def move(self, tcp: np.ndarray, duration_s: float) -> None:
        """Move the TCP towards ``tcp`` (x, y, z [m], yaw [rad]) for ``duration_s`` seconds."""
        ...

    def grasp(self, force_n: float) -> None:
        """Close the gripper and squeeze with ``force_n`` newtons."""
        ...

    def open(self) -> None:
        """Open the gripper fully."""
        ...

    def state(self) -> RobotState:
        """The current :class:`RobotState`."""
        ...


class RealGraspEnv(gym.Env):
    """Reach, grasp and sense one object with a real robot and acoustic sensor.

    Action and observation exactly as ``aas_gym/AcousticGrasp-v0``: Box(6) in [-1, 1] (TCP
    delta x, y, z, yaw scaled by 10 mm / 0.05 rad, gripper > 0 open / <= 0 grasp with
    ``grip_force_n``, sense > 0 records); Dict ``tcp``, ``tcp_velocity``, ``gripper``
    (opening, speed, motor force), ``object`` (pose), ``acoustic`` (140 features of the
    latest recording), ``waveform`` with ``include_waveform``. Reward: minus the TCP-object
    distance, +1 while grasped, +10 for a recording while grasped (ends the episode).

    Args:
        robot: a :class:`RobotInterface`.
        sensor: a ``sensors.AcousticSensor`` (:class:`real.RealAcousticSensor`, or any other).
        excitation: ``sensors.Excitation`` or name.
        duration_s: recording length.
        grip_force_n: grasp force.
        include_waveform: add the raw recording.
        sense_mode: ``"action"``, ``"every_step"`` or ``"never"``.
        control_period_s: time each step lets the robot move (the simulated env's 0.05 s).
        max_episode_steps: truncation (200 like the simulated env).
        home_tcp: where ``reset`` moves the TCP if the robot has no ``reset``.
        reset_duration_s: how long that move may take.
    """

    metadata = {"render_modes": []}

    def __init__(self, robot: RobotInterface, sensor: AcousticSensor, *, excitation="linear_sweep",
                 duration_s: float = 1.0, grip_force_n: float = 40.0, include_waveform: bool = False,
                 sense_mode: str = "action", control_period_s: float = 0.05, max_episode_steps: int = 200,
                 home_tcp=HOME_TCP, reset_duration_s: float = 3.0) -> None:
        missing = [m for m in ("move", "grasp", "open", "state") if not callable(getattr(robot, m, None))]
        if missing:
            raise TypeError(f"robot does not implement RobotInterface: missing {missing}")
        if not callable(getattr(sensor, "sense", None)):
            raise TypeError("sensor must implement sensors.AcousticSensor (a sense(excitation, duration_s) method)")
        if sense_mode not in ("action", "every_step", "never"):
            raise ValueError(f"sense_mode must be 'action', 'every_step' or 'never', got {sense_mode!r}")
        self.robot, self.sensor = robot, sensor
        self.excitation = excitation if isinstance(excitation, Excitation) else Excitation.by_name(excitation)
        self.duration_s = float(duration_s)
        if not self.duration_s >= self.excitation.period_s:
            raise ValueError(f"duration_s must be at least one excitation period ({self.excitation.period_s} s)")
        if not 0 < grip_force_n <= 140:
            raise ValueError(f"grip_force_n must be in (0, 140] N, got {grip_force_n}")
        self.grip_force_n = float(grip_force_n)
        self.include_waveform = bool(include_waveform)
        self.sense_mode = sense_mode
        self.control_period_s = float(control_period_s)
        self.max_episode_steps = int(max_episode_steps)
        self.home_tcp = np.asarray(home_tcp, dtype=float)
        self.reset_duration_s = float(reset_duration_s)
        self.n_samples = int(round(self.duration_s * self.excitation.fs))
        self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        inf = np.inf
        obs = {
            "tcp": spaces.Box(-inf, inf, (4,), np.float32),
            "tcp_velocity": spaces.Box(-inf, inf, (4,), np.float32),
            "gripper": spaces.Box(-inf, inf, (3,), np.float32),
            "object": spaces.Box(-inf, inf, (7,), np.float32),
            "acoustic": spaces.Box(0.0, inf, (N_FEATURES,), np.float32),
        }
        if self.include_waveform:
            obs["waveform"] = spaces.Box(-inf, inf, (self.n_samples,), np.float32)
        self.observation_space = spaces.Dict(obs)
        self._acoustic = self._empty_acoustic()
        self._target = self.home_tcp.copy()
        self._gripper_closed: bool | None = None
        self._steps = 0
        self.last_recording = None

    def _empty_acoustic(self) -> dict[str, np.ndarray]:
        out = {"acoustic": np.zeros(N_FEATURES, np.float32)}
        if self.include_waveform:
            out["waveform"] = np.zeros(self.n_samples, np.float32)
        return out

    def _obs(self, s: RobotState) -> dict[str, np.ndarray]:
        obs = {
            "tcp": np.asarray(s.tcp, np.float32).reshape(4),
            "tcp_velocity": np.asarray(s.tcp_velocity, np.float32).reshape(4),
            "gripper": np.array([s.gripper_opening_m, s.gripper_speed_m_s, s.gripper_force_n], np.float32),
            "object": np.asarray(s.object_pose, np.float32).reshape(7),
        }
        for key, value in self._acoustic.items():
            obs[key] = value.copy()
        return obs

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        reset = getattr(self.robot, "reset", None)
        if callable(reset):
            reset(seed=seed, options=options)
        else:
            self.robot.open()
            self.robot.move(self.home_tcp, self.reset_duration_s)
        self._gripper_closed = False
        self._steps = 0
        self._acoustic = self._empty_acoustic()
        s = self.robot.state()
        self._target = np.asarray(s.tcp, dtype=float).copy()
        return self._obs(s), {"grasped": bool(s.grasped)}

    def step(self, action):
        a = np.asarray(action, dtype=np.float64).reshape(6)
        a = np.clip(a, -1.0, 1.0)
        self._target = self._target + a[:4] * np.asarray(MAX_DELTA)
        close = not a[4] > 0
        if close != self._gripper_closed:  # command changes only: a real gripper re-grasps otherwise
            self.robot.grasp(self.grip_force_n) if close else self.robot.open()
            self._gripper_closed = close
        self.robot.move(self._target, self.control_period_s)
        s = self.robot.state()
        self._steps += 1
        tcp, obj = np.asarray(s.tcp, float), np.asarray(s.object_pose, float)
        dist = math.sqrt(float(np.sum((tcp[:3] - obj[:3]) ** 2)))
        grasped = bool(s.grasped)
        reward = -dist + (1.0 if grasped else 0.0)
        terminated = False
        info: dict[str, Any] = {"grasped": grasped, "is_success": False}
        if self.sense_mode == "every_step" or (self.sense_mode == "action" and a[5] > 0):
            rec = self.sensor.sense(self.excitation, self.duration_s)
            self.last_recording = rec
            self._acoustic = {"acoustic": np.asarray(rec.features(), dtype=np.float32)}
            if self.include_waveform:
                w = np.zeros(self.n_samples, np.float32)
                n = min(self.n_samples, rec.waveform.size)
                w[:n] = rec.waveform[:n]
                self._acoustic["waveform"] = w
            info["recording_metadata"] = rec.metadata
            s = self.robot.state()  # the grasp may have changed while recording
            info["recording_grasped"] = grasped = grasped and bool(s.grasped)
            if grasped and self.sense_mode == "action":
                reward += 10.0
                terminated = True
                info["is_success"] = True
        truncated = not terminated and self._steps >= self.max_episode_steps
        return self._obs(s), float(reward), terminated, truncated, info


class MujocoRobot:
    """:class:`RobotInterface` on the aas_gym MuJoCo scene (the floating Franka hand).

    ``reset`` places the objects as ``aas_gym/AcousticGrasp-v0`` does; ``move`` advances the
    physics by ``duration_s``. ``sim_sensor`` is the scene's ``aas_gym.SimAcousticSensor``, so
    the same env runs on simulated or real sound.

    Args:
        objects, scene, **env_kwargs: as for ``aas_gym/AcousticGrasp-v0``.
    """

    def __init__(self, objects=("aluminium_bar",), *, scene: str = "single", **env_kwargs) -> None:
        from aas_gym.envs.acoustic_grasp import AcousticGraspEnv

        self._env = AcousticGraspEnv(objects, scene=scene, sense_mode="never", **env_kwargs)
        self._env.reset(seed=0)
        self._gripper_force_n = self._env.grip_force_n

    @property
    def model(self):
        """The MuJoCo model of the current scene."""
        return self._env.model

    @property
    def data(self):
        """Its MjData."""
        return self._env.data

    @property
    def sim_sensor(self):
        """The scene's simulated acoustic sensor (``aas_gym.SimAcousticSensor``)."""
        return self._env.sensor

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """New episode: objects placed, hand home and open."""
        self._env.reset(seed=seed, options=options)

    def move(self, tcp, duration_s: float) -> None:
        import mujoco

        self._env.hand.command(self.data, tcp=np.asarray(tcp, float))
        mujoco.mj_step(self.model, self.data, nstep=max(1, int(round(duration_s / self.model.opt.timestep))))

    def grasp(self, force_n: float) -> None:
        self._env.hand.set_grip_force(force_n)
        self._env.hand.command(self.data, opening_m=0.0)

    def open(self) -> None:
        self._env.hand.command(self.data, opening_m=0.08)

    def state(self) -> RobotState:
        import mujoco

        hand, d, m = self._env.hand, self.data, self.model
        sensor = self._env.sensor
        target = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sensor.bodies[0])
        return RobotState(
            tcp=hand.tcp(d), tcp_velocity=hand.tcp_velocity(d), gripper_opening_m=hand.opening_m(d),
            gripper_speed_m_s=float(np.sum(hand.finger_velocity(d))),
            gripper_force_n=float(-d.actuator_force[hand.gripper_actuator]),
            object_pose=np.concatenate([d.xpos[target], d.xquat[target]]),
            grasped=sensor.grasped_body() == sensor.bodies[0])

    def close(self) -> None:
        self._env.close()
