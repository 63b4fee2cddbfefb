"""``RealGraspEnv``: the ``aas_gym/AcousticGrasp-v0`` task on a real robot and rig.

Same action and observation spaces, reward and success as the simulated environment (all
from ``sensors.task``), so a policy or classifier moves between them unchanged. The robot
comes in through :class:`RobotInterface`, which a user implements for their driver (e.g.
franka_ros / libfranka); ``aas_gym.robot.MujocoRobot`` implements it on the simulated scene,
to test the env's logic end to end. This package does not import ``aas_gym``.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sensors import AcousticSensor
from sensors.task import (HOME_TCP, AcousticConfig, AcousticEnvMixin, GraspHold, RobotState, check_grip_force,
                          check_integer, check_number, decode_grasp_action, grasp_reward_terms, next_tcp_target,
                          proprio_spaces, records_this_step, reward_total, step_success, tcp_object_distance_m)


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


class RealGraspEnv(AcousticEnvMixin, gym.Env):
    """Reach, grasp and sense one object with a real robot and acoustic sensor.

    The task of ``aas_gym/AcousticGrasp-v0``, its rules written once in ``sensors.task``
    (``action``, ``reward``, ``cadence``): Box(6) in [-1, 1] (TCP delta x, y, z, yaw scaled by
    10 mm / 0.05 rad, gripper > 0 open / <= 0 grasp with ``grip_force_n``, sense > 0
    records); Dict ``tcp``, ``tcp_velocity``, ``gripper`` (opening, speed, motor force),
    ``object`` (pose), ``acoustic`` (140 features of the latest recording), ``waveform`` with
    ``acoustic.waveform``. Reward (``info["reward_terms"]``: ``reach``, ``grasp``,
    ``success``): minus the TCP-object distance, +1 while grasped, +10 for a recording while
    grasped (ends the episode).

    ``acoustic={"cadence": "stream"}`` (with a :class:`real.RealAcousticSensor`): the rig
    records without a break while the excitation loops (a :class:`real.RigStream`, started by
    ``reset``, closed by ``close``). Each step's ``audio`` holds the
    ``round(control_period_s * sample_rate_hz)`` samples recorded from when the move starts
    (``info["audio_phase_samples"]`` is their excitation phase; an episode's first step waits
    for phase 0, at most one period, as the simulated stream starts there), ``acoustic`` the
    features of the latest complete excitation period.
    The sense action then ends the episode with success once that period was recorded entirely
    after the grasp was first reported at a step's end; ``info["stream_problems"]`` lists
    xruns and lost alignment so far.

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `robot` | :class:`RobotInterface` | (required) | the robot driver |
    | `sensor` | `sensors.AcousticSensor` | (required) | :class:`real.RealAcousticSensor`, or any other |
    | `acoustic` | `sensors.task.AcousticConfig`, dict of its fields, or None | None | the same configuration as the simulated envs': `excitation`, `cadence`, `duration_s`, `waveform`, `feature_scale`, `enabled`, `features`, `history`, `update_period_s` (in control periods' time: `k * control_period_s` is every k-th step), `corruption` (the same pipeline and seeding as in simulation; streamed, over the unbroken stream from the first step's audio); its simulation-only fields (`noise_std`, `leak`, `fingertip`, `stream_tolerance`) are not used |
    | `grip_force_n` | float | 40.0 | grasp force [N], in (0, 140] |
    | `control_period_s` | float | 0.05 | time each step lets the robot move [s] (the simulated env's step) |
    | `max_episode_steps` | int | 200 | truncation (as the simulated env) |
    | `home_tcp` | sequence of 4 floats | `HOME_TCP` | where ``reset`` moves the TCP if the robot has no ``reset`` |
    | `reset_duration_s` | float | 3.0 | how long that move may take [s] |

    Deprecated (one more release, with a `DeprecationWarning`): the keywords `excitation`,
    `duration_s`, `include_waveform`, `sense_mode` beside `acoustic=`.
    """

    metadata = {"render_modes": []}
    #: The old keywords this env accepted beside ``acoustic=`` (deprecated).
    _LEGACY = ("excitation", "duration_s", "include_waveform", "sense_mode")

    def __init__(self, robot: RobotInterface, sensor: AcousticSensor, *,
                 acoustic: AcousticConfig | dict | None = None, grip_force_n: float = 40.0,
                 control_period_s: float = 0.05, max_episode_steps: int = 200, home_tcp=HOME_TCP,
                 reset_duration_s: float = 3.0, **deprecated) -> None:
        unknown = sorted(set(deprecated) - set(self._LEGACY))
        if unknown:
            raise TypeError(f"RealGraspEnv() got an unexpected keyword argument {unknown[0]!r}")
        missing = [m for m in ("move", "grasp", "open", "state") if not callable(getattr(robot, m, None))]
        if missing:
            raise TypeError(f"robot does not implement RobotInterface: missing {missing}")
        if not callable(getattr(sensor, "sense", None)):
            raise TypeError("sensor must implement sensors.AcousticSensor (a sense(excitation, duration_s) method)")
        self.robot, self.sensor = robot, sensor
        self.acoustic = AcousticConfig.coerce(acoustic, legacy=deprecated, owner="RealGraspEnv")
        self.grip_force_n = check_grip_force(grip_force_n)
        # Checked like the simulated envs' arguments: a bool or a string is no number here.
        self.control_period_s = check_number("control_period_s", control_period_s, 0.0, 10.0, low_open=True, unit="s")
        self.max_episode_steps = check_integer("max_episode_steps", max_episode_steps, 1)
        self.home_tcp = np.asarray(home_tcp, dtype=float)
        if self.home_tcp.shape != (4,) or not np.all(np.isfinite(self.home_tcp)):
            raise ValueError(f"home_tcp must be 4 finite numbers (x, y, z [m], yaw [rad]), got {home_tcp!r}")
        self.reset_duration_s = check_number("reset_duration_s", reset_duration_s, 0.0, 60.0, unit="s")
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
            self.audio_samples if self.acoustic.streaming else None)})
        self._init_acoustic_frames(self.audio_samples if self.acoustic.streaming else None, self.control_period_s)
        self._acoustic = self._empty_acoustic()
        self._target = self.home_tcp.copy()
        self._gripper_closed: bool | None = None
        self._steps = 0
        self.last_recording = None
        self.stream = None  # the RigStream of the episode (cadence "stream")
        self._stream_corruption = None  # its sensors.signals.CorruptedStream (acoustic.corruption)
        self._hold = GraspHold(self.excitation.period_samples)

    def _empty_acoustic(self) -> dict[str, np.ndarray]:
        return self.acoustic_frames.zeros()

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
        self._reset_acoustic()
        reset = getattr(self.robot, "reset", None)
        if callable(reset):
            reset(seed=seed, options=options)
        else:
            self.robot.open()
            self.robot.move(self.home_tcp, self.reset_duration_s)
        self._gripper_closed = False
        self._steps = 0
        self._acoustic = self._empty_acoustic()
        self._hold.reset()
        if self.acoustic.streaming:
            self._start_stream()
        s = self.robot.state()
        self._target = np.asarray(s.tcp, dtype=float).copy()
        return self._obs(s), {"grasped": bool(s.grasped)}

    def step(self, action):
        # NaN or inf must never reach a real robot: refuse before any command is sent.
        act = decode_grasp_action(action)
        if self.acoustic.streaming and self.stream is None:
            raise RuntimeError("reset() starts the acoustic stream: call it before step()")
        self._target = np.array(next_tcp_target(self._target.tolist(), act.tcp_delta))
        close = not act.open_gripper
        if close != self._gripper_closed:  # command changes only: a real gripper re-grasps otherwise
            self.robot.grasp(self.grip_force_n) if close else self.robot.open()
            self._gripper_closed = close
        if self.stream is not None:
            # This step's audio starts as the move does; an episode's first, at phase 0.
            before = self.stream.position
            skipped = self.stream.catch_up(period_start=self._steps == 0)
            self._advance_stream_corruption(before, skipped)
            audio_start = self.stream.position
        self.robot.move(self._target, self.control_period_s)
        s = self.robot.state()
        self._steps += 1
        due = self._acoustic_due()  # acoustic.update_period_s
        distance_m = tcp_object_distance_m(s.tcp, s.object_pose)
        grasped = bool(s.grasped)
        info: dict[str, Any] = {"grasped": grasped, "is_success": False}
        cadence = self.cadence
        success = False
        if cadence == "stream":
            audio, features = self.stream.read(self.audio_samples), self.stream.latest_features()
            if self._stream_corruption is not None:
                audio = self._stream_corruption.process(audio).astype(np.float32)
                features = self._stream_corruption.latest_features()
            if due:
                self._acoustic = self.acoustic_frames.push(self.acoustic.stream_entries(features, audio))
            info["audio_phase_samples"] = audio_start % self.excitation.period_samples
            info["stream_problems"] = self.stream.problems
            self._hold.update(grasped, self.stream.position)
            success = step_success(cadence, sense=act.sense, grasped=grasped,
                                   heard_whole_period=self._hold.heard_whole_period(self.stream.latest_features_period))
        elif due and records_this_step(cadence, act.sense):
            rec = self.sensor.sense(self.excitation, self.duration_s)
            self.last_recording = rec
            self._acoustic = self._recording_entries(rec)
            info["recording_metadata"] = rec.metadata
            s = self.robot.state()  # the grasp may have changed while recording
            info["recording_grasped"] = grasped and bool(s.grasped)
            success = step_success(cadence, sense=act.sense, grasped=grasped,
                                   recording_grasped=info["recording_grasped"])
        terms = grasp_reward_terms(distance_m, grasped, success)
        info["is_success"] = success
        info["reward_terms"] = terms
        truncated = not success and self._steps >= self.max_episode_steps
        return self._obs(s), reward_total(terms), success, truncated, info

    def _advance_stream_corruption(self, before: int, skipped: int) -> None:
        """The corrupted stream (``acoustic.corruption``) starts at the episode's first step's
        audio (period phase 0), a new one spawned from ``corruption_rng``; later, the samples
        a step's ``catch_up`` skipped go through it too, so it corrupts one unbroken stream
        (its latency, drift, buffer grid and noise run on as in simulation)."""
        if self._steps == 0:
            self._stream_corruption = self.acoustic.corrupted_stream(self.corruption_rng, self.excitation)
        elif self._stream_corruption is not None and skipped:
            self._stream_corruption.process(self.stream.samples(before, before + skipped))

    def _start_stream(self) -> None:
        """A new stream for the episode (nothing of the last one carries over), aligned."""
        from .rig_stream import RigStream

        self.close()
        self.stream = RigStream(self.sensor.rig, self.excitation).start()
        self.stream.catch_up()
        self._hold.reset()

    def close(self) -> None:
        """Close the stream (cadence ``"stream"``) and release the rig's devices."""
        if self.stream is not None:
            self.stream.close()
            self.stream = None
