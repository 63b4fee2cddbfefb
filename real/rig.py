"""The physical rig through PyAudio: play a looping excitation on the actuator channel while
recording the contact microphone.

Synchronization. Two modes, both checked on every recording:

- ``stream_mode="separate"`` (default): one input and one output stream of the same device
  clock, the input started first. Their relative start is arbitrary, so the round-trip
  latency is measured on every recording by cross-correlation with the excitation; the
  spacing of the excitation's periods in the recording proves that no sample was dropped or
  inserted (``sync.drift_samples``).
- ``stream_mode="duplex"``: one full-duplex PortAudio stream with one callback. Measured on
  this project's machine through ALSA's PulseAudio plugin, PortAudio's full-duplex path
  inserts one or two samples about every 1025 (0.15 % drift, no status flag raised), so it
  is not the default there; on a sound card's own ALSA device it is the classic choice.

Errors name the device. Input overflows and output underruns (PortAudio callback status
flags) and a lost synchronization are reported in the metadata and, by ``xrun_policy``,
raised (:class:`XrunError`), warned (:class:`RigWarning`) or ignored. A recording that stops
early (device gone, Ctrl-C, error) keeps what was recorded: the exception carries it as
``.recording``, and with a ``save_path`` the samples were streamed to ``<name>.partial.f32``
(+ ``.partial.json``) while recording and end up in ``<name>.partial.npz``.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import tempfile
import threading
import time
import warnings
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sensors import AcousticObservation, Excitation
from sensors.atomic import atomic_write_text

from .latency import find_latency, period_lags

try:  # PyAudio is the optional extra [real]; the error says how to get it.
    import pyaudio
except ImportError:  # pragma: no cover - depends on the installation
    pyaudio = None

# PortAudio callback status flags (portaudio.h).
_FLAGS = {1: "input_underflow", 2: "input_overflow", 4: "output_underflow", 8: "output_overflow",
          16: "priming_output"}
_PROBLEM_FLAGS = 1 | 2 | 4 | 8


class RigError(RuntimeError):
    """An audio-rig failure. ``device`` names the device involved; ``recording`` holds what
    was recorded before the failure (a :class:`RigRecording` with ``complete=False``) and
    ``partial_path`` the file it was saved to, if any."""

    def __init__(self, message: str, *, device: str | None = None, recording: RigRecording | None = None,
                 partial_path: Path | None = None) -> None:
        super().__init__(message)
        self.device = device
        self.recording = recording
        self.partial_path = partial_path


class NoAudioDeviceError(RigError):
    """PortAudio finds no device (or no default device of the needed kind)."""


class DeviceNotFoundError(RigError):
    """No device matches the requested name or index."""


class UnsupportedSampleRateError(RigError):
    """The device refuses the sample rate."""


class DeviceLostError(RigError):
    """The device stopped delivering audio during a recording (unplugged, server gone)."""


class ExcitationNotFoundError(RigError):
    """The excitation does not come back in the microphone recording."""


class XrunError(RigError):
    """Overflow/underrun flags or lost sample synchronization (``xrun_policy="raise"``)."""


class RigWarning(UserWarning):
    """Overflow/underrun or lost synchronization under ``xrun_policy="warn"``."""


def _require_pyaudio():
    if pyaudio is None:
        raise NoAudioDeviceError("PyAudio is not installed: pip install 'aas-gym[real]' "
                                 "(building it needs Debian's portaudio19-dev)")
    return pyaudio


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Collect what C libraries (ALSA, JACK) print on fd 2 instead of flooding the terminal;
    the lines are kept for error messages."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no fd 2 (embedded interpreter): nothing to capture
        yield lines
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(tmp.read().decode(errors="replace").splitlines())


_NOISE = ("ALSA lib", "Expression '", "jack", "Jack", "Cannot connect to server", "JackShm")


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Like :func:`_captured_stderr`, then writes back what is not PortAudio/ALSA noise."""
    with _captured_stderr() as lines:
        yield
    keep = [ln for ln in lines if not any(n in ln for n in _NOISE)]
    if keep:
        os.write(2, ("\n".join(keep) + "\n").encode())


def _alsa_hint(lines: list[str], n: int = 3) -> str:
    useful = [ln for ln in lines if ln.strip() and "jack" not in ln.lower()]
    return (" [" + " | ".join(useful[-n:]) + "]") if useful else ""


@contextlib.contextmanager
def _portaudio() -> Iterator[Any]:
    """A fresh PortAudio session (device lists are read at initialization, so a new
    session sees devices that appeared or vanished since the last one)."""
    pa_mod = _require_pyaudio()
    with _captured_stderr():
        pa = pa_mod.PyAudio()
    try:
        yield pa
    finally:
        with _captured_stderr():
            pa.terminate()


@dataclass(frozen=True)
class AudioDevice:
    """A PortAudio device as listed by :func:`list_devices`."""

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


def _devices(pa) -> list[AudioDevice]:
    try:
        din = pa.get_default_input_device_info()["index"]
    except OSError:
        din = -1
    try:
        dout = pa.get_default_output_device_info()["index"]
    except OSError:
        dout = -1
    out = []
    for i in range(pa.get_device_count()):
        info = pa.get_device_info_by_index(i)
        out.append(AudioDevice(
            index=i, name=info["name"], host_api=pa.get_host_api_info_by_index(info["hostApi"])["name"],
            max_input_channels=int(info["maxInputChannels"]), max_output_channels=int(info["maxOutputChannels"]),
            default_sample_rate_hz=float(info["defaultSampleRate"]),
            is_default_input=i == din, is_default_output=i == dout))
    return out


def list_devices() -> list[AudioDevice]:
    """The audio devices PortAudio sees now (empty if there are none)."""
    with _portaudio() as pa:
        return _devices(pa)


def _describe(devices: list[AudioDevice], kind: str) -> str:
    key = "max_input_channels" if kind == "input" else "max_output_channels"
    usable = [str(d) for d in devices if getattr(d, key) > 0]
    return ", ".join(usable) if usable else "none"


def resolve_device(pa, spec: int | str | None, kind: str, channels: int) -> AudioDevice:
    """The device for ``spec`` (``None`` = system default, an index, or a case-insensitive
    name or name substring; an exact name wins over substrings) with ``channels`` ``kind``
    (``"input"``/``"output"``) channels."""
    devices = _devices(pa)
    key = "max_input_channels" if kind == "input" else "max_output_channels"
    if not devices:
        raise NoAudioDeviceError(
            f"no audio device: PortAudio finds none for the {kind} "
            f"({'system default' if spec is None else repr(spec)}). Is a sound card connected, or a sound "
            "server running? (without hardware: python -m real.loopback start)",
            device="default" if spec is None else str(spec))
    if spec is None:
        chosen = [d for d in devices if (d.is_default_input if kind == "input" else d.is_default_output)]
        if not chosen:
            raise NoAudioDeviceError(f"no default {kind} device; {kind} devices: {_describe(devices, kind)}",
                                     device="default")
        dev = chosen[0]
    elif isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        if not 0 <= int(spec) < len(devices):
            raise DeviceNotFoundError(f"no {kind} device with index {spec}; {kind} devices: "
                                      f"{_describe(devices, kind)}", device=f"index {spec}")
        dev = devices[int(spec)]
    elif isinstance(spec, str):
        exact = [d for d in devices if d.name.lower() == spec.lower() and getattr(d, key) > 0]
        partial = [d for d in devices if spec.lower() in d.name.lower() and getattr(d, key) > 0]
        if exact:
            dev = exact[0]
        elif len(partial) == 1:
            dev = partial[0]
        elif partial:
            raise DeviceNotFoundError(f"{kind} device name {spec!r} is ambiguous: {', '.join(map(str, partial))}",
                                      device=spec)
        else:
            raise DeviceNotFoundError(f"no {kind} device named like {spec!r}; {kind} devices: "
                                      f"{_describe(devices, kind)}", device=spec)
    else:
        raise TypeError(f"{kind}_device must be None, an index or a name, got {type(spec).__name__}")
    if getattr(dev, key) < channels:
        raise DeviceNotFoundError(f"{kind} device {dev} has {getattr(dev, key)} {kind} channels, "
                                  f"{channels} needed", device=dev.name)
    return dev


def check_sample_rate(pa, device: AudioDevice, kind: str, sample_rate_hz: int, channels: int) -> None:
    """Raise :class:`UnsupportedSampleRateError` naming ``device`` if it refuses ``sample_rate_hz``."""
    kw = ({"input_device": device.index, "input_channels": channels, "input_format": pyaudio.paFloat32}
          if kind == "input" else
          {"output_device": device.index, "output_channels": channels, "output_format": pyaudio.paFloat32})
    try:
        with _captured_stderr() as lines:
            pa.is_format_supported(float(sample_rate_hz), **kw)
    except ValueError as exc:
        raise UnsupportedSampleRateError(
            f"{kind} device {device} does not support a sample rate of {sample_rate_hz} Hz ({exc.args[0] if exc.args else exc}); "
            f"its default rate is {device.default_sample_rate_hz:g} Hz{_alsa_hint(lines)}", device=device.name) from None


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
    ``<name>.partial.json`` (written first), so a crash loses at most the last ~0.5 s."""

    FSYNC_INTERVAL_S = 0.5

    def __init__(self, final_path: Path, header: dict[str, Any]) -> None:
        self.raw_path, self.json_path, self.npz_path = partial_paths(final_path)
        self.raw_path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.json_path, json.dumps({**header, "partial": True, "final_path": str(final_path)}))
        self._fh = open(self.raw_path, "wb")
        self._last_sync = time.monotonic()

    def append(self, block: np.ndarray) -> None:
        self._fh.write(np.ascontiguousarray(block, dtype="<f4").tobytes())
        self._fh.flush()
        if time.monotonic() - self._last_sync > self.FSYNC_INTERVAL_S:
            os.fsync(self._fh.fileno())
            self._last_sync = time.monotonic()

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()

    def discard(self) -> None:
        self.close()
        for p in (self.raw_path, self.json_path):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


def recover_partial(path: str | os.PathLike) -> Path | None:
    """Turn the raw ``<name>.partial.f32`` + ``.partial.json`` left by a killed process into
    ``<name>.partial.npz`` (an ``AcousticObservation`` with ``metadata["partial"] = True``).
    ``path`` is the final recording path or either partial file. Returns the .npz, or None
    if there is nothing to recover."""
    p = Path(path)
    name = p.name
    for suffix in (".partial.f32", ".partial.json", ".partial.npz"):
        if name.endswith(suffix):
            p = p.with_name(name[: -len(suffix)])
    raw, js, npz = partial_paths(p)
    if not (raw.exists() and js.exists()):
        return npz if npz.exists() else None
    header = json.loads(js.read_text())
    channels = int(header["channels"])
    data = np.fromfile(raw, dtype="<f4")
    data = data[: data.size - data.size % channels].reshape(-1, channels)
    if data.shape[0] == 0:
        raw.unlink()
        js.unlink()
        return None
    meta = dict(header.get("metadata", {}))
    meta.update({"partial": True, "complete": False,
                 "error": meta.get("error") or "recovered after the recording process ended abruptly"})
    obs = AcousticObservation(waveform=data[:, int(header["mic_channel"])], sample_rate_hz=int(header["sample_rate_hz"]),
                              excitation=Excitation.from_dict(header["excitation"]), start_time_s=0.0, metadata=meta)
    obs.save(npz)
    raw.unlink()
    js.unlink()
    return npz


class PyAudioRig:
    """The actuator output and contact-microphone input of the rig.

    Args:
        input_device, output_device: ``None`` (system default), a PortAudio index, or a
            (case-insensitive) name or name substring, see :func:`list_devices`.
        sample_rate_hz: sample rate in Hz (the paper's 44.1 kHz).
        actuator_channel: output channel of the actuator (others play silence).
        mic_channel: input channel of the contact microphone.
        output_channels, input_channels: channels to open (default: just enough).
        frames_per_buffer: PortAudio buffer, frames.
        stream_mode: ``"separate"`` (default) or ``"duplex"``, see the module notes.
        output_gain: scale of the excitation on the output (full scale 1).
        max_latency_s: give up when the excitation has not come back after this long.
        start_timeout_s: time the input may take to deliver its first samples.
        stall_timeout_s: the input delivering nothing for this long means the device is gone.
        xrun_policy: ``"raise"`` (:class:`XrunError`), ``"warn"`` (:class:`RigWarning`) or
            ``"ignore"`` for status flags and lost synchronization.
        sync_tolerance_samples: allowed spread of the per-period latency.
        lead_in_s: the output starts this long (at most one period) before a period
            boundary, playing the end of the loop: devices that lose their first output
            buffer lose part of the lead-in, and a real object is already vibrating in its
            steady state when the first aligned period starts.

    Raises at construction if PortAudio finds no device, the named device does not exist, or
    it refuses ``sample_rate_hz``; every error names the device.
    """

    def __init__(self, input_device: int | str | None = None, output_device: int | str | None = None,
                 sample_rate_hz: int = 44100, *, actuator_channel: int = 0, mic_channel: int = 0,
                 output_channels: int | None = None, input_channels: int | None = None,
                 frames_per_buffer: int = 1024, stream_mode: str = "separate", output_gain: float = 1.0,
                 max_latency_s: float = 2.0, start_timeout_s: float = 5.0, stall_timeout_s: float = 1.0,
                 xrun_policy: str = "raise", sync_tolerance_samples: int = 0, lead_in_s: float = 0.1) -> None:
        if stream_mode not in ("separate", "duplex"):
            raise ValueError(f"stream_mode must be 'separate' or 'duplex', got {stream_mode!r}")
        if xrun_policy not in ("raise", "warn", "ignore"):
            raise ValueError(f"xrun_policy must be 'raise', 'warn' or 'ignore', got {xrun_policy!r}")
        if isinstance(sample_rate_hz, bool) or int(sample_rate_hz) != sample_rate_hz or sample_rate_hz <= 0:
            raise ValueError(f"sample_rate_hz must be a positive integer sample rate in Hz, got {sample_rate_hz!r}")
        if not (math.isfinite(output_gain) and 0 < output_gain <= 1):
            raise ValueError(f"output_gain must be in (0, 1], got {output_gain!r}")
        for name, v in (("actuator_channel", actuator_channel), ("mic_channel", mic_channel)):
            if int(v) != v or v < 0:
                raise ValueError(f"{name} must be a channel index >= 0, got {v!r}")
        self.input_spec, self.output_spec = input_device, output_device
        self.sample_rate_hz = int(sample_rate_hz)
        self.actuator_channel, self.mic_channel = int(actuator_channel), int(mic_channel)
        self.output_channels = int(output_channels or self.actuator_channel + 1)
        self.input_channels = int(input_channels or self.mic_channel + 1)
        if self.actuator_channel >= self.output_channels or self.mic_channel >= self.input_channels:
            raise ValueError("actuator_channel/mic_channel must be below output_channels/input_channels")
        if stream_mode == "duplex":  # PyAudio opens both directions with one channel count
            self.input_channels = self.output_channels = max(self.input_channels, self.output_channels)
        self.frames_per_buffer = int(frames_per_buffer)
        self.stream_mode = stream_mode
        self.output_gain = float(output_gain)
        self.max_latency_s, self.start_timeout_s = float(max_latency_s), float(start_timeout_s)
        self.stall_timeout_s = float(stall_timeout_s)
        self.xrun_policy = xrun_policy
        self.sync_tolerance_samples = int(sync_tolerance_samples)
        if not (math.isfinite(lead_in_s) and lead_in_s >= 0):
            raise ValueError(f"lead_in_s must be >= 0, got {lead_in_s!r}")
        self.lead_in_s = float(lead_in_s)
        self.last_recording: RigRecording | None = None
        with _portaudio() as pa:
            self.input_device, self.output_device = self._resolve(pa)

    def _resolve(self, pa) -> tuple[AudioDevice, AudioDevice]:
        din = resolve_device(pa, self.input_spec, "input", self.input_channels)
        dout = resolve_device(pa, self.output_spec, "output", self.output_channels)
        check_sample_rate(pa, din, "input", self.sample_rate_hz, self.input_channels)
        check_sample_rate(pa, dout, "output", self.sample_rate_hz, self.output_channels)
        return din, dout

    def __repr__(self) -> str:
        return (f"PyAudioRig(input={self.input_device}, output={self.output_device}, sample_rate_hz={self.sample_rate_hz}, "
                f"mode={self.stream_mode})")

    # -- recording ------------------------------------------------------------------------

    def record(self, excitation: Excitation, duration_s: float, *, save_path: str | os.PathLike | None = None,
               labels: dict[str, Any] | None = None, on_progress=None) -> RigRecording:
        """Play ``excitation`` looping and record until ``duration_s`` seconds of microphone
        signal after the first excitation period are in.

        With ``save_path`` the input streams to a clearly named partial file while recording;
        on success it stays until the caller saves the final file with
        :meth:`RigRecording.save` (or drops it with :meth:`RigRecording.discard_partial`); on
        failure it becomes ``<name>.partial.npz``. ``on_progress(frames_recorded)`` is called from
        this thread about every 20 ms while recording.

        Raises:
            NoAudioDeviceError, DeviceNotFoundError, UnsupportedSampleRateError: before recording.
            DeviceLostError, ExcitationNotFoundError, XrunError, KeyboardInterrupt: during;
                :class:`RigError` s carry the samples recorded so far as ``.recording``.
        """
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
        if excitation.sample_rate_hz != self.sample_rate_hz:
            raise ValueError(f"excitation sampled at {excitation.sample_rate_hz} Hz, rig runs at {self.sample_rate_hz} Hz")
        duration_s = float(duration_s)
        if not (math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration_s must be > 0, got {duration_s!r}")
        with _portaudio() as pa:
            din, dout = self._resolve(pa)
            self.input_device, self.output_device = din, dout
            session = _Session(self, pa, din, dout, excitation, duration_s, save_path, labels, on_progress)
            # PortAudio's threads print ALSA/PulseAudio diagnostics on fd 2 while streaming
            # (many when a device vanishes): keep them out of the terminal, pass on the rest.
            with _quiet_stderr():
                return session.run()


class _Session:
    """One recording: streams, callbacks, the watch loop and the post-checks."""

    POLL_S = 0.02
    DETECT_EVERY_S = 0.1

    def __init__(self, rig: PyAudioRig, pa, din: AudioDevice, dout: AudioDevice, excitation: Excitation,
                 duration_s: float, save_path, labels, on_progress=None) -> None:
        self.rig, self.pa, self.din, self.dout = rig, pa, din, dout
        self.on_progress = on_progress
        self.excitation, self.duration_s = excitation, duration_s
        self.labels = labels
        self.n_target = int(round(duration_s * rig.sample_rate_hz))
        # One period, actuator channel only, interleaved; tiled so any callback's block is a
        # contiguous slice.
        P = excitation.period_samples
        frame = np.zeros((P, rig.output_channels), dtype=np.float32)
        frame[:, rig.actuator_channel] = rig.output_gain * excitation.signal
        reps = 2 + (rig.frames_per_buffer + P - 1) // P
        self.out_tiled = np.tile(frame, (reps, 1))
        self.P = P
        self.lead_in = min(int(round(rig.lead_in_s * rig.sample_rate_hz)), P)
        self.out_pos = (-self.lead_in) % P
        self.in_chunks: deque[bytes] = deque()
        self.in_frames = 0
        self.events: list[dict[str, Any]] = []
        self.last_in_t = None
        self.first_in = threading.Event()
        self.streams: list[Any] = []
        self.stopping = False
        self.started_at = _dt.datetime.now(_dt.timezone.utc).isoformat()
        self.writer = None
        if save_path is not None:
            self.writer = _PartialWriter(Path(save_path), {
                "channels": rig.input_channels, "mic_channel": rig.mic_channel, "sample_rate_hz": rig.sample_rate_hz,
                "dtype": "float32le interleaved", "excitation": excitation.to_dict(),
                "metadata": {"source": "real", "device": {"input": din.to_dict(), "output": dout.to_dict()},
                             "recorded_at": self.started_at, "labels": dict(labels or {}),
                             "excitation": excitation.name}})

    # PortAudio threads ------------------------------------------------------------------

    def _note_flags(self, stream: str, status: int, frame: int) -> None:
        if status & _PROBLEM_FLAGS or status & 16:
            for bit, name in _FLAGS.items():
                if status & bit:
                    self.events.append({"stream": stream, "flag": name, "frame": int(frame)})

    def _out_block(self, n: int) -> bytes:
        start = self.out_pos % self.P
        if start + n <= self.out_tiled.shape[0]:
            block = self.out_tiled[start:start + n]
        else:
            block = self.out_tiled[(start + np.arange(n)) % self.P]
        self.out_pos += n
        return block.tobytes()

    def _in_cb(self, in_data, frame_count, time_info, status):
        self.in_chunks.append(in_data)
        if status:
            self._note_flags("input", status, self.in_frames)
        self.in_frames += frame_count
        self.last_in_t = time.monotonic()
        self.first_in.set()
        return (None, pyaudio.paContinue)

    def _out_cb(self, in_data, frame_count, time_info, status):
        if status:
            self._note_flags("output", status, self.out_pos)
        return (self._out_block(frame_count), pyaudio.paContinue)

    def _duplex_cb(self, in_data, frame_count, time_info, status):
        self._in_cb(in_data, frame_count, time_info, 0)
        if status:
            self._note_flags("duplex", status, self.out_pos)
        return (self._out_block(frame_count), pyaudio.paContinue)

    # main thread ------------------------------------------------------------------------

    def _open(self, **kw):
        rig = self.rig
        dev = self.din if kw.get("input") else self.dout
        try:
            with _captured_stderr() as lines:
                return self.pa.open(rate=rig.sample_rate_hz, format=pyaudio.paFloat32, frames_per_buffer=rig.frames_per_buffer,
                                    start=False, **kw)
        except (OSError, ValueError) as exc:
            err = exc.args[1] if isinstance(exc, OSError) and len(exc.args) > 1 else exc
            which = "duplex" if kw.get("input") and kw.get("output") else ("input" if kw.get("input") else "output")
            cls = UnsupportedSampleRateError if "sample rate" in str(err).lower() else RigError
            raise cls(f"cannot open the {which} stream on device {dev} at {rig.sample_rate_hz} Hz: {err}{_alsa_hint(lines)}",
                      device=dev.name) from None

    def _start(self) -> None:
        rig = self.rig
        if rig.stream_mode == "duplex":
            s = self._open(channels=rig.input_channels, input=True, output=True,
                           input_device_index=self.din.index, output_device_index=self.dout.index,
                           stream_callback=self._duplex_cb)
            self.streams.append(("duplex", s))
            s.start_stream()
            self._wait_first_input()
            return
        sin = self._open(channels=rig.input_channels, input=True, input_device_index=self.din.index,
                         stream_callback=self._in_cb)
        self.streams.append(("input", sin))
        sout = self._open(channels=rig.output_channels, output=True, output_device_index=self.dout.index,
                          stream_callback=self._out_cb)
        self.streams.append(("output", sout))
        sin.start_stream()
        # The output starts once the input runs, so the first period is always recorded.
        self._wait_first_input()
        sout.start_stream()

    def _wait_first_input(self) -> None:
        deadline = time.monotonic() + self.rig.start_timeout_s
        while not self.first_in.wait(self.POLL_S):
            self._check_alive()
            if time.monotonic() > deadline:
                raise DeviceLostError(f"input device {self.din} delivered no audio within "
                                      f"{self.rig.start_timeout_s} s of starting", device=self.din.name)

    def _check_alive(self) -> None:
        for kind, s in self.streams:
            try:
                active = s.is_active()
            except OSError:
                active = False
            if not active and not self.stopping and (kind != "output" or self.first_in.is_set()):
                dev = self.dout if kind == "output" else self.din
                raise DeviceLostError(f"{kind} stream on device {dev} stopped during the recording "
                                      "(device disconnected or sound server gone)", device=dev.name)
        if self.last_in_t is not None and time.monotonic() - self.last_in_t > self.rig.stall_timeout_s:
            raise DeviceLostError(f"input device {self.din} delivered nothing for {self.rig.stall_timeout_s} s "
                                  "during the recording (device disconnected or sound server gone)",
                                  device=self.din.name)

    def _drain(self, parts: list[np.ndarray]) -> int:
        got = 0
        ch = self.rig.input_channels
        while self.in_chunks:
            block = np.frombuffer(self.in_chunks.popleft(), dtype=np.float32).reshape(-1, ch)
            parts.append(block)
            if self.writer is not None:
                self.writer.append(block)
            got += block.shape[0]
        return got

    def _stop(self) -> None:
        """Stop and close the streams; a stream of a vanished device may block in PortAudio,
        so this runs in a helper thread that is given up on after a few seconds."""
        self.stopping = True

        def close_all():
            with _captured_stderr():
                for _, s in self.streams:
                    with contextlib.suppress(Exception):
                        s.stop_stream()
                    with contextlib.suppress(Exception):
                        s.close()

        t = threading.Thread(target=close_all, name="aas-rig-close", daemon=True)
        t.start()
        t.join(5.0)

    def run(self) -> RigRecording:
        rig = self.rig
        parts: list[np.ndarray] = []
        total = 0
        latency = None
        target = None
        next_detect = 0.0
        give_up = int((rig.max_latency_s + 2 * self.excitation.period_s) * rig.sample_rate_hz) + self.n_target
        reported = {}
        try:
            self._start()
            for kind, s in self.streams:
                with contextlib.suppress(Exception):
                    if kind in ("input", "duplex"):
                        reported["input"] = float(s.get_input_latency())
                    if kind in ("output", "duplex"):
                        reported["output"] = float(s.get_output_latency())
            while True:
                time.sleep(self.POLL_S)
                total += self._drain(parts)
                if self.on_progress is not None:
                    self.on_progress(total)
                self._check_alive()
                now = time.monotonic()
                if target is None and total >= self.P and now >= next_detect:
                    next_detect = now + self.DETECT_EVERY_S
                    latency = find_latency(np.concatenate(parts)[:, rig.mic_channel], self.excitation)
                    if latency is not None:
                        # One callback block of slack so the final estimate fits too.
                        target = latency + self.n_target + rig.frames_per_buffer
                if target is not None and total >= target:
                    mic = np.concatenate(parts)[:, rig.mic_channel]
                    latency = find_latency(mic, self.excitation)
                    if latency is not None and latency + self.n_target <= total:
                        break
                    target = (latency or 0) + self.n_target + rig.frames_per_buffer
                if target is None and total >= give_up:
                    raise ExcitationNotFoundError(
                        f"the excitation played on output device {self.dout} did not come back in input "
                        f"device {self.din} (channel {rig.mic_channel}) within {rig.max_latency_s} s: "
                        "check the wiring, gains and device choice", device=self.din.name)
        except BaseException as exc:
            self._stop()
            total += self._drain(parts)
            if parts:  # align what there is, so the partial recording is usable as is
                latency = find_latency(np.concatenate(parts)[:, rig.mic_channel], self.excitation)
            rec = self._recording(parts, latency, reported, complete=False,
                                  error=f"{type(exc).__name__}: {exc}")
            path = self._save_partial(rec)
            if isinstance(exc, RigError):
                exc.recording, exc.partial_path = rec, path
                if path is not None:
                    exc.args = (f"{exc.args[0]} -- the {rec.input.shape[0] / rig.sample_rate_hz:.2f} s recorded so far "
                                f"are saved in {path}",)
            rig.last_recording = rec
            raise
        self._stop()
        self._drain(parts)
        rec = self._recording(parts, latency, reported, complete=True, error=None)
        rig.last_recording = rec
        if rec.problems and rig.xrun_policy != "ignore":
            msg = (f"recording on input {self.din} / output {self.dout}: " + "; ".join(rec.problems))
            if rig.xrun_policy == "raise":
                rec.complete = False
                rec.error = msg
                path = self._save_partial(rec)
                raise XrunError(msg + (f" -- the recording is saved in {path}" if path else ""),
                                device=self.din.name, recording=rec, partial_path=path)
            warnings.warn(msg, RigWarning, stacklevel=3)
        if rec.clipped and rig.xrun_policy != "ignore":
            warnings.warn(f"input {self.din} reached full scale (clipping?): lower the output gain or the "
                          "microphone gain", RigWarning, stacklevel=3)
        # The streamed partial files stay until the caller has saved the final file
        # (RigRecording.save), so there is no moment with neither on disk.
        rec._writer = self.writer
        return rec

    def _recording(self, parts, latency, reported, *, complete: bool, error: str | None) -> RigRecording:
        rig = self.rig
        data = np.concatenate(parts) if parts else np.zeros((0, rig.input_channels), np.float32)
        mic = data[:, rig.mic_channel]
        lags: list[int] = []
        problems: list[str] = []
        if latency is not None:
            # Only the periods inside the kept span: the stream keeps running for a moment
            # after the target is reached.
            span = mic[: latency + self.n_target] if complete else mic
            lags = period_lags(span, self.excitation, latency).tolist()
            drift = (max(lags) - min(lags)) if lags else 0
            if drift > rig.sync_tolerance_samples:
                problems.append(f"sample synchronization lost: the excitation period drifted by {drift} samples "
                                f"(per-period latencies {sorted(set(lags))[:8]}), samples were dropped or inserted")
        flags: dict[str, int] = {}
        for ev in self.events:
            if ev["flag"] != "priming_output":
                flags[f"{ev['stream']} {ev['flag']}"] = flags.get(f"{ev['stream']} {ev['flag']}", 0) + 1
        problems += [f"{n} callback(s) flagged {k}" for k, n in sorted(flags.items())]
        return RigRecording(
            input=data, mic_channel=rig.mic_channel, sample_rate_hz=rig.sample_rate_hz, excitation=self.excitation,
            duration_s=self.duration_s, latency_samples=latency, period_lags_samples=lags, events=list(self.events),
            input_device=self.din, output_device=self.dout, stream_mode=rig.stream_mode,
            reported_latency_s=reported, started_at=self.started_at, complete=complete, problems=problems,
            error=error, lead_in_samples=self.lead_in)

    def _save_partial(self, rec: RigRecording) -> Path | None:
        if self.writer is None:
            return None
        self.writer.close()
        if rec.input.shape[0] == 0:
            self.writer.discard()
            return None
        obs = rec.to_observation(trim=False, labels=self.labels)
        obs.save(self.writer.npz_path)
        self.writer.discard()
        return self.writer.npz_path
