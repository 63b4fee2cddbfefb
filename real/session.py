"""One recording on the rig (:class:`RecordingSession`): the streams, the watch loop and the
checks after it (latency, synchronization, xruns), and the partial files when it stops early."""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

from sensors import Excitation

from .errors import ExcitationNotFoundError, RigError, RigWarning, StorageError, XrunError
from .latency import find_latency, period_lags, period_mismatch
from .partial_files import PartialWriter
from .records import AudioDevice, RigRecording
from .settings import RigSettings
from .streams import RigStreams


class RecordingSession:
    """One recording on open devices: the streams (:class:`RigStreams`), the watch loop and the
    checks after it. :meth:`run` records; whatever it ends with (a complete recording, or what
    was recorded before an error) is kept in :attr:`recording` for the rig's ``last_recording``."""

    DETECT_EVERY_S = 0.1

    def __init__(self, settings: RigSettings, pa, din: AudioDevice, dout: AudioDevice, excitation: Excitation,
                 duration_s: float, save_path, labels, on_progress=None) -> None:
        self.settings = settings
        self.audio = RigStreams(settings, pa, din, dout, excitation)
        self.din, self.dout, self.excitation, self.P = din, dout, excitation, self.audio.P
        self.recording: RigRecording | None = None
        self.on_progress = on_progress
        self.duration_s = duration_s
        self.labels = labels
        self.n_target = int(round(duration_s * settings.sample_rate_hz))
        self.writer = None
        if save_path is not None:
            self.writer = PartialWriter(Path(save_path), {
                "channels": settings.input_channels, "mic_channel": settings.mic_channel,
                "sample_rate_hz": settings.sample_rate_hz,
                "dtype": "float32le interleaved", "excitation": excitation.to_dict(),
                "metadata": {"source": "real", "device": {"input": din.to_dict(), "output": dout.to_dict()},
                             "recorded_at": self.audio.started_at, "labels": dict(labels or {}),
                             "excitation": excitation.name}})

    def _drain(self, parts: list[np.ndarray]) -> int:
        got = 0
        for block in self.audio.take():
            parts.append(block)
            if self.writer is not None:
                self.writer.append(block)
            got += block.shape[0]
        return got

    def run(self) -> RigRecording:
        """Record until ``duration_s`` of microphone signal after the first excitation period
        are in, then check it (raises as :meth:`real.PyAudioRig.record`)."""
        st, audio = self.settings, self.audio
        parts: list[np.ndarray] = []
        total = 0
        latency = None
        target = None
        next_detect = 0.0
        give_up = int((st.max_latency_s + 2 * self.excitation.period_s) * st.sample_rate_hz) + self.n_target
        reported = {}
        try:
            audio.start()
            reported = audio.reported_latency()
            while True:
                time.sleep(audio.POLL_S)
                total += self._drain(parts)
                if self.on_progress is not None:
                    self.on_progress(total)
                audio.check_alive()
                now = time.monotonic()
                if target is None and total >= self.P and now >= next_detect:
                    next_detect = now + self.DETECT_EVERY_S
                    latency = find_latency(np.concatenate(parts)[:, st.mic_channel], self.excitation)
                    if latency is not None:
                        # One callback block of slack so the final estimate fits too.
                        target = latency + self.n_target + st.frames_per_buffer
                if target is not None and total >= target:
                    mic = np.concatenate(parts)[:, st.mic_channel]
                    latency = find_latency(mic, self.excitation)
                    if latency is not None and latency + self.n_target <= total:
                        break
                    target = (latency or 0) + self.n_target + st.frames_per_buffer
                if target is None and total >= give_up:
                    raise ExcitationNotFoundError(
                        f"the excitation played on output device {self.dout} did not come back in input "
                        f"device {self.din} (channel {st.mic_channel}) within {st.max_latency_s} s: "
                        "check the wiring, gains and device choice", device=self.din.name)
        except BaseException as exc:
            audio.stop()
            total += self._drain(parts)
            if parts:  # align what there is, so the partial recording is usable as is
                latency = find_latency(np.concatenate(parts)[:, st.mic_channel], self.excitation)
            rec = self._recording(parts, latency, reported, complete=False,
                                  error=f"{type(exc).__name__}: {exc}")
            path = self._save_partial(rec)
            if isinstance(exc, RigError):
                exc.recording, exc.partial_path = rec, path
                if path is not None:
                    exc.args = (f"{exc.args[0]} -- {self._where_saved(rec, path)}",)
            self.recording = rec
            raise
        audio.stop()
        self._drain(parts)
        rec = self._recording(parts, latency, reported, complete=True, error=None)
        self.recording = rec
        if self.writer is not None and self.writer.error is not None:
            raise self._storage_error(rec)
        if rec.problems and st.xrun_policy != "ignore":
            msg = (f"recording on input {self.din} / output {self.dout}: " + "; ".join(rec.problems))
            if st.xrun_policy == "raise":
                rec.complete = False
                rec.error = msg
                path = self._save_partial(rec)
                raise XrunError(msg + (f" -- {self._where_saved(rec, path)}" if path else ""),
                                device=self.din.name, recording=rec, partial_path=path)
            warnings.warn(msg, RigWarning, stacklevel=3)
        if rec.clipped and st.xrun_policy != "ignore":
            warnings.warn(f"input {self.din} reached full scale (clipping?): lower the output gain or the "
                          "microphone gain", RigWarning, stacklevel=3)
        # The streamed partial files stay until the caller has saved the final file
        # (RigRecording.save), so there is no moment with neither on disk.
        rec.partial_files = self.writer
        return rec

    def _recording(self, parts, latency, reported, *, complete: bool, error: str | None) -> RigRecording:
        st, audio = self.settings, self.audio
        data = np.concatenate(parts) if parts else np.zeros((0, st.input_channels), np.float32)
        mic = data[:, st.mic_channel]
        lags: list[int] = []
        problems: list[str] = []
        if latency is not None:
            # Only the periods inside the kept span: the stream keeps running for a moment
            # after the target is reached.
            span = mic[: latency + self.n_target] if complete else mic
            lags = period_lags(span, self.excitation, latency).tolist()
            drift = (max(lags) - min(lags)) if lags else 0
            if drift > st.sync_tolerance_samples:
                problems.append(f"sample synchronization lost: the excitation period drifted by {drift} samples "
                                f"(per-period latencies {sorted(set(lags))[:8]}), samples were dropped or inserted")
            else:
                # aligned, but is every period the same? (a lost block and a repeated one in
                # the same period keep the latency)
                mismatch = period_mismatch(span, self.P, lags)
                bad = np.flatnonzero(mismatch > st.period_tolerance)
                if bad.size:
                    problems.append(f"period {int(bad[0]) + 1} differs from the one before by "
                                    f"{100 * mismatch[bad[0]]:.2g} % RMS (tolerance {100 * st.period_tolerance:.2g} %): "
                                    "samples were dropped, inserted or corrupted")
        problems += audio.flag_problems()
        return RigRecording(
            input=data, mic_channel=st.mic_channel, sample_rate_hz=st.sample_rate_hz, excitation=self.excitation,
            duration_s=self.duration_s, latency_samples=latency, period_lags_samples=lags, events=list(audio.events),
            input_device=self.din, output_device=self.dout, stream_mode=st.stream_mode,
            reported_latency_s=reported, started_at=audio.started_at, complete=complete, problems=problems,
            error=error, lead_in_samples=audio.lead_in)

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
        sr, n = self.settings.sample_rate_hz, rec.input.shape[0]
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
