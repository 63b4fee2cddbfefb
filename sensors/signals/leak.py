"""Actuator-to-microphone leak through the gripper body.

On the rig the exciter's vibration also reaches the piezo through the hand itself.  It is
recorded once per excitation with the gripper idle (nothing grasped) and stored as an .npz
file with:

- ``waveform``: float32 (n,), the microphone recording (full scale 1, same units as the
  observation waveform);
- ``sample_rate_hz``: int;
- ``excitation``: the excitation's ``to_dict()`` as a JSON string;
- ``metadata``: JSON string (device, latency, date, ...; optional).

``real`` writes this format with :func:`save_leak`; the simulator reads it with
:func:`load_leak` and adds :func:`align_leak` 's output to the synthesized signal, shifted so
that the excitation peak (the maximum of the cross-correlation with one excitation period)
falls at the same sample in both signals.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._infra.atomic import atomic_open
from .._infra.npz import FileFormatError, read_npz
from .observation import check_sample_rate_hz, recorded_waveform

__all__ = ["LeakRecording", "save_leak", "load_leak", "excitation_lag", "align_leak", "aligned_leak_cycle"]


@dataclass
class LeakRecording:
    """A leak recording: waveform (float32), sample rate, excitation dict, metadata."""

    waveform: np.ndarray
    sample_rate_hz: int
    excitation: dict
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.waveform = recorded_waveform(self.waveform, "leak waveform")
        self.sample_rate_hz = check_sample_rate_hz(self.sample_rate_hz)
        if hasattr(self.excitation, "to_dict"):
            self.excitation = self.excitation.to_dict()
        self.excitation = dict(self.excitation)

    def matches(self, excitation) -> bool:
        """True if recorded with this excitation (same description)."""
        d = excitation.to_dict() if hasattr(excitation, "to_dict") else dict(excitation)
        return json.loads(json.dumps(d)) == json.loads(json.dumps(self.excitation))


def save_leak(path: str | os.PathLike, waveform, sample_rate_hz: int, excitation,
              metadata: dict | None = None) -> Path:
    """Write a leak recording (``excitation``: a ``sensors.Excitation`` or its dict)."""
    rec = LeakRecording(waveform, sample_rate_hz, excitation, dict(metadata or {}))
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_suffix(".npz")
    with atomic_open(path) as fh:
        np.savez(fh, waveform=rec.waveform, sample_rate_hz=np.int64(rec.sample_rate_hz),
                 excitation=np.array(json.dumps(rec.excitation)), metadata=np.array(json.dumps(rec.metadata)))
    return path


def load_leak(path: str | os.PathLike) -> LeakRecording:
    """Read a leak recording written by :func:`save_leak`; ``FileFormatError`` (a
    ``ValueError``) naming the file for anything that is not one."""
    z = read_npz(path, {"waveform", "sample_rate_hz", "excitation"}, "a leak recording")
    meta = json.loads(str(z["metadata"])) if "metadata" in z else {}
    try:
        return LeakRecording(z["waveform"], z["sample_rate_hz"][()], json.loads(str(z["excitation"])), meta)
    except (TypeError, ValueError) as exc:
        raise FileFormatError(f"{path}: not a valid leak recording ({exc})") from None


def leak_file_identity(path: str | os.PathLike) -> dict[str, str]:
    """What observations record about the leak file they used: its name and the SHA-256 of
    its bytes, never its absolute path (datasets must not carry the user's directory layout)."""
    path = Path(path)
    return {"name": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}


def excitation_lag(signal, excitation_period, max_lag: int | None = None) -> int:
    """Sample at which the excitation sits in ``signal``: argmax over lags 0..max_lag of
    |cross-correlation| with one excitation period (polarity does not matter)."""
    x = np.asarray(signal, dtype=float)
    e = np.asarray(excitation_period, dtype=float)
    if max_lag is None:
        max_lag = len(e) - 1
    max_lag = int(min(max_lag, len(x) - 1))
    if not np.any(e) or not np.any(x):
        return 0
    # c[k] = sum_n x[n + k] e[n]
    import scipy.signal as ssig  # ~0.5 s to import (-X importtime): first use only

    c = ssig.fftconvolve(x, e[::-1])[len(e) - 1: len(e) + max_lag]
    return int(np.argmax(np.abs(c)))


def aligned_leak_cycle(leak: LeakRecording, excitation, target_lag: int = 0) -> np.ndarray:
    """One cycle of the leak as a recording that starts at loop phase 0 hears it, shifted so
    its excitation peak falls at ``target_lag``: the recorded span of whole excitation
    periods, which such a recording repeats (sample k of it is ``cycle[k % len(cycle)]``).

    The leak was recorded under the looping excitation, so it is periodic with the
    excitation period; the cycle uses as many whole periods as the recording holds.
    """
    if leak.sample_rate_hz != excitation.sample_rate_hz:
        raise ValueError(f"leak recorded at {leak.sample_rate_hz} Hz, excitation at {excitation.sample_rate_hz} Hz")
    if not leak.matches(excitation):
        raise ValueError(f"leak was recorded for {leak.excitation.get('kind')!r}, not for this excitation "
                         f"{excitation.to_dict().get('kind')!r} (settings differ)")
    P = excitation.period_samples
    w = leak.waveform.astype(float)
    if len(w) < P:
        raise ValueError(f"leak recording ({len(w)} samples) is shorter than one excitation period ({P})")
    lag = excitation_lag(w, excitation.signal, max_lag=min(P - 1, len(w) - P))
    start = lag - int(target_lag)
    # periodic extension inside the recorded span [lo, hi) of whole periods
    lo = lag % P
    span = ((len(w) - lo) // P) * P
    return w[lo + np.mod(start + np.arange(span) - lo, span)]


def align_leak(leak: LeakRecording, excitation, n_samples: int, target_lag: int = 0) -> np.ndarray:
    """The leak shifted so its excitation peak falls at ``target_lag``, ``n_samples`` long
    (:func:`aligned_leak_cycle`, repeated where the recording does not cover the output)."""
    cycle = aligned_leak_cycle(leak, excitation, target_lag)
    return cycle[np.arange(int(n_samples)) % len(cycle)]
