"""The acoustic observation that the simulated and the real sensor both produce."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .._infra.atomic import atomic_open
from .excitation import Excitation
from .._infra.npz import FileFormatError, read_npz
from .features import amplitude_spectrum, spectral_features, validate_waveform


_FLOAT32_MAX = float(np.finfo(np.float32).max)


def recorded_waveform(waveform, name: str = "waveform") -> np.ndarray:
    """A recording as the project stores it, float32 at full scale 1. Refused rather than
    silently changed: integer PCM (its scale is 32768x; convert with ``x / 32768``), values
    a float32 cannot hold (they would become inf), and everything ``spectral_features``
    refuses (NaN, empty, several channels)."""
    w = np.asarray(waveform)
    if w.dtype.kind in "iub":
        raise TypeError(f"{name} has integer dtype {w.dtype}: the project stores float samples at full scale 1 "
                        f"(convert 16-bit PCM with x / 32768)")
    validate_waveform(w, name)
    if w.size and float(np.max(np.abs(w))) > _FLOAT32_MAX:
        raise ValueError(f"{name} has values beyond float32's range ({float(np.max(np.abs(w))):.3g}): "
                         "they would be stored as inf")
    return w.astype(np.float32, copy=False)


def check_sample_rate_hz(value) -> int:
    """A sample rate as a positive whole number of Hz; 44100.7 or ``True`` are refused, not
    truncated."""
    if isinstance(value, (bool, np.bool_)) or not np.isscalar(value) or not np.isfinite(value) \
            or int(value) != value or value <= 0:
        raise ValueError(f"sample_rate_hz must be a positive whole number of Hz, got {value!r}")
    return int(value)


@dataclass
class AcousticObservation:
    """One recording of the contact microphone while the actuator plays an excitation.

    Attributes:
        waveform: microphone signal, float32, one channel (arbitrary units, full scale 1).
        sample_rate_hz: sample rate of ``waveform``.
        excitation: the excitation that was played.
        start_time_s: time in ``waveform`` at which the first excitation period starts
            (playback latency on the rig, 0 in simulation); feature windows start here.
        metadata: free-form JSON-serialisable facts (source "sim"/"real", device,
            latency, labels, ground truth, timestamp).
    """

    waveform: np.ndarray
    sample_rate_hz: int
    excitation: Excitation
    start_time_s: float = 0.0
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.waveform = recorded_waveform(self.waveform)
        self.sample_rate_hz = check_sample_rate_hz(self.sample_rate_hz)
        if not isinstance(self.excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation, got {type(self.excitation).__name__}")
        if self.excitation.sample_rate_hz != self.sample_rate_hz:
            raise ValueError(
                f"sample_rate_hz={self.sample_rate_hz} Hz differs from the excitation's sample_rate_hz={self.excitation.sample_rate_hz} Hz"
            )
        if not np.isfinite(self.start_time_s) or self.start_time_s < 0:
            raise ValueError(f"start_time_s must be >= 0, got {self.start_time_s!r}")

    @property
    def duration_s(self) -> float:
        """Length of the recording in seconds."""
        return self.waveform.size / self.sample_rate_hz

    def features(self, *, average: bool = True, **kwargs: Any) -> np.ndarray:
        """The 140-d spectral feature vector (see :func:`sensors.spectral_features`).

        Windows are one excitation period long and start at ``start_time_s``.
        """
        return spectral_features(
            self.waveform, self.sample_rate_hz, period_s=self.excitation.period_s,
            start_s=self.start_time_s, average=average, **kwargs,
        )

    def spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """Full-resolution amplitude spectrum averaged over windows: ``(frequencies_hz, amplitude)``."""
        return amplitude_spectrum(
            self.waveform, self.sample_rate_hz, period_s=self.excitation.period_s, start_s=self.start_time_s
        )

    # -- persistence ----------------------------------------------------------------------

    def save(self, path: str | os.PathLike) -> Path:
        """Write an ``.npz`` atomically: a crash never leaves a half-written file that looks whole."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        meta = json.dumps({
            "sample_rate_hz": self.sample_rate_hz,
            "excitation": self.excitation.to_dict(),
            "start_time_s": self.start_time_s,
            "metadata": self.metadata,
        })
        with atomic_open(path) as fh:
            np.savez(fh, waveform=self.waveform, meta=np.array(meta))
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> AcousticObservation:
        """Read a file written by :meth:`save` (``FileFormatError`` naming the file otherwise)."""
        data = read_npz(path, {"meta", "waveform"}, "an aas-gym acoustic observation")
        try:
            meta = json.loads(str(data["meta"]))
        except ValueError as exc:
            raise FileFormatError(f"{path}: not an aas-gym acoustic observation (bad metadata: {exc})") from None
        waveform = data["waveform"]
        return cls(
            waveform=waveform,
            sample_rate_hz=meta["sample_rate_hz"],
            excitation=Excitation.from_dict(meta["excitation"]),
            start_time_s=meta["start_time_s"],
            metadata=meta["metadata"],
        )


@runtime_checkable
class AcousticSensor(Protocol):
    """What the simulated and the real sensor both implement."""

    def sense(self, excitation: Excitation, duration_s: float) -> AcousticObservation:
        """Play ``excitation`` (looping) for ``duration_s`` seconds and return the recording."""
        ...
