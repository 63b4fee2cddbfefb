"""Corruptions of a recording, as a real rig brings them, separate from the clean signal
(dm_control's corruptor idea): each stage is a small frozen dataclass with an
``apply(waveform, sample_rate_hz, rng)`` that returns a new waveform (full scale 1), and a
:class:`CorruptionPipeline` composes stages in the order given. All randomness comes from the
``rng`` passed in (the envs pass a generator spawned from their ``np_random``), so the same
seed gives the same corruption in simulation and on the rig.

A physically ordered chain: ``BackgroundNoise`` (what the microphone hears) -> ``GainDrift``
(the preamplifier) -> ``DCOffset`` -> ``Clipping`` (the converter's full scale) ->
``DroppedBuffers`` (the driver) -> ``Latency``.

On a stream (``cadence="stream"``) the same stages run chunk by chunk:
``sensors.signals.stream_corruption``.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .noise_library import check_noise_source, noise_segment

__all__ = ["BackgroundNoise", "Clipping", "CorruptionPipeline", "DCOffset", "DroppedBuffers", "GainDrift",
           "Latency", "STAGES"]


def _number(name: str, value: Any, low: float = 0.0, high: float = np.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and low <= value <= high):
        raise ValueError(f"{name} must be a finite number in [{low:g}, {high:g}], got {value!r}")
    return value


class _Stage:
    """Checks every float field as a non-negative number (subclasses narrow further)."""

    _ranges: dict[str, tuple[float, float]] = {}

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.type in ("float", float):
                low, high = self._ranges.get(f.name, (0.0, np.inf))
                object.__setattr__(self, f.name, _number(f"{type(self).__name__}.{f.name}", getattr(self, f.name),
                                                         low, high))

    def to_dict(self) -> dict:
        """``{"kind": <name>, **fields}``: what :meth:`CorruptionPipeline.coerce` reads back."""
        return {"kind": _KIND_OF[type(self)], **dataclasses.asdict(self)}


@dataclass(frozen=True)
class GainDrift(_Stage):
    """A gain that is off and drifts during the recording: ``gain_db(t) = g0 + slope * t``
    with ``g0 ~ Normal(0, gain_std_db)`` and ``slope ~ Uniform(-drift_db_per_s,
    drift_db_per_s)`` drawn per recording (``t`` from the recording's start)."""

    gain_std_db: float = 0.0
    drift_db_per_s: float = 0.0
    _ranges = {"gain_std_db": (0.0, 40.0), "drift_db_per_s": (0.0, 40.0)}

    def gain_db(self, n_samples: int, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """The per-sample gain [dB] this stage draws (same draws as :meth:`apply`)."""
        g0 = float(rng.normal(0.0, self.gain_std_db)) if self.gain_std_db > 0 else 0.0
        slope = float(rng.uniform(-self.drift_db_per_s, self.drift_db_per_s)) if self.drift_db_per_s > 0 else 0.0
        return g0 + slope * np.arange(n_samples) / sample_rate_hz

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        return waveform * 10.0 ** (self.gain_db(waveform.size, sample_rate_hz, rng) / 20.0)


@dataclass(frozen=True)
class DCOffset(_Stage):
    """A constant offset added to every sample: ``offset_fs + Normal(0, offset_std_fs)``
    (full-scale units), drawn per recording."""

    offset_fs: float = 0.0
    offset_std_fs: float = 0.0
    _ranges = {"offset_fs": (-1.0, 1.0)}

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        extra = float(rng.normal(0.0, self.offset_std_fs)) if self.offset_std_fs > 0 else 0.0
        return waveform + (self.offset_fs + extra)


@dataclass(frozen=True)
class Latency(_Stage):
    """The recording starts late: delayed by ``round((latency_s + Uniform(0, jitter_s)) *
    sample_rate_hz)`` samples, zeros first, the length kept (the tail is lost)."""

    latency_s: float = 0.0
    jitter_s: float = 0.0
    _ranges = {"latency_s": (0.0, 10.0), "jitter_s": (0.0, 10.0)}

    def delay_samples(self, sample_rate_hz: float, rng: np.random.Generator) -> int:
        """The delay [samples] this stage draws (same draw as :meth:`apply`)."""
        jitter = float(rng.uniform(0.0, self.jitter_s)) if self.jitter_s > 0 else 0.0
        return int(round((self.latency_s + jitter) * sample_rate_hz))

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        d = min(self.delay_samples(sample_rate_hz, rng), waveform.size)
        out = np.zeros_like(waveform)
        out[d:] = waveform[:waveform.size - d]
        return out


@dataclass(frozen=True)
class DroppedBuffers(_Stage):
    """The driver loses buffers: the recording cut into buffers of ``buffer_samples`` (from
    its start), each zeroed with probability ``probability``, independently."""

    probability: float = 0.0
    buffer_samples: int = 1024
    _ranges = {"probability": (0.0, 1.0)}

    def __post_init__(self) -> None:
        super().__post_init__()
        if isinstance(self.buffer_samples, bool) or not isinstance(self.buffer_samples, (int, np.integer)) \
                or self.buffer_samples < 1:
            raise ValueError(f"DroppedBuffers.buffer_samples must be a positive integer, got {self.buffer_samples!r}")
        object.__setattr__(self, "buffer_samples", int(self.buffer_samples))

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        n_buffers = -(-waveform.size // self.buffer_samples)
        dropped = rng.random(n_buffers) < self.probability
        keep = np.repeat(~dropped, self.buffer_samples)[:waveform.size]
        return np.where(keep, waveform, 0.0)


@dataclass(frozen=True)
class Clipping(_Stage):
    """The converter saturates: samples clipped to ``[-full_scale, full_scale]``."""

    full_scale: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.full_scale > 0:
            raise ValueError(f"Clipping.full_scale must be positive, got {self.full_scale!r}")

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        return np.clip(waveform, -self.full_scale, self.full_scale)


@dataclass(frozen=True)
class BackgroundNoise(_Stage):
    """Additive background noise at ``level_dbfs`` (its RMS relative to full scale 1, dB):
    from the noise library (``source`` one of ``sensors.signals.noise_library.NOISE_KINDS``:
    ``"white"``, ``"pink"``, ``"room"``, ``"motor"``) or from a folder of ``.wav``/``.npz``
    recordings (``source`` its path). A fresh segment is drawn per recording."""

    level_dbfs: float = -120.0
    source: str = "room"
    _ranges = {"level_dbfs": (-300.0, 20.0)}

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.source, (str, os.PathLike)):
            raise TypeError(f"BackgroundNoise.source must be a noise kind or a folder path, got {self.source!r}")
        object.__setattr__(self, "source", check_noise_source(self.source))  # a typo fails here, not after a grasp

    @property
    def rms_fs(self) -> float:
        """The noise RMS in full-scale units."""
        return 10.0 ** (self.level_dbfs / 20.0)

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        return waveform + self.rms_fs * noise_segment(self.source, waveform.size, int(sample_rate_hz), rng)


#: Stage classes by the ``kind`` a dict names them with.
STAGES = {"background_noise": BackgroundNoise, "gain_drift": GainDrift, "dc_offset": DCOffset,
          "clipping": Clipping, "dropped_buffers": DroppedBuffers, "latency": Latency}
_KIND_OF = {cls: kind for kind, cls in STAGES.items()}


@dataclass(frozen=True)
class CorruptionPipeline:
    """Stages applied in order to each recording (``stages``: instances of :data:`STAGES`)."""

    stages: tuple = ()

    def __post_init__(self) -> None:
        stages = tuple(self.stages)
        for s in stages:
            if type(s) not in _KIND_OF:
                raise TypeError(f"a corruption stage must be one of {[c.__name__ for c in STAGES.values()]}, got {s!r}")
        object.__setattr__(self, "stages", stages)

    def __bool__(self) -> bool:
        return bool(self.stages)

    @classmethod
    def coerce(cls, value: "CorruptionPipeline | Sequence | None") -> "CorruptionPipeline":
        """A pipeline from a pipeline, ``None`` (no stage), or a sequence of stages or of dicts
        ``{"kind": "clipping", "full_scale": 0.5}`` (kinds: :data:`STAGES`)."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, (str, bytes, dict)) or not isinstance(value, Sequence):
            raise TypeError("corruption must be a CorruptionPipeline, a sequence of stages or of dicts "
                            f"with a 'kind' ({sorted(STAGES)}), or None; got {value!r}")
        stages = []
        for item in value:
            if isinstance(item, dict):
                fields = dict(item)
                kind = fields.pop("kind", None)
                if kind not in STAGES:
                    raise ValueError(f"corruption stage kind must be one of {sorted(STAGES)}, got {kind!r}")
                known = [f.name for f in dataclasses.fields(STAGES[kind])]
                unknown = sorted(set(fields) - set(known))
                if unknown:
                    raise TypeError(f"corruption stage {kind!r} has no field(s) {unknown}; its fields: {known}")
                item = STAGES[kind](**fields)
            stages.append(item)
        return cls(tuple(stages))

    def to_list(self) -> list[dict]:
        """The stages as dicts (JSON-ready; :meth:`coerce` reads them back)."""
        return [s.to_dict() for s in self.stages]

    def apply(self, waveform: np.ndarray, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """The corrupted copy of ``waveform`` (float64); the input is not changed."""
        x = np.array(waveform, dtype=float)
        for stage in self.stages:
            x = stage.apply(x, sample_rate_hz, rng)
        return x
