"""The corruption pipeline on a stream (``cadence="stream"``): a stateful
:class:`StreamCorruptor` takes the microphone's samples chunk by chunk and returns exactly
the samples its whole-stream form (:meth:`StreamCorruptor.whole`) gives for the concatenated
stream, whatever the chunk sizes; :class:`CorruptedStream` adds the 140 features of each
complete excitation period of the corrupted stream (what a streamed observation shows).

Streaming semantics of each stage (``sensors.signals.corruption``), ``n`` the stream's
absolute sample index from the corruptor's start:

- every stage draws from its own generator, spawned in stage order from the episode's one:
  with one shared generator a stage's draws would interleave with the others' chunk by chunk;
- ``GainDrift``: gain and slope drawn once, ``t = n / sample_rate_hz``: a continuous drift;
- ``DCOffset``: the offset drawn once: fixed for the episode;
- ``Latency``: the delay drawn once; a delay line carries samples across chunks, the first
  ``delay`` samples are silence, as in the whole-recording stage;
- ``DroppedBuffers``: a fixed buffer grid over ``n``; each buffer's draw made when it starts
  (consecutive ``Generator.random`` calls give the numbers one call would);
- ``Clipping``: stateless;
- ``BackgroundNoise``: the whole-recording stage draws one segment for the recording's length
  (spectral shaping and unit RMS over all of it), which a stream of unknown length cannot. The
  stream is cut into blocks of :data:`NOISE_BLOCK_S` on the ``n`` grid, each block a fresh
  segment of that length as the whole-recording stage draws it (unit RMS per block, each
  block's spectrum as documented in ``sensors.signals.noise_library``).
"""

from __future__ import annotations

import numpy as np

from .corruption import BackgroundNoise, Clipping, CorruptionPipeline, DCOffset, DroppedBuffers, GainDrift, Latency
from .features import spectral_features

__all__ = ["NOISE_BLOCK_S", "CorruptedStream", "StreamCorruptor"]

#: Length [s] of one background-noise block of a stream (module docstring).
NOISE_BLOCK_S = 2.0


class _Gain:
    def __init__(self, stage: GainDrift, fs: float, rng: np.random.Generator) -> None:
        self.fs, self.g0_db = fs, float(rng.normal(0.0, stage.gain_std_db)) if stage.gain_std_db > 0 else 0.0
        self.slope = float(rng.uniform(-stage.drift_db_per_s, stage.drift_db_per_s)) if stage.drift_db_per_s > 0 else 0.0

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        gain_db = self.g0_db + self.slope * np.arange(n0, n0 + x.size) / self.fs
        return x * 10.0 ** (gain_db / 20.0)


class _Offset:
    def __init__(self, stage: DCOffset, fs: float, rng: np.random.Generator) -> None:
        self.offset = stage.offset_fs + (float(rng.normal(0.0, stage.offset_std_fs)) if stage.offset_std_fs > 0 else 0.0)

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        return x + self.offset


class _Delay:
    def __init__(self, stage: Latency, fs: float, rng: np.random.Generator) -> None:
        self.line = np.zeros(stage.delay_samples(fs, rng))  # the samples still in flight

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        if not self.line.size:
            return x.copy()
        joined = np.concatenate([self.line, x])
        self.line = joined[x.size:]
        return joined[:x.size]


class _Drops:
    def __init__(self, stage: DroppedBuffers, fs: float, rng: np.random.Generator) -> None:
        self.B, self.p, self.rng = stage.buffer_samples, stage.probability, rng
        self.dropped = np.zeros(0, bool)  # one draw per buffer started so far

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        needed = -(-(n0 + x.size) // self.B)
        if needed > self.dropped.size:
            self.dropped = np.concatenate([self.dropped, self.rng.random(needed - self.dropped.size) < self.p])
        keep = ~self.dropped[np.arange(n0, n0 + x.size) // self.B]
        return np.where(keep, x, 0.0)


class _Clip:
    def __init__(self, stage: Clipping, fs: float, rng: np.random.Generator) -> None:
        self.fs_ = stage.full_scale

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        return np.clip(x, -self.fs_, self.fs_)


class _Noise:
    def __init__(self, stage: BackgroundNoise, fs: float, rng: np.random.Generator) -> None:
        self.stage, self.fs, self.rng = stage, fs, rng
        self.block = int(round(NOISE_BLOCK_S * fs))
        self.noise = np.zeros(0)   # the current block's samples ...
        self.start = 0             # ... from this absolute index

    def __call__(self, x: np.ndarray, n0: int) -> np.ndarray:
        out = np.empty_like(x)
        k = 0
        while k < x.size:
            n = n0 + k
            if n >= self.start + self.noise.size:  # the next block on the grid
                self.start = n - n % self.block
                self.noise = self.stage.apply(np.zeros(self.block), self.fs, self.rng)
            take = min(x.size - k, self.start + self.noise.size - n)
            out[k:k + take] = x[k:k + take] + self.noise[n - self.start:n - self.start + take]
            k += take
        return out


_STATES = {GainDrift: _Gain, DCOffset: _Offset, Latency: _Delay, DroppedBuffers: _Drops, Clipping: _Clip,
           BackgroundNoise: _Noise}


class StreamCorruptor:
    """``pipeline`` applied to a stream chunk by chunk (module docstring: each stage's streaming
    semantics). ``rng``: the episode's corruption generator; one child per stage is spawned
    from it here, so the same generator state gives the same corrupted stream bit for bit."""

    def __init__(self, pipeline: CorruptionPipeline, sample_rate_hz: float, rng: np.random.Generator) -> None:
        self.pipeline = CorruptionPipeline.coerce(pipeline)
        self.sample_rate_hz = float(sample_rate_hz)
        children = rng.spawn(len(self.pipeline.stages))
        self._states = [_STATES[type(s)](s, self.sample_rate_hz, g) for s, g in zip(self.pipeline.stages, children)]
        self.position = 0  #: samples corrupted so far (the next chunk's absolute index)

    def process(self, chunk: np.ndarray) -> np.ndarray:
        """The corrupted samples (float64) of the stream's next ``chunk``."""
        x = np.array(chunk, dtype=float).ravel()
        for state in self._states:
            x = state(x, self.position)
        self.position += x.size
        return x

    @staticmethod
    def whole(pipeline: CorruptionPipeline, waveform: np.ndarray, sample_rate_hz: float,
              rng: np.random.Generator) -> np.ndarray:
        """The whole-stream form: each stage's whole-recording ``apply`` with its own spawned
        generator, except ``BackgroundNoise``, whose noise is drawn block by block."""
        pipeline = CorruptionPipeline.coerce(pipeline)
        x = np.array(waveform, dtype=float).ravel()
        for stage, g in zip(pipeline.stages, rng.spawn(len(pipeline.stages))):
            x = _Noise(stage, float(sample_rate_hz), g)(x, 0) if isinstance(stage, BackgroundNoise) \
                else stage.apply(x, sample_rate_hz, g)
        return x


class CorruptedStream:
    """A :class:`StreamCorruptor` and the 140 features (``sensors.spectral_features``) of the
    latest complete excitation period of the corrupted stream (samples ``[kP, (k+1)P)`` from
    its start, ``P = period_samples``), as the clean streams' ``latest_features`` give them."""

    def __init__(self, pipeline: CorruptionPipeline, sample_rate_hz: float, rng: np.random.Generator,
                 period_samples: int, period_s: float) -> None:
        self.corruptor = StreamCorruptor(pipeline, sample_rate_hz, rng)
        self.period_s = float(period_s)
        self._window = np.zeros(int(period_samples))
        self._features: np.ndarray | None = None
        self._features_period = -1

    def process(self, chunk: np.ndarray) -> np.ndarray:
        """The corrupted chunk (float64); completes periods' features on the way."""
        start = self.corruptor.position
        out = self.corruptor.process(chunk)
        P, k = self._window.size, 0
        while k < out.size:
            phase = (start + k) % P
            take = min(P - phase, out.size - k)
            self._window[phase:phase + take] = out[k:k + take]
            k += take
            if (start + k) % P == 0:
                self._features = spectral_features(self._window, self.corruptor.sample_rate_hz, period_s=self.period_s)
                self._features_period = (start + k) // P - 1
        return out

    def latest_features(self) -> np.ndarray | None:
        """Features of the latest complete period of the corrupted stream (``None`` before one)."""
        return self._features

    @property
    def latest_features_period(self) -> int:
        """Index k of the period behind :meth:`latest_features` (-1: none yet)."""
        return self._features_period
