"""The rig's PortAudio streams and their callbacks (:class:`_Streams`, shared with
``real.rig_stream``), and one recording on them: the watch loop and the checks after it
(latency, synchronization, xruns)."""

from __future__ import annotations

import contextlib
import datetime as _dt
import threading
import time
import warnings
from collections import deque
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sensors import Excitation

from . import bounded
from .devices import AudioDevice, _alsa_hint, _captured_stderr, _terminate_portaudio, pyaudio
from .errors import (DeviceLostError, ExcitationNotFoundError, RigError, RigWarning, StorageError,
                     UnsupportedSampleRateError, XrunError)
from .latency import find_latency, period_lags, period_mismatch

if TYPE_CHECKING:
    from .rig import PyAudioRig
from .rig_recording import _FLAGS, _PROBLEM_FLAGS, RigRecording, _PartialWriter


class _Streams:
    """The rig's PortAudio streams with the excitation looping on the actuator channel: the
    callbacks, opening and starting, liveness and stopping. Input blocks queue up in
    ``in_chunks`` (PortAudio's thread appends, the caller's thread drains)."""

    POLL_S = 0.02

    def __init__(self, rig: PyAudioRig, pa, din: AudioDevice, dout: AudioDevice, excitation: Excitation) -> None:
        self.rig, self.pa, self.din, self.dout = rig, pa, din, dout
        self.excitation = excitation
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
        self.new_input = threading.Event()  # set by every input callback: readers wait on it
        self.streams: list[Any] = []
        self.started: set[str] = set()  # kinds of the streams started (the output waits for the input)
        self.stopping = False
        self.started_at = _dt.datetime.now(_dt.timezone.utc).isoformat()

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
            self.started.add("duplex")
            self._wait_first_input()
            return
        sin = self._open(channels=rig.input_channels, input=True, input_device_index=self.din.index,
                         stream_callback=self._in_cb)
        self.streams.append(("input", sin))
        sout = self._open(channels=rig.output_channels, output=True, output_device_index=self.dout.index,
                          stream_callback=self._out_cb)
        self.streams.append(("output", sout))
        sin.start_stream()
        self.started.add("input")
        # The output starts once the input runs, so the first period is always recorded.
        self._wait_first_input()
        sout.start_stream()
        self.started.add("output")

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
            # Only started streams: the first input can arrive between the wait for it and
            # this check, while the output is not started yet (a 'lost' output under load).
            if not active and not self.stopping and kind in self.started:
                dev = self.dout if kind == "output" else self.din
                raise DeviceLostError(f"{kind} stream on device {dev} stopped during the recording "
                                      "(device disconnected or sound server gone)", device=dev.name)
        if self.last_in_t is not None and time.monotonic() - self.last_in_t > self.rig.stall_timeout_s:
            raise DeviceLostError(f"input device {self.din} delivered nothing for {self.rig.stall_timeout_s} s "
                                  "during the recording (device disconnected or sound server gone)",
                                  device=self.din.name)

    def _take(self) -> list[np.ndarray]:
        """The input blocks queued since the last call, ``(frames, input_channels)`` each."""
        ch = self.rig.input_channels
        out = []
        while self.in_chunks:
            out.append(np.frombuffer(self.in_chunks.popleft(), dtype=np.float32).reshape(-1, ch))
        return out

    def _stop(self, terminate: bool = False) -> bool:
        """Stop and close the streams (and with ``terminate`` end the PortAudio session after
        them: terminating closes blocked ones again). A stream of a stalled or vanished sound
        server blocks in PortAudio until the server answers, so this waits at most the rig's
        ``server_timeout_s`` (:mod:`real.bounded`); returns False if it gave up (the streams
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

        with _captured_stderr():
            done, _ = bounded.call_bounded(close_all, self.rig.server_timeout_s, "closing the streams")
        if terminate:
            _terminate_portaudio(self.pa, self.rig.server_timeout_s)
        return done

    def _reported_latency(self) -> dict[str, float]:
        """PortAudio's own input/output latency estimates, seconds."""
        reported = {}
        for kind, s in self.streams:
            with contextlib.suppress(Exception):
                if kind in ("input", "duplex"):
                    reported["input"] = float(s.get_input_latency())
                if kind in ("output", "duplex"):
                    reported["output"] = float(s.get_output_latency())
        return reported

    def _flag_problems(self) -> list[str]:
        """One line per callback status flag seen (priming the output is no problem)."""
        flags: dict[str, int] = {}
        for ev in self.events:
            if ev["flag"] != "priming_output":
                flags[f"{ev['stream']} {ev['flag']}"] = flags.get(f"{ev['stream']} {ev['flag']}", 0) + 1
        return [f"{n} callback(s) flagged {k}" for k, n in sorted(flags.items())]


class _Session(_Streams):
    """One recording: the streams, the watch loop and the post-checks."""

    DETECT_EVERY_S = 0.1

    def __init__(self, rig: PyAudioRig, pa, din: AudioDevice, dout: AudioDevice, excitation: Excitation,
                 duration_s: float, save_path, labels, on_progress=None) -> None:
        super().__init__(rig, pa, din, dout, excitation)
        self.on_progress = on_progress
        self.duration_s = duration_s
        self.labels = labels
        self.n_target = int(round(duration_s * rig.sample_rate_hz))
        self.writer = None
        if save_path is not None:
            self.writer = _PartialWriter(Path(save_path), {
                "channels": rig.input_channels, "mic_channel": rig.mic_channel, "sample_rate_hz": rig.sample_rate_hz,
                "dtype": "float32le interleaved", "excitation": excitation.to_dict(),
                "metadata": {"source": "real", "device": {"input": din.to_dict(), "output": dout.to_dict()},
                             "recorded_at": self.started_at, "labels": dict(labels or {}),
                             "excitation": excitation.name}})

    def _drain(self, parts: list[np.ndarray]) -> int:
        got = 0
        for block in self._take():
            parts.append(block)
            if self.writer is not None:
                self.writer.append(block)
            got += block.shape[0]
        return got

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
            reported = self._reported_latency()
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
                    exc.args = (f"{exc.args[0]} -- {self._where_saved(rec, path)}",)
            rig.last_recording = rec
            raise
        self._stop()
        self._drain(parts)
        rec = self._recording(parts, latency, reported, complete=True, error=None)
        rig.last_recording = rec
        if self.writer is not None and self.writer.error is not None:
            raise self._storage_error(rec)
        if rec.problems and rig.xrun_policy != "ignore":
            msg = (f"recording on input {self.din} / output {self.dout}: " + "; ".join(rec.problems))
            if rig.xrun_policy == "raise":
                rec.complete = False
                rec.error = msg
                path = self._save_partial(rec)
                raise XrunError(msg + (f" -- {self._where_saved(rec, path)}" if path else ""),
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
            else:
                # aligned, but is every period the same? (a lost block and a repeated one in
                # the same period keep the latency)
                mismatch = period_mismatch(span, self.P, lags)
                bad = np.flatnonzero(mismatch > rig.period_tolerance)
                if bad.size:
                    problems.append(f"period {int(bad[0]) + 1} differs from the one before by "
                                    f"{100 * mismatch[bad[0]]:.2g} % RMS (tolerance {100 * rig.period_tolerance:.2g} %): "
                                    "samples were dropped, inserted or corrupted")
        problems += self._flag_problems()
        return RigRecording(
            input=data, mic_channel=rig.mic_channel, sample_rate_hz=rig.sample_rate_hz, excitation=self.excitation,
            duration_s=self.duration_s, latency_samples=latency, period_lags_samples=lags, events=list(self.events),
            input_device=self.din, output_device=self.dout, stream_mode=rig.stream_mode,
            reported_latency_s=reported, started_at=self.started_at, complete=complete, problems=problems,
            error=error, lead_in_samples=self.lead_in)

    def _save_partial(self, rec: RigRecording) -> Path | None:
        """Save ``rec`` as ``<name>.partial.npz`` and drop the streamed files; if the disk
        refuses, keep the streamed files (what fitted) and return the raw one."""
        w = self.writer
        if w is None:
            return None
        w.close()
        if rec.input.shape[0] == 0:
            w.discard()
            return None
        try:
            rec.to_observation(trim=False, labels=self.labels).save(w.npz_path)
        except OSError as exc:
            w.error = w.error or exc
            return w.raw_path if w.has_data else None
        w.discard()
        return w.npz_path

    def _where_saved(self, rec: RigRecording, path: Path) -> str:
        sr, n = self.rig.sample_rate_hz, rec.input.shape[0]
        if path == self.writer.npz_path:
            return f"the {n / sr:.2f} s recorded {'' if rec.complete else 'so far '}are saved in {path}"
        return (f"the disk took only the first {self.writer.frames_written / sr:.2f} s of the {n / sr:.2f} s "
                f"recorded ({self.writer.error.strerror or self.writer.error}): they are in {path} "
                "(real.recover_partial(path, out_dir=...) makes an .npz of them), all of them in .recording")

    def _storage_error(self, rec: RigRecording) -> StorageError:
        """The streamed file failed (disk full, file too large) but the recording is whole in
        memory: say where what fitted went."""
        cause = self.writer.error
        path = self._save_partial(rec)
        where = self._where_saved(rec, path) if path is not None else (
            f"nothing could be written to {self.writer.raw_path.parent}")
        return StorageError(f"writing the recording to {self.writer.raw_path} failed ({cause.strerror or cause}); "
                            f"the recording is complete in memory (.recording, rig.last_recording) -- {where}",
                            cause=cause, device=self.din.name, recording=rec, partial_path=path)
