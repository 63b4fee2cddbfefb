"""What a recording on the rig yields (:class:`RigRecording`), and the partial files that keep
it when a recording stops early."""

from __future__ import annotations

import contextlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sensors import AcousticObservation, Excitation
from sensors._infra.atomic import atomic_write_text

from .devices import AudioDevice
from .errors import StorageError

# PortAudio callback status flags (portaudio.h).
_FLAGS = {1: "input_underflow", 2: "input_overflow", 4: "output_underflow", 8: "output_overflow",
          16: "priming_output"}
_PROBLEM_FLAGS = 1 | 2 | 4 | 8


@dataclass
class RigRecording:
    """What the rig recorded: all input channels from the moment the input started.

    Attributes:
        input: float32 ``(n_samples, n_input_channels)``.
        mic_channel: column of the contact microphone.
        sample_rate_hz: sample rate in Hz.
        excitation: what the actuator played (looping from the output's first sample).
        duration_s: requested aligned length, seconds.
        latency_samples: samples from the start of ``input`` to the first complete
            excitation period (the measured round trip, plus the output's lead-in and the
            start offset of the streams), ``None`` if not found.
        period_lags_samples: the latency measured on every complete period.
        events: callback status flags, ``{"stream", "flag", "frame"}`` each.
        input_device, output_device: the devices.
        stream_mode: ``"separate"`` or ``"duplex"``.
        reported_latency_s: PortAudio's own input/output latency estimates.
        started_at: UTC ISO time of the start.
        complete: False if the recording stopped early.
        problems: human-readable xrun/sync problems.
        error: why it stopped early, if it did.
        lead_in_samples: what the output played before its first period boundary.
    """

    input: np.ndarray
    mic_channel: int
    sample_rate_hz: int
    excitation: Excitation
    duration_s: float
    latency_samples: int | None
    period_lags_samples: list[int]
    events: list[dict[str, Any]]
    input_device: AudioDevice
    output_device: AudioDevice
    stream_mode: str
    reported_latency_s: dict[str, float]
    started_at: str
    complete: bool = True
    problems: list[str] = field(default_factory=list)
    error: str | None = None
    lead_in_samples: int = 0
    _writer: Any = field(default=None, repr=False, compare=False)

    CLIP_LEVEL = 0.999

    def save(self, path: str | os.PathLike, *, trim: bool = True, labels: dict[str, Any] | None = None,
             extra_metadata: dict[str, Any] | None = None) -> Path:
        """Save :meth:`to_observation` atomically to ``path`` (.npz), then remove the partial
        files streamed while recording."""
        out = self.to_observation(trim=trim, labels=labels, extra_metadata=extra_metadata).save(path)
        self.discard_partial()
        return out

    def discard_partial(self) -> None:
        """Remove the partial files streamed while recording (once the final file is safe)."""
        if self._writer is not None:
            self._writer.discard()
            self._writer = None

    @property
    def mic(self) -> np.ndarray:
        """The microphone channel, float32."""
        return self.input[:, self.mic_channel]

    @property
    def clipped(self) -> bool:
        """True if the microphone reached full scale (an ADC clips there; a digital
        loopback of a full-scale excitation also does)."""
        return bool(self.mic.size) and float(np.max(np.abs(self.mic))) >= self.CLIP_LEVEL

    @property
    def latency_s(self) -> float | None:
        """``latency_samples`` in seconds."""
        return None if self.latency_samples is None else self.latency_samples / self.sample_rate_hz

    @property
    def drift_samples(self) -> int:
        """Spread of the per-period latencies (0 = sample-synchronized)."""
        lags = self.period_lags_samples
        return int(max(lags) - min(lags)) if lags else 0

    def flag_counts(self) -> dict[str, int]:
        """Number of callbacks with each status flag."""
        counts = {name: 0 for name in _FLAGS.values()}
        for ev in self.events:
            counts[ev["flag"]] += 1
        return counts

    def metadata(self, labels: dict[str, Any] | None = None) -> dict[str, Any]:
        """The recording's facts as plain JSON (stored with every observation)."""
        return {
            "source": "real",
            "complete": self.complete,
            "partial": not self.complete,
            "error": self.error,
            "excitation": self.excitation.name,
            "recorded_at": self.started_at,
            "duration_s": self.duration_s,
            "device": {"input": self.input_device.to_dict(), "output": self.output_device.to_dict(),
                       "mic_channel": self.mic_channel},
            "stream_mode": self.stream_mode,
            "latency_s": self.latency_s,
            "latency_samples": self.latency_samples,
            "reported_latency_s": self.reported_latency_s,
            "sync": {"period_lags_samples": list(map(int, self.period_lags_samples)),
                     "drift_samples": self.drift_samples},
            "xruns": {**self.flag_counts(), "events": self.events[:50]},
            "problems": list(self.problems),
            "peak_amplitude": float(np.max(np.abs(self.mic))) if self.mic.size else 0.0,
            "clipped": self.clipped,
            "lead_in_s": self.lead_in_samples / self.sample_rate_hz,
            "labels": dict(labels or {}),
        }

    def to_observation(self, *, trim: bool = True, labels: dict[str, Any] | None = None,
                       extra_metadata: dict[str, Any] | None = None) -> AcousticObservation:
        """The :class:`sensors.AcousticObservation`.

        ``trim=True``: exactly ``round(duration_s * sample_rate_hz)`` samples starting at the first
        excitation period, ``start_time_s = 0`` -- the simulated sensor's layout, so raw
        waveforms from both stack into one classifier input. ``trim=False``: everything
        recorded, ``start_time_s`` = the latency (feature windows start there).
        An incomplete recording or one without a latency is returned whole.
        """
        meta = self.metadata(labels)
        meta.update(extra_metadata or {})
        mic = self.mic
        n = int(round(self.duration_s * self.sample_rate_hz))
        L = self.latency_samples
        if L is not None and trim and mic.size >= L + n:
            wave, start_s = mic[L:L + n], 0.0
            meta["preroll_trimmed"] = True
        else:
            wave, start_s = mic, (L / self.sample_rate_hz if L is not None and L < mic.size else 0.0)
            meta["preroll_trimmed"] = False
        if wave.size == 0:
            raise ValueError("nothing was recorded")
        return AcousticObservation(waveform=np.array(wave, dtype=np.float32), sample_rate_hz=self.sample_rate_hz,
                                   excitation=self.excitation, start_time_s=start_s, metadata=meta)


def partial_paths(path: str | os.PathLike) -> tuple[Path, Path, Path]:
    """``(<name>.partial.f32, <name>.partial.json, <name>.partial.npz)`` for final ``path``."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix == ".npz" else path
    return (stem.with_name(stem.name + ".partial.f32"), stem.with_name(stem.name + ".partial.json"),
            stem.with_name(stem.name + ".partial.npz"))


class _PartialWriter:
    """Streams input samples to ``<name>.partial.f32`` as they arrive, described by
    ``<name>.partial.json`` (written first), so a crash loses at most the last ~0.5 s.

    A failing disk (full, file too large) never raises here: the writer keeps an exact
    prefix of the samples on disk (unbuffered writes, so a short write is counted), stops
    writing and keeps the first ``OSError`` in ``error`` for the recording loop to report;
    the samples themselves stay in the caller's memory.
    """

    FSYNC_INTERVAL_S = 0.5

    def __init__(self, final_path: Path, header: dict[str, Any]) -> None:
        self.raw_path, self.json_path, self.npz_path = partial_paths(final_path)
        self.frame_bytes = 4 * int(header["channels"])
        self.bytes_written = 0
        self.error: OSError | None = None
        self._fh = None
        self._last_sync = time.monotonic()
        try:
            self.raw_path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(self.json_path, json.dumps({**header, "partial": True, "final_path": str(final_path)}))
            self._fh = open(self.raw_path, "wb", buffering=0)
        except OSError as exc:
            self.error = exc

    @property
    def frames_written(self) -> int:
        """Whole frames on disk."""
        return self.bytes_written // self.frame_bytes

    @property
    def has_data(self) -> bool:
        """A header and at least one whole frame are on disk (what :func:`recover_partial` needs)."""
        return self.json_path.exists() and self.frames_written > 0

    def append(self, block: np.ndarray) -> None:
        if self.error is not None or self._fh is None:
            return
        data = memoryview(np.ascontiguousarray(block, dtype="<f4").tobytes())
        try:
            while data:
                n = self._fh.write(data)
                self.bytes_written += n
                data = data[n:]
            if time.monotonic() - self._last_sync > self.FSYNC_INTERVAL_S:
                os.fsync(self._fh.fileno())
                self._last_sync = time.monotonic()
        except OSError as exc:
            self.error = exc

    def close(self) -> None:
        if self._fh is not None and not self._fh.closed:
            try:
                os.fsync(self._fh.fileno())
            except OSError as exc:
                self.error = self.error or exc
            finally:
                self._fh.close()

    def discard(self) -> None:
        self.close()
        for p in (self.raw_path, self.json_path):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


def recover_partial(path: str | os.PathLike, out_dir: str | os.PathLike | None = None) -> Path | None:
    """Turn the raw ``<name>.partial.f32`` + ``.partial.json`` left by a killed process (or by
    a disk that filled up) into ``<name>.partial.npz`` (an ``AcousticObservation`` with
    ``metadata["partial"] = True``). ``path`` is the final recording path or either partial
    file. Returns the .npz, or None if there is nothing to recover.

    ``out_dir``: write the .npz there instead of beside the partial files (when their disk is
    full). The raw files are removed only once the .npz is safely written; if it cannot be,
    :class:`real.StorageError` says so and they stay.
    """
    p = Path(path)
    name = p.name
    for suffix in (".partial.f32", ".partial.json", ".partial.npz"):
        if name.endswith(suffix):
            p = p.with_name(name[: -len(suffix)])
    raw, js, npz = partial_paths(p)
    if out_dir is not None:
        npz = Path(out_dir) / npz.name
    if not (raw.exists() and js.exists()):
        return npz if npz.exists() else None
    header = json.loads(js.read_text())
    channels = int(header["channels"])
    buf = raw.read_bytes()  # whole frames only: a full disk may have cut the last one short
    data = np.frombuffer(buf[: len(buf) - len(buf) % (4 * channels)], dtype="<f4").reshape(-1, channels)
    if data.shape[0] == 0:
        raw.unlink()
        js.unlink()
        return None
    meta = dict(header.get("metadata", {}))
    meta.update({"partial": True, "complete": False,
                 "error": meta.get("error") or "recovered from the partial files (the recording process ended "
                                               "abruptly, or the disk filled up)"})
    obs = AcousticObservation(waveform=data[:, int(header["mic_channel"])], sample_rate_hz=int(header["sample_rate_hz"]),
                              excitation=Excitation.from_dict(header["excitation"]), start_time_s=0.0, metadata=meta)
    try:
        obs.save(npz)  # creates out_dir
    except OSError as exc:
        raise StorageError(f"cannot write {npz} ({exc.strerror or exc}); the partial files {raw.name} and {js.name} "
                           f"are kept: real.recover_partial({str(path)!r}, out_dir=<a folder on another disk>)",
                           cause=exc) from exc
    raw.unlink()
    js.unlink()
    return npz
