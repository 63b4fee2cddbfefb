"""The grasp-and-sense task contract shared by the simulated envs (``aas_gym``) and the real
env (``real``): one place for the constants, the observation layout and the acoustic
observation's configuration, so a policy sees the same spaces on both sides.

Nothing here knows about MuJoCo or PyAudio; gymnasium is imported only by the helpers that
build spaces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..signals.features import FEATURE_SCALES, feature_frequencies_hz, scale_features

#: Length of the spectral feature vector (3-10 kHz in 50 Hz steps).
N_FEATURES = int(feature_frequencies_hz().size)
#: Where an episode starts: TCP x, y, z [m], yaw [rad].
HOME_TCP = (0.0, 0.0, 0.3, 0.0)
#: Largest TCP change per env step for action 1: 10 mm, 10 mm, 10 mm, 0.05 rad.
MAX_DELTA = (0.01, 0.01, 0.01, 0.05)
#: Grip forces an env accepts [N]: the Franka hand's continuous force is 70 N, its peak 140 N.
MAX_GRIP_FORCE_N = 140.0
#: Fully open gripper: distance between the fingertip faces [m].
MAX_OPENING_M = 0.08

#: Named slices of the proprioceptive state vector, in the order envs assemble it.
#: ``gripper`` is opening [m], opening speed [m/s], motor force [N]; ``object`` is the
#: target's position [m] and quaternion (w, x, y, z).
STATE_LAYOUT: dict[str, slice] = {
    "tcp": slice(0, 4),
    "tcp_velocity": slice(4, 8),
    "gripper": slice(8, 11),
    "object": slice(11, 18),
}
STATE_SIZE = 18

CADENCES = ("action", "every_step", "never", "stream")


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



def check_grip_force(grip_force_n: float) -> float:
    """``grip_force_n`` as a float, or ``ValueError`` if it is outside (0, 140] N."""
    f = float(grip_force_n)
    if not (math.isfinite(f) and 0 < f <= MAX_GRIP_FORCE_N):
        raise ValueError(f"grip_force_n must be in (0, {MAX_GRIP_FORCE_N:g}] N, got {grip_force_n!r}")
    return f


def check_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as a float64 array of ``shape``; ``ValueError`` for another shape or for
    NaN / infinite entries (``max(-1, min(1, nan))`` is 1: a NaN would be a full-speed move)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numeric with shape {shape}, got {type(action).__name__}") from None
    if a.shape != tuple(shape):
        if a.size == math.prod(shape) and a.squeeze().shape == tuple(s for s in shape if s != 1):
            a = a.reshape(shape)
        else:
            raise ValueError(f"action must have shape {tuple(shape)}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action has NaN or infinite entries: {a.tolist()}")
    return a


@dataclass(frozen=True)
class AcousticConfig:
    """How an env exposes the acoustic sensor: one configuration for every simulated env and
    for ``real.RealGraspEnv`` (as dm_control's observables: off until enabled, with noise as a
    separate corruption of the recording).

    Attributes:
        enabled: record at all; ``False`` drops the acoustic entries from the observation
            and costs nothing per step.
        cadence: ``"action"`` (record when the policy asks), ``"every_step"``, ``"never"`` or
            ``"stream"``: the microphone records without a break while the robot moves, the
            excitation looping; each step returns the samples recorded during it under
            ``audio`` and the features of the latest complete excitation period under
            ``acoustic`` (zeros until one is complete). Envs whose actions are probes
            (recognition, grasp position) record every step; streamed, a probe's ``audio`` is
            the ``duration_s`` the hand holds the grasp.
        waveform: add the raw recording (``waveform``, padded or cut to ``duration_s``).
        feature_scale: how the 140 features are scaled: ``"linear"`` (amplitudes, 1e-7 to
            1e-4), ``"db"`` (level relative to 1e-6, tens of dB) or ``"normalized"`` (unit
            norm); see :func:`sensors.signals.features.scale_features`. A policy network next to
            proprioception of order 1 needs ``"db"`` or ``"normalized"``.
        noise_std: std of additive microphone noise in waveform units (simulation only; the
            real microphone brings its own).
        duration_s: length of one recording [s].
    """

    enabled: bool = True
    cadence: str = "action"
    waveform: bool = False
    feature_scale: str = "linear"
    noise_std: float = 0.0
    duration_s: float = 1.0

    def __post_init__(self) -> None:
        if self.cadence not in CADENCES:
            raise ValueError(f"cadence must be one of {CADENCES}, got {self.cadence!r}")
        if self.feature_scale not in FEATURE_SCALES:
            raise ValueError(f"feature_scale must be one of {FEATURE_SCALES}, got {self.feature_scale!r}")
        if not (math.isfinite(self.noise_std) and self.noise_std >= 0):
            raise ValueError(f"noise_std must be >= 0, got {self.noise_std!r}")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"duration_s must be > 0 s, got {self.duration_s!r}")
        if self.cadence == "stream" and self.waveform:
            raise ValueError("waveform=True is for per-action recordings; a streamed observation "
                             "carries its samples under 'audio'")

    @classmethod
    def coerce(cls, value: "AcousticConfig | dict | None" = None, *, include_waveform: bool | None = None,
               duration_s: float | None = None, sense_mode: str | None = None,
               **defaults: Any) -> "AcousticConfig":
        """The env's config from ``acoustic=`` (``None``, a dict of fields or a config) and
        the older keywords ``include_waveform``, ``duration_s``, ``sense_mode``, which stay
        accepted as spellings of ``waveform``, ``duration_s`` and ``cadence``. ``defaults``
        are the env's own defaults for fields nobody set."""
        if value is None:
            fields: dict[str, Any] = {}
        elif isinstance(value, cls):
            fields = {f: getattr(value, f) for f in cls.__dataclass_fields__}
        elif isinstance(value, dict):
            fields = dict(value)
        else:
            raise TypeError(f"acoustic must be an AcousticConfig, a dict or None, got {type(value).__name__}")
        for name, given in (("waveform", include_waveform), ("duration_s", duration_s), ("cadence", sense_mode)):
            if given is None:
                continue
            if name in fields and fields[name] != given and value is not None:
                raise ValueError(f"acoustic.{name}={fields[name]!r} contradicts the keyword given as {given!r}")
            fields[name] = given
        return cls(**{**defaults, **fields})

    def n_samples(self, sample_rate_hz: float) -> int:
        """Samples in one recording at ``sample_rate_hz``."""
        return int(round(self.duration_s * sample_rate_hz))

    def scale_features(self, features: np.ndarray) -> np.ndarray:
        """The amplitude features in this config's ``feature_scale`` (float32)."""
        return scale_features(features, self.feature_scale).astype(np.float32)

    @property
    def streaming(self) -> bool:
        """Enabled with cadence ``"stream"``."""
        return self.enabled and self.cadence == "stream"

    def spaces(self, sample_rate_hz: float, audio_samples: int | None = None) -> dict:
        """The acoustic entries of the observation space (empty when disabled);
        ``audio_samples``: the length of a streamed step's ``audio``."""
        from gymnasium import spaces  # only env builders need gymnasium

        if not self.enabled:
            return {}
        low = -np.inf if self.feature_scale == "db" else 0.0
        out = {"acoustic": spaces.Box(low, np.inf, (N_FEATURES,), np.float32)}
        if self.waveform:
            out["waveform"] = spaces.Box(-np.inf, np.inf, (self.n_samples(sample_rate_hz),), np.float32)
        if self.streaming:
            out["audio"] = spaces.Box(-np.inf, np.inf, (self._audio_samples(audio_samples),), np.float32)
        return out

    def empty(self, sample_rate_hz: float, audio_samples: int | None = None) -> dict[str, np.ndarray]:
        """The acoustic entries before the first recording: zeros."""
        if not self.enabled:
            return {}
        out = {"acoustic": self.scale_features(np.zeros(N_FEATURES))}
        if self.waveform:
            out["waveform"] = np.zeros(self.n_samples(sample_rate_hz), np.float32)
        if self.streaming:
            out["audio"] = np.zeros(self._audio_samples(audio_samples), np.float32)
        return out

    def stream_entries(self, features: np.ndarray | None, audio: np.ndarray) -> dict[str, np.ndarray]:
        """The streamed entries: the latest complete period's features (zeros before one)
        and this step's samples."""
        f = np.zeros(N_FEATURES) if features is None else features
        return {"acoustic": self.scale_features(f), "audio": np.asarray(audio, np.float32)}

    @staticmethod
    def _audio_samples(audio_samples: int | None) -> int:
        if audio_samples is None or int(audio_samples) < 1:
            raise ValueError("a streaming env must say how many samples one step records (audio_samples)")
        return int(audio_samples)

    def entries(self, recording) -> dict[str, np.ndarray]:
        """The acoustic entries of a ``sensors.AcousticObservation``: its features and, with
        ``waveform``, its samples zero-padded or cut to ``duration_s``."""
        if not self.enabled:
            return {}
        out = {"acoustic": self.scale_features(recording.features())}
        if self.waveform:
            n = self.n_samples(recording.sample_rate_hz)
            w = np.zeros(n, np.float32)
            m = min(n, recording.waveform.size)
            w[:m] = recording.waveform[:m]
            out["waveform"] = w
        return out


def proprio_spaces(with_object: bool = True) -> dict:
    """Observation-space entries of the proprioceptive state (see ``STATE_LAYOUT``)."""
    from gymnasium import spaces

    out = {}
    for name, sl in STATE_LAYOUT.items():
        if name == "object" and not with_object:
            continue
        out[name] = spaces.Box(-np.inf, np.inf, (sl.stop - sl.start,), np.float32)
    return out
