"""``RealGraspEnv``: the ``aas_gym/AcousticGrasp-v0`` task on a real robot and rig.

Same action and observation spaces as the simulated environment (both built from
``sensors.task.grasp``), so a policy or classifier moves between them unchanged. The robot
comes in through :class:`RobotInterface`, which a user implements for their driver (e.g.
franka_ros / libfranka); ``aas_gym.robot.MujocoRobot`` implements it on the simulated scene,
to test the env's logic end to end. This package does not import ``aas_gym``.
"""

from __future__ import annotations

import math
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sensors import AcousticSensor, Excitation
from sensors.task.grasp import (HOME_TCP, MAX_DELTA, AcousticConfig, RobotState, check_action, check_grip_force,
                                proprio_spaces)


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

    ``acoustic={"cadence": "stream"}`` (with a :class:`real.RealAcousticSensor`): the rig
    records without a break while the excitation loops (a :class:`real.RigStream`, started by
    ``reset``, closed by ``close``). Each step's ``audio`` holds the
    ``round(control_period_s * sample_rate_hz)`` samples recorded from when the move starts
    (``info["audio_phase_samples"]`` is their excitation phase; an episode's first step waits
    for phase 0, at most one period, as the simulated stream starts there), ``acoustic`` the
    features of the latest complete excitation period.
    The sense action then ends the episode with success once the object was grasped through
    a whole period; ``info["stream_problems"]`` lists xruns and lost alignment so far.

    Args:
        robot: a :class:`RobotInterface`.
        sensor: a ``sensors.AcousticSensor`` (:class:`real.RealAcousticSensor`, or any other).
        excitation: ``sensors.Excitation`` or name.
        acoustic: ``sensors.task.grasp.AcousticConfig`` (or a dict of its fields): when to
            record (``cadence``), recording length, waveform in the observation, feature
            scale; the same configuration as the simulated envs'.
        grip_force_n: grasp force.
        duration_s, include_waveform, sense_mode: older spellings of ``acoustic.duration_s``,
            ``acoustic.waveform`` and ``acoustic.cadence``.
        control_period_s: time each step lets the robot move (the simulated env's 0.05 s).
        max_episode_steps: truncation (200 like the simulated env).
        home_tcp: where ``reset`` moves the TCP if the robot has no ``reset``.
        reset_duration_s: how long that move may take.
    """

    metadata = {"render_modes": []}

    def __init__(self, robot: RobotInterface, sensor: AcousticSensor, *, excitation="linear",
                 acoustic: AcousticConfig | dict | None = None, grip_force_n: float = 40.0,
                 duration_s: float | None = None, include_waveform: bool | None = None,
                 sense_mode: str | None = None, control_period_s: float = 0.05, max_episode_steps: int = 200,
                 home_tcp=HOME_TCP, reset_duration_s: float = 3.0) -> None:
        missing = [m for m in ("move", "grasp", "open", "state") if not callable(getattr(robot, m, None))]
        if missing:
            raise TypeError(f"robot does not implement RobotInterface: missing {missing}")
        if not callable(getattr(sensor, "sense", None)):
            raise TypeError("sensor must implement sensors.AcousticSensor (a sense(excitation, duration_s) method)")
        self.robot, self.sensor = robot, sensor
        self.excitation = excitation if isinstance(excitation, Excitation) else Excitation.by_name(excitation)
        self.acoustic = AcousticConfig.coerce(acoustic, include_waveform=include_waveform, duration_s=duration_s,
                                              sense_mode=sense_mode)
        if not self.acoustic.duration_s >= self.excitation.period_s:
            raise ValueError(f"duration_s must be at least one excitation period ({self.excitation.period_s} s)")
        self.grip_force_n = check_grip_force(grip_force_n)
        self.control_period_s = float(control_period_s)
        self.max_episode_steps = int(max_episode_steps)
        self.home_tcp = np.asarray(home_tcp, dtype=float)
        self.reset_duration_s = float(reset_duration_s)
        self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.audio_samples = int(round(self.control_period_s * self.excitation.sample_rate_hz))
        if self.acoustic.streaming:
            from .sensor import RealAcousticSensor  # PortAudio only for a streaming env

            if not isinstance(sensor, RealAcousticSensor):
                raise TypeError(f"acoustic cadence 'stream' needs a real.RealAcousticSensor (its rig streams), "
                                f"got {type(sensor).__name__}")
            if self.audio_samples < 1:
                raise ValueError(f"control_period_s={control_period_s} s holds no sample at "
                                 f"{self.excitation.sample_rate_hz} Hz")
        self.observation_space = spaces.Dict({**proprio_spaces(), **self.acoustic.spaces(
            self.excitation.sample_rate_hz, self.audio_samples if self.acoustic.streaming else None)})
        self._acoustic = self._empty_acoustic()
        self._target = self.home_tcp.copy()
        self._gripper_closed: bool | None = None
        self._steps = 0
        self.last_recording = None
        self.stream = None  # the RigStream of the episode (cadence "stream")
        self._grasped_from: int | None = None  # stream index from which the grasp held

    @property
    def duration_s(self) -> float:
        return self.acoustic.duration_s

    @property
    def sense_mode(self) -> str:
        return self.acoustic.cadence

    def _empty_acoustic(self) -> dict[str, np.ndarray]:
        return self.acoustic.empty(self.excitation.sample_rate_hz,
                                   self.audio_samples if self.acoustic.streaming else None)

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
        if self.acoustic.streaming:
            self._start_stream()
        s = self.robot.state()
        self._target = np.asarray(s.tcp, dtype=float).copy()
        return self._obs(s), {"grasped": bool(s.grasped)}

    def step(self, action):
        # NaN or inf must never reach a real robot: refuse before any command is sent.
        a = np.clip(check_action(action, (6,)), -1.0, 1.0)
        if self.acoustic.streaming and self.stream is None:
            raise RuntimeError("reset() starts the acoustic stream: call it before step()")
        self._target = self._target + a[:4] * np.asarray(MAX_DELTA)
        close = not a[4] > 0
        if close != self._gripper_closed:  # command changes only: a real gripper re-grasps otherwise
            self.robot.grasp(self.grip_force_n) if close else self.robot.open()
            self._gripper_closed = close
        if self.stream is not None:
            # This step's audio starts as the move does; an episode's first, at phase 0.
            self.stream.catch_up(period_start=self._steps == 0)
            audio_start = self.stream.position
        self.robot.move(self._target, self.control_period_s)
        s = self.robot.state()
        self._steps += 1
        tcp, obj = np.asarray(s.tcp, float), np.asarray(s.object_pose, float)
        dist = math.sqrt(float(np.sum((tcp[:3] - obj[:3]) ** 2)))
        grasped = bool(s.grasped)
        reward = -dist + (1.0 if grasped else 0.0)
        terminated = False
        info: dict[str, Any] = {"grasped": grasped, "is_success": False}
        cadence = self.acoustic.cadence if self.acoustic.enabled else "never"
        if cadence == "stream":
            audio = self.stream.read(self.audio_samples)
            self._acoustic = self.acoustic.stream_entries(self.stream.latest_features(), audio)
            info["audio_phase_samples"] = audio_start % self.excitation.period_samples
            info["stream_problems"] = self.stream.problems
            # Success: asked to stop while grasping, after a whole period recorded through the grasp.
            if not grasped:
                self._grasped_from = None
            elif self._grasped_from is None:
                self._grasped_from = audio_start
            k = self.stream.latest_features_period
            if a[5] > 0 and grasped and k >= 0 and k * self.excitation.period_samples >= self._grasped_from:
                reward += 10.0
                terminated = True
                info["is_success"] = True
        elif cadence == "every_step" or (cadence == "action" and a[5] > 0):
            rec = self.sensor.sense(self.excitation, self.duration_s)
            self.last_recording = rec
            self._acoustic = self.acoustic.entries(rec)
            info["recording_metadata"] = rec.metadata
            s = self.robot.state()  # the grasp may have changed while recording
            info["recording_grasped"] = grasped = grasped and bool(s.grasped)
            if grasped and cadence == "action":
                reward += 10.0
                terminated = True
                info["is_success"] = True
        truncated = not terminated and self._steps >= self.max_episode_steps
        return self._obs(s), float(reward), terminated, truncated, info

    def _start_stream(self) -> None:
        """A new stream for the episode (nothing of the last one carries over), aligned."""
        from .rig_stream import RigStream

        self.close()
        self.stream = RigStream(self.sensor.rig, self.excitation).start()
        self.stream.catch_up()
        self._grasped_from = None

    def close(self) -> None:
        """Close the stream (cadence ``"stream"``) and release the rig's devices."""
        if self.stream is not None:
            self.stream.close()
            self.stream = None
