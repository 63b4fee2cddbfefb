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
(+ ``.partial.json``) while recording and end up in ``<name>.partial.npz``. A disk that fills
up (or refuses the file) loses nothing either: the recording finishes in memory and comes back
on :class:`StorageError`, with what fitted on disk as its ``partial_path``.
"""

from __future__ import annotations

import math
import os
from typing import Any

from sensors import Excitation

from .devices import SERVER_TIMEOUT_S, check_sample_rate, list_devices, portaudio_session, quiet_stderr, resolve_device
from .errors import (DeviceLostError, DeviceNotFoundError, ExcitationNotFoundError, NoAudioDeviceError, RigError,
                     RigWarning, StorageError, UnsupportedSampleRateError, XrunError)
from .partial_files import partial_paths, recover_partial
from .records import AudioDevice, RigRecording
from .session import RecordingSession
from .settings import RigSettings

__all__ = ["AudioDevice", "DeviceLostError", "DeviceNotFoundError", "ExcitationNotFoundError", "NoAudioDeviceError",
           "PyAudioRig", "RigError", "RigRecording", "RigSettings", "RigWarning", "StorageError",
           "UnsupportedSampleRateError", "XrunError", "list_devices", "partial_paths", "recover_partial",
           "resolve_device", "check_sample_rate"]


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
        period_tolerance: allowed relative RMS difference between consecutive aligned
            periods (a steady state repeats every period; noise at 40 dB SNR differs by
            1.4 %, a lost 1024-sample block by about 30 %).
        lead_in_s: the output starts this long (at most one period) before a period
            boundary, playing the end of the loop: devices that lose their first output
            buffer lose part of the lead-in, and a real object is already vibrating in its
            steady state when the first aligned period starts.
        server_timeout_s: longest wait for a sound-server call that can block (PortAudio's
            initialization, closing the streams, termination). A recording whose server
            stalls returns within about ``stall_timeout_s + 2 * server_timeout_s`` with a
            :class:`DeviceLostError` carrying the partial recording (saved with a
            ``save_path``); while PortAudio is still blocked, new recordings in this process
            fail at once with a :class:`DeviceLostError` saying so.

    Raises at construction if PortAudio finds no device, the named device does not exist, or
    it refuses ``sample_rate_hz``; every error names the device.
    """

    def __init__(self, input_device: int | str | None = None, output_device: int | str | None = None,
                 sample_rate_hz: int = 44100, *, actuator_channel: int = 0, mic_channel: int = 0,
                 output_channels: int | None = None, input_channels: int | None = None,
                 frames_per_buffer: int = 1024, stream_mode: str = "separate", output_gain: float = 1.0,
                 max_latency_s: float = 2.0, start_timeout_s: float = 5.0, stall_timeout_s: float = 1.0,
                 xrun_policy: str = "raise", sync_tolerance_samples: int = 0, period_tolerance: float = 0.1,
                 lead_in_s: float = 0.1, server_timeout_s: float = SERVER_TIMEOUT_S) -> None:
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
        if not (math.isfinite(period_tolerance) and period_tolerance > 0):
            raise ValueError(f"period_tolerance must be > 0, got {period_tolerance!r}")
        self.period_tolerance = float(period_tolerance)
        if not (math.isfinite(lead_in_s) and lead_in_s >= 0):
            raise ValueError(f"lead_in_s must be >= 0, got {lead_in_s!r}")
        self.lead_in_s = float(lead_in_s)
        if not (math.isfinite(server_timeout_s) and server_timeout_s > 0):
            raise ValueError(f"server_timeout_s must be > 0, got {server_timeout_s!r}")
        self.server_timeout_s = float(server_timeout_s)
        self.last_recording: RigRecording | None = None
        with portaudio_session(self.server_timeout_s) as pa:
            self.resolve_devices(pa)

    @property
    def settings(self) -> RigSettings:
        """The rig's current settings as one frozen value: what a recording or a
        :class:`real.RigStream` runs with (a snapshot, taken when it starts)."""
        return RigSettings(
            sample_rate_hz=self.sample_rate_hz, actuator_channel=self.actuator_channel, mic_channel=self.mic_channel,
            output_channels=self.output_channels, input_channels=self.input_channels,
            frames_per_buffer=self.frames_per_buffer, stream_mode=self.stream_mode, output_gain=self.output_gain,
            max_latency_s=self.max_latency_s, start_timeout_s=self.start_timeout_s,
            stall_timeout_s=self.stall_timeout_s, xrun_policy=self.xrun_policy,
            sync_tolerance_samples=self.sync_tolerance_samples, period_tolerance=self.period_tolerance,
            lead_in_s=self.lead_in_s, server_timeout_s=self.server_timeout_s)

    def resolve_devices(self, pa) -> tuple[AudioDevice, AudioDevice]:
        """Look the input and output devices up again in the PortAudio session ``pa`` (they may
        have moved or vanished since), check the sample rate on both, keep them as
        ``input_device`` / ``output_device`` and return them.

        Raises:
            NoAudioDeviceError, DeviceNotFoundError, UnsupportedSampleRateError.
        """
        din = resolve_device(pa, self.input_spec, "input", self.input_channels)
        dout = resolve_device(pa, self.output_spec, "output", self.output_channels)
        check_sample_rate(pa, din, "input", self.sample_rate_hz, self.input_channels)
        check_sample_rate(pa, dout, "output", self.sample_rate_hz, self.output_channels)
        self.input_device, self.output_device = din, dout
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
            DeviceLostError: before recording too, if the sound server does not answer within
                ``server_timeout_s`` or PortAudio is still blocked in an earlier call.
            DeviceLostError, ExcitationNotFoundError, XrunError, KeyboardInterrupt: during;
                :class:`RigError` s carry the samples recorded so far as ``.recording``.
            StorageError: the partial file could not be written (disk full, file too large):
                the recording is complete in ``.recording``; ``.partial_path`` holds what
                fitted (``recover_partial(path, out_dir=...)`` makes an .npz of it elsewhere).
        """
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
        if excitation.sample_rate_hz != self.sample_rate_hz:
            raise ValueError(f"excitation sampled at {excitation.sample_rate_hz} Hz, rig runs at {self.sample_rate_hz} Hz")
        duration_s = float(duration_s)
        if not (math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration_s must be > 0, got {duration_s!r}")
        with portaudio_session(self.server_timeout_s) as pa:
            din, dout = self.resolve_devices(pa)
            session = RecordingSession(self.settings, pa, din, dout, excitation, duration_s, save_path, labels,
                                       on_progress)
            try:
                # PortAudio's threads print ALSA/PulseAudio diagnostics on fd 2 while streaming
                # (many when a device vanishes): keep them out of the terminal, pass on the rest.
                with quiet_stderr():
                    return session.run()
            finally:  # also what an error or Ctrl-C stopped: the samples recorded until then
                if session.recording is not None:
                    self.last_recording = session.recording
