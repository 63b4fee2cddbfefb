"""The rig's PortAudio streams with the excitation looping on the actuator channel
(:class:`RigStreams`): the callbacks, opening and starting, liveness checks and a bounded stop.
A recording (:mod:`real.session`) and a stream (:mod:`real.rig_stream`) both run on them."""

from __future__ import annotations

import contextlib
import datetime as _dt
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from sensors import Excitation

from . import bounded
from .devices import alsa_hint, captured_stderr, pyaudio, terminate_portaudio
from .errors import DeviceLostError, RigError, UnsupportedSampleRateError
from .records import CALLBACK_FLAGS, PROBLEM_FLAGS, AudioDevice
from .settings import RigSettings


class RigStreams:
    """The rig's PortAudio streams with the excitation looping on the actuator channel: the
    callbacks, opening and starting, liveness and stopping. Input blocks queue up in
    ``in_chunks`` (PortAudio's thread appends, the caller's thread drains)."""

    POLL_S = 0.02

    def __init__(self, settings: RigSettings, pa, din: AudioDevice, dout: AudioDevice, excitation: Excitation) -> None:
        self.settings, self.pa, self.din, self.dout = settings, pa, din, dout
        self.excitation = excitation
        # One period, actuator channel only, interleaved; tiled so any callback's block is a
        # contiguous slice.
        P = excitation.period_samples
        frame = np.zeros((P, settings.output_channels), dtype=np.float32)
        frame[:, settings.actuator_channel] = settings.output_gain * excitation.signal
        reps = 2 + (settings.frames_per_buffer + P - 1) // P
        self.out_tiled = np.tile(frame, (reps, 1))
        self.P = P
        self.lead_in = min(int(round(settings.lead_in_s * settings.sample_rate_hz)), P)
        self.out_pos = (-self.lead_in) % P
        self.in_chunks: deque[bytes] = deque()
        self.in_frames = 0
        self.events: list[dict[str, Any]] = []
        self.last_in_t = None
        self.first_in = threading.Event()
        self.new_input = threading.Event()  # set by every input callback: readers wait on it
        self.streams: list[Any] = []
        self.started: set[str] = set()  # kinds of the streams started (the output waits for the input)
        self.stopping = False
        self.started_at = _dt.datetime.now(_dt.timezone.utc).isoformat()

    # PortAudio threads ------------------------------------------------------------------

    def _note_flags(self, stream: str, status: int, frame: int) -> None:
        if status & PROBLEM_FLAGS or status & 16:
            for bit, name in CALLBACK_FLAGS.items():
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
        self.new_input.set()
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
        st = self.settings
        dev = self.din if kw.get("input") else self.dout
        try:
            with captured_stderr() as lines:
                return self.pa.open(rate=st.sample_rate_hz, format=pyaudio.paFloat32, frames_per_buffer=st.frames_per_buffer,
                                    start=False, **kw)
        except (OSError, ValueError) as exc:
            err = exc.args[1] if isinstance(exc, OSError) and len(exc.args) > 1 else exc
            which = "duplex" if kw.get("input") and kw.get("output") else ("input" if kw.get("input") else "output")
            cls = UnsupportedSampleRateError if "sample rate" in str(err).lower() else RigError
            raise cls(f"cannot open the {which} stream on device {dev} at {st.sample_rate_hz} Hz: {err}{alsa_hint(lines)}",
                      device=dev.name) from None

    def start(self) -> None:
        """Open and start the streams; returns once the input delivers (the output of
        separate streams starts then, so the first period is always recorded)."""
        st = self.settings
        if st.stream_mode == "duplex":
            s = self._open(channels=st.input_channels, input=True, output=True,
                           input_device_index=self.din.index, output_device_index=self.dout.index,
                           stream_callback=self._duplex_cb)
            self.streams.append(("duplex", s))
            s.start_stream()
            self.started.add("duplex")
            self._wait_first_input()
            return
        sin = self._open(channels=st.input_channels, input=True, input_device_index=self.din.index,
                         stream_callback=self._in_cb)
        self.streams.append(("input", sin))
        sout = self._open(channels=st.output_channels, output=True, output_device_index=self.dout.index,
                          stream_callback=self._out_cb)
        self.streams.append(("output", sout))
        sin.start_stream()
        self.started.add("input")
        # The output starts once the input runs, so the first period is always recorded.
        self._wait_first_input()
        sout.start_stream()
        self.started.add("output")

    def _wait_first_input(self) -> None:
        deadline = time.monotonic() + self.settings.start_timeout_s
        while not self.first_in.wait(self.POLL_S):
            self.check_alive()
            if time.monotonic() > deadline:
                raise DeviceLostError(f"input device {self.din} delivered no audio within "
                                      f"{self.settings.start_timeout_s} s of starting", device=self.din.name)

    def check_alive(self) -> None:
        """Raise :class:`DeviceLostError` if a started stream stopped or the input stalled."""
        for kind, s in self.streams:
            try:
                active = s.is_active()
            except OSError:
                active = False
            # Only started streams: the first input can arrive between the wait for it and
            # this check, while the output is not started yet (a 'lost' output under load).
            if not active and not self.stopping and kind in self.started:
                dev = self.dout if kind == "output" else self.din
                raise DeviceLostError(f"{kind} stream on device {dev} stopped during the recording "
                                      "(device disconnected or sound server gone)", device=dev.name)
        if self.last_in_t is not None and time.monotonic() - self.last_in_t > self.settings.stall_timeout_s:
            raise DeviceLostError(f"input device {self.din} delivered nothing for {self.settings.stall_timeout_s} s "
                                  "during the recording (device disconnected or sound server gone)",
                                  device=self.din.name)

    def take(self) -> list[np.ndarray]:
        """The input blocks queued since the last call, ``(frames, input_channels)`` each."""
        ch = self.settings.input_channels
        out = []
        while self.in_chunks:
            out.append(np.frombuffer(self.in_chunks.popleft(), dtype=np.float32).reshape(-1, ch))
        return out

    def stop(self, terminate: bool = False) -> bool:
        """Stop and close the streams (and with ``terminate`` end the PortAudio session after
        them: terminating closes blocked ones again). A stream of a stalled or vanished sound
        server blocks in PortAudio until the server answers, so this waits at most the
        settings' ``server_timeout_s`` (:mod:`real.bounded`); returns False if it gave up (the streams
        then close when the server answers, and new sessions are refused until they have).
        Callers keep PortAudio's diagnostics off the terminal."""
        self.stopping = True
        streams = [s for _, s in self.streams]

        def close_all():
            for s in streams:
                with contextlib.suppress(Exception):
                    s.stop_stream()
                with contextlib.suppress(Exception):
                    s.close()

        with captured_stderr():
            done, _ = bounded.call_bounded(close_all, self.settings.server_timeout_s, "closing the streams")
        if terminate:
            terminate_portaudio(self.pa, self.settings.server_timeout_s)
        return done

    def reported_latency(self) -> dict[str, float]:
        """PortAudio's own input/output latency estimates, seconds."""
        reported = {}
        for kind, s in self.streams:
            with contextlib.suppress(Exception):
                if kind in ("input", "duplex"):
                    reported["input"] = float(s.get_input_latency())
                if kind in ("output", "duplex"):
                    reported["output"] = float(s.get_output_latency())
        return reported

    def flag_problems(self) -> list[str]:
        """One line per callback status flag seen (priming the output is no problem)."""
        flags: dict[str, int] = {}
        for ev in self.events:
            if ev["flag"] != "priming_output":
                flags[f"{ev['stream']} {ev['flag']}"] = flags.get(f"{ev['stream']} {ev['flag']}", 0) + 1
        return [f"{n} callback(s) flagged {k}" for k, n in sorted(flags.items())]
