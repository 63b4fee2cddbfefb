"""``RigStream``: the rig recording without a break while the excitation loops, read piece by
piece -- the real counterpart of ``sensors.AcousticStream`` (what ``RealGraspEnv`` streams).

The rig's devices open as for a recording (:class:`real.streams.RigStreams`: separate or duplex
streams, callbacks, xrun flags, device-lost checks) and stay open until :meth:`RigStream.close`.
The stream is aligned once: its sample 0 is the first complete excitation period that came
back (the round-trip latency is measured with :func:`real.latency.find_latency` on the
incoming samples), so stream sample k was played at excitation phase ``k % period``, as in
the simulated stream. Every later period is checked against that alignment (dropped or
inserted samples move the excitation) and PortAudio's flags are collected in
:attr:`RigStream.problems`; a stream reports them and goes on (``xrun_policy`` is for
recordings). Everything recorded is kept (176 kB per second of mono float32) and stays
available through :meth:`RigStream.recording`, also after a device was lost.
"""

from __future__ import annotations

import math
import time

import numpy as np

from sensors import Excitation
from sensors.signals.features import spectral_features

from .devices import new_portaudio, quiet_stderr, terminate_portaudio
from .errors import DeviceLostError, ExcitationNotFoundError, RigError
from .latency import MIN_PEAK_TO_MEDIAN, excitation_correlation, find_latency, period_mismatch
from .records import RigRecording
from .rig import PyAudioRig
from .streams import RigStreams


class RigStream:
    """The rig's microphone, recording without a break while the actuator loops ``excitation``.

    Use as a context manager (or call :meth:`start` and :meth:`close`)::

        with RigStream(rig, "linear") as stream:
            chunk = stream.read(2205)           # the next 50 ms at 44.1 kHz
            features = stream.latest_features()

    Args:
        rig: the :class:`PyAudioRig` whose devices, channels, gain, lead-in and timeouts
            (``max_latency_s``, ``start_timeout_s``, ``stall_timeout_s``,
            ``sync_tolerance_samples``) the stream uses, as they are when the stream is made.
        excitation: ``sensors.Excitation`` or its name, at the rig's sample rate.
        period_tolerance: if set, every complete period is also compared with the one before
            (relative RMS) and a larger difference is reported as dropped or inserted
            samples. For steady loops only (a loopback, a grasp held still): a moving grasp
            changes the periods too. ``None``: alignment and PortAudio's flags only.

    Attributes:
        settings: the rig's :class:`real.RigSettings` the stream runs with.
        latency_samples: input samples before stream sample 0 (``None`` until aligned).
        position: stream index of the next sample :meth:`read` returns.
    """

    DETECT_EVERY_S = 0.1

    def __init__(self, rig: PyAudioRig, excitation: Excitation | str, *, period_tolerance: float | None = None) -> None:
        if not isinstance(rig, PyAudioRig):
            raise TypeError(f"rig must be a real.PyAudioRig, got {type(rig).__name__}")
        excitation = Excitation.by_name(excitation) if isinstance(excitation, str) else excitation
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation or a name, got {type(excitation).__name__}")
        if excitation.sample_rate_hz != rig.sample_rate_hz:
            raise ValueError(f"excitation sampled at {excitation.sample_rate_hz} Hz, rig runs at {rig.sample_rate_hz} Hz")
        if period_tolerance is not None and not (math.isfinite(period_tolerance) and period_tolerance > 0):
            raise ValueError(f"period_tolerance must be > 0 or None, got {period_tolerance!r}")
        self.rig, self.excitation = rig, excitation
        self.settings = rig.settings  # what the stream runs with, taken now
        self.period_tolerance = period_tolerance
        self.sample_rate_hz = self.settings.sample_rate_hz
        self.P = excitation.period_samples
        self.latency_samples: int | None = None
        self.position = 0
        self._streams: RigStreams | None = None
        self._closed = False
        self._error: str | None = None
        self._input = np.zeros((1 << 16, self.settings.input_channels), np.float32)  # grows by doubling
        self._n = 0                                 # input frames received
        self._reported: dict[str, float] = {}
        self._next_detect = 0.0
        self._lags: list[int] = []                  # per checked period: measured latency
        self._checked = 0                           # periods whose alignment was checked
        self._sync_problem: str | None = None      # the first of each kind (later ones follow from it)
        self._period_problem: str | None = None
        self._features: np.ndarray | None = None
        self._features_period = -1

    # -- life cycle ------------------------------------------------------------------------

    def start(self) -> RigStream:
        """Open the devices and start playing and recording (returns once the input runs).

        Raises:
            NoAudioDeviceError, DeviceNotFoundError, UnsupportedSampleRateError, DeviceLostError
            (no input within ``rig.start_timeout_s``), RuntimeError if started before.
        """
        if self._streams is not None or self._closed:
            raise RuntimeError("a RigStream starts once; open a new one to stream again")
        # The first matched filter imports scipy.signal (~0.4 s holding the GIL): done now, not
        # while PortAudio's callbacks need the GIL to keep the output fed.
        excitation_correlation(self.excitation.signal, self.excitation)
        pa = new_portaudio(self.settings.server_timeout_s)
        try:
            din, dout = self.rig.resolve_devices(pa)
            self._streams = RigStreams(self.settings, pa, din, dout, self.excitation)
            with quiet_stderr():
                self._streams.start()
            self._reported = self._streams.reported_latency()
        except BaseException:
            self._closed = True
            if self._streams is None:
                terminate_portaudio(pa, self.settings.server_timeout_s)
            else:
                with quiet_stderr():
                    self._streams.stop(terminate=True)
            raise
        return self

    def close(self) -> None:
        """Stop playing and recording and release the devices (idempotent; never hangs: a
        vanished device's streams are given up on after a few seconds). What was recorded
        stays available (:meth:`recording`)."""
        if self.running:
            self._closed = True
            with quiet_stderr():
                self._streams.stop(terminate=True)
            self._collect()  # the last blocks delivered before the streams stopped
            if self.latency_samples is not None:
                self._check_periods()
        self._closed = True

    def __enter__(self) -> RigStream:
        return self if self._streams is not None else self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def running(self) -> bool:
        """Started and not closed."""
        return self._streams is not None and not self._closed

    # -- reading ---------------------------------------------------------------------------

    def read(self, n_samples: int, timeout_s: float | None = None) -> np.ndarray:
        """The next ``n_samples`` microphone samples of the stream, float32, continuing where
        the last read (or :meth:`catch_up`) ended. Blocks until they are recorded; the first
        call also waits for the alignment (about the round-trip latency plus two periods).

        Args:
            n_samples: how many samples.
            timeout_s: longest wait [s]; default the samples' own duration plus 10 s.

        Raises:
            DeviceLostError: the device stopped or stalled (``rig.stall_timeout_s``), or the
                samples did not come within ``timeout_s``. ExcitationNotFoundError: the
                excitation did not come back within ``rig.max_latency_s``. Both carry what was
                recorded as ``.recording`` and close the stream.
        """
        n = int(n_samples)
        if n != n_samples or n < 0:
            raise ValueError(f"n_samples must be an integer >= 0, got {n_samples!r}")
        self._wait_for(self.position + n, timeout_s, n / self.sample_rate_hz)
        start = self.latency_samples + self.position
        self.position += n
        return self._mic(start, start + n).copy()

    def samples(self, start: int, stop: int) -> np.ndarray:
        """Aligned stream samples ``[start, stop)`` already recorded (float32 copy), e.g.
        those a :meth:`catch_up` skipped."""
        if self.latency_samples is None or not 0 <= start <= stop <= self._n - self.latency_samples:
            raise ValueError(f"stream samples [{start}, {stop}) are not recorded yet")
        return self._mic(self.latency_samples + start, self.latency_samples + stop).copy()

    def catch_up(self, *, period_start: bool = False, timeout_s: float | None = None) -> int:
        """Skip the samples recorded but not read yet, so that the next :meth:`read` returns
        samples recorded from now on (the stream index moves on with them: alignment holds).
        With ``period_start`` skip on to the next period boundary and wait for it, so the next
        read also starts at excitation phase 0. Returns the number of samples skipped.
        Waits for the alignment first; raises as :meth:`read`."""
        self._wait_for(self.position, timeout_s, 0.0)
        target = max(self.position, self._n - self.latency_samples)
        if period_start:
            target = -(-target // self.P) * self.P
            self._wait_for(target, timeout_s, self.excitation.period_s)
        skipped, self.position = target - self.position, target
        return skipped

    def latest_features(self) -> np.ndarray | None:
        """``sensors.spectral_features`` (140 amplitudes, 3-10 kHz) of the latest complete
        excitation period up to :attr:`position` (stream samples ``[kP, (k+1)P)``), or
        ``None`` before one. Computed once per period."""
        k = self.position // self.P - 1
        if self.latency_samples is None or k < 0:
            return None
        if k != self._features_period:
            s = self.latency_samples + k * self.P
            self._features = spectral_features(self._mic(s, s + self.P), self.sample_rate_hz,
                                               period_s=self.excitation.period_s)
            self._features_period = k
        return self._features

    @property
    def latest_features_period(self) -> int:
        """Index k of the period behind :meth:`latest_features` (-1: none yet)."""
        return self.position // self.P - 1 if self.latency_samples is not None else -1

    @property
    def problems(self) -> list[str]:
        """Xruns and lost alignment seen so far, one human-readable line each; empty for an
        exact stream. Updated by :meth:`read`, :meth:`catch_up` and :meth:`close`; a period's
        alignment is checked once the next quarter period is in, so a problem in the samples
        just read shows after about 1.25 periods more."""
        found = [p for p in (self._sync_problem, self._period_problem) if p]
        return found + (self._streams.flag_problems() if self._streams else [])

    def recording(self) -> RigRecording:
        """Everything recorded so far (all input channels from the moment the input started,
        pre-roll included) as a :class:`RigRecording`; ``complete`` is False after an error.
        ``to_observation()`` of it starts at stream sample 0."""
        if self._streams is None:
            raise RuntimeError("the stream was never started")
        s, L = self._streams, self.latency_samples
        return RigRecording(
            input=self._input[:self._n].copy(), mic_channel=self.settings.mic_channel,
            sample_rate_hz=self.sample_rate_hz, excitation=self.excitation, duration_s=(self._n - (L or 0)) / self.sample_rate_hz, latency_samples=L,
            period_lags_samples=list(self._lags), events=list(s.events), input_device=s.din, output_device=s.dout,
            stream_mode=self.settings.stream_mode, reported_latency_s=dict(self._reported), started_at=s.started_at,
            complete=self._error is None, problems=self.problems, error=self._error, lead_in_samples=s.lead_in)

    def __repr__(self) -> str:
        state = "running" if self.running else ("closed" if self._closed else "not started")
        return (f"RigStream({self.excitation.name}, {state}, position={self.position}, "
                f"latency_samples={self.latency_samples}, problems={len(self.problems)})")

    # -- internals -------------------------------------------------------------------------

    def _mic(self, start: int, stop: int) -> np.ndarray:
        return self._input[start:stop, self.settings.mic_channel]

    def _wait_for(self, stream_index: int, timeout_s: float | None, duration_s: float) -> None:
        """Block until the aligned stream holds samples up to ``stream_index`` (exclusive)."""
        s = self._streams
        if s is None:
            raise RuntimeError("start the stream first")
        wait_s = duration_s + 10.0 if timeout_s is None else float(timeout_s)
        deadline = time.monotonic() + wait_s
        try:
            # PortAudio's threads print ALSA/PulseAudio diagnostics on fd 2 (many when a device
            # vanishes), mostly while a reader waits here; other lines pass on when it returns.
            with quiet_stderr():
                self._wait_loop(stream_index, deadline, wait_s)
        except RigError as exc:
            if self.running:
                self._error = f"{type(exc).__name__}: {exc}"
                self.close()  # release the devices; the samples stay
            exc.recording = self.recording()
            raise

    def _wait_loop(self, stream_index: int, deadline: float, wait_s: float) -> None:
        s = self._streams
        while True:
            s.new_input.clear()
            if self.running:
                self._collect()
                if self.latency_samples is None:
                    self._align()
                if self.latency_samples is not None:
                    self._check_periods()
                s.check_alive()
            if self.latency_samples is not None and self._n >= self.latency_samples + stream_index:
                return
            if not self.running:
                if self._error is None:
                    raise RuntimeError("the stream is closed: it has no more samples")
                raise DeviceLostError(f"the stream ended: {self._error}", device=s.din.name)
            if time.monotonic() > deadline:
                raise DeviceLostError(f"input device {s.din} did not deliver the samples asked for within "
                                      f"{wait_s:.3g} s", device=s.din.name)
            s.new_input.wait(s.POLL_S)

    def _collect(self) -> None:
        """Move the queued input blocks into the kept recording."""
        for block in self._streams.take():
            m = block.shape[0]
            if self._n + m > self._input.shape[0]:
                grown = np.zeros((max(2 * self._input.shape[0], self._n + m), self._input.shape[1]), np.float32)
                grown[:self._n] = self._input[:self._n]
                self._input = grown
            self._input[self._n:self._n + m] = block
            self._n += m

    def _align(self) -> None:
        P, now = self.P, time.monotonic()
        give_up = int((self.settings.max_latency_s + 3 * self.excitation.period_s) * self.sample_rate_hz)
        if self._n >= 2 * P and now >= self._next_detect:
            self._next_detect = now + self.DETECT_EVERY_S
            lat = find_latency(self._mic(0, min(self._n, give_up + 2 * P)), self.excitation)
            # Committed once the period after the first one is in too: find_latency then
            # checks that the first was complete (as good as its successor).
            if lat is not None and lat + 2 * P <= self._n:
                self.latency_samples = int(lat)
                return
        if self._n >= give_up + 2 * P:
            s = self._streams
            raise ExcitationNotFoundError(
                f"the excitation played on output device {s.dout} did not come back in input device {s.din} "
                f"(channel {self.settings.mic_channel}) within {self.settings.max_latency_s} s: check the wiring, "
                "gains and device choice", device=s.din.name)

    def _check_periods(self) -> None:
        """Where each complete period's excitation arrives (a matched-filter peak within a
        quarter period of the alignment); a move means samples were dropped or inserted."""
        L, P = self.latency_samples, self.P
        w = P // 4
        while L + (self._checked + 1) * P + w <= self._n:
            k = self._checked
            start = L + k * P
            lo = max(0, start - w)
            c = excitation_correlation(self._mic(lo, start + P + w), self.excitation)
            if c.size and c.max() >= MIN_PEAK_TO_MEDIAN * np.median(c):  # silent periods say nothing
                lag = lo + int(np.argmax(c)) - k * P
                self._lags.append(lag)
                if abs(lag - L) > self.settings.sync_tolerance_samples and self._sync_problem is None:
                    self._sync_problem = (f"sample synchronization lost at stream sample {k * P} (period {k}): the "
                                          f"excitation arrived {lag - L:+d} samples off, samples were dropped or inserted")
            if self.period_tolerance is not None and k > 0 and self._period_problem is None:
                mismatch = period_mismatch(self._mic(start - P, start + P), P, [0, 0])
                if mismatch.size and mismatch[0] > self.period_tolerance:
                    self._period_problem = (f"period {k} differs from the one before by {100 * mismatch[0]:.2g} % RMS "
                                            f"(tolerance {100 * self.period_tolerance:.2g} %): samples were dropped, "
                                            "inserted or corrupted")
            self._checked += 1
