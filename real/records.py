"""The rig's plain records: :class:`AudioDevice` (a device as PortAudio lists it) and
:class:`RigRecording` (what a recording on the rig yields), with the table of PortAudio's
callback status flags they are described by.

Data only: this module imports nothing else of ``real``, so every other module can use it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sensors import AcousticObservation, Excitation

#: PortAudio callback status flags (portaudio.h): bit -> name.
CALLBACK_FLAGS = {1: "input_underflow", 2: "input_overflow", 4: "output_underflow", 8: "output_overflow",
                  16: "priming_output"}
#: The flags that mean lost or missing samples (priming the output is none).
PROBLEM_FLAGS = 1 | 2 | 4 | 8


@dataclass(frozen=True)
class AudioDevice:
    """A PortAudio device as listed by :func:`real.list_devices`."""

    index: int
    name: str
    host_api: str
    max_input_channels: int
    max_output_channels: int
    default_sample_rate_hz: float
    is_default_input: bool = False
    is_default_output: bool = False

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON description (stored in recording metadata)."""
        return dict(self.__dict__)

    def __str__(self) -> str:
        return f"{self.name!r} (index {self.index}, {self.host_api})"


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
        partial_files: the partial files streamed while recording (anything with a
            ``discard()``, :class:`real.partial_files.PartialWriter`), removed by
            :meth:`save` and :meth:`discard_partial`; ``None`` if there are none.
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
    partial_files: Any = field(default=None, repr=False, compare=False)

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
        if self.partial_files is not None:
            self.partial_files.discard()
            self.partial_files = None

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
        counts = {name: 0 for name in CALLBACK_FLAGS.values()}
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
