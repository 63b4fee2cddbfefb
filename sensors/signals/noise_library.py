"""Background noise for the corruption pipeline: synthesized robot-motor and room noise with
documented spectra, and the user's own recordings (``.wav`` or ``.npz``) from a folder.

Every segment is returned at unit RMS (full scale 1): the caller scales it to a level
(:class:`sensors.signals.corruption.BackgroundNoise`). Synthesized kinds, by their power
spectral density (PSD) over frequency ``f``:

``"white"``
    flat PSD up to Nyquist (the sound card's own floor).
``"pink"``
    PSD proportional to ``1 / f`` (-3 dB per octave) from 20 Hz up.
``"room"``
    pink noise (ventilation, distant speech and traffic) through a second-order low-pass at
    4 kHz: PSD ~ ``1 / f`` below 4 kHz, ~ ``1 / f^5`` (-15 dB per octave) above it, the slope
    of a furnished room's ambient noise beyond the speech band.
``"motor"``
    a robot joint's drive: a harmonic series on a fundamental drawn uniformly in 100-300 Hz
    (commutation), harmonic ``k`` at amplitude ``1 / k`` up to 10 kHz, each with a random
    phase and a slow +-1 % frequency wobble, plus gear and bearing whine: white noise
    band-passed to 2-8 kHz carrying a quarter of the total power.

A folder of recordings (``load_noise_folder``) holds ``.wav`` files (any integer or float
PCM, first channel) and ``.npz`` files with ``waveform`` and ``sample_rate_hz``; each is
resampled to the sensor's rate and normalized to unit RMS. Recordings of the rig's own input
while the robot moves and nothing is played belong there (the project ships none).
"""

from __future__ import annotations

import os
from math import gcd
from pathlib import Path

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU

__all__ = ["NOISE_KINDS", "check_noise_source", "load_noise_folder", "noise_segment", "synthesize_noise"]

#: The synthesized noise kinds (module docstring: their spectra).
NOISE_KINDS = ("white", "pink", "room", "motor")

#: Folders of noise recordings by (resolved path, sample rate): loaded once per process.
_FOLDERS: LRU[tuple[np.ndarray, ...]] = LRU(CACHE_SIZES["signals.noise_folders"])


def _unit_rms(x: np.ndarray) -> np.ndarray:
    rms = float(np.sqrt(np.mean(x * x)))
    if not rms > 0:
        raise ValueError("a noise segment is silent: it cannot be scaled to a level")
    return x / rms


def _shaped(n_samples: int, sample_rate_hz: float, rng: np.random.Generator, gain) -> np.ndarray:
    """White Gaussian noise shaped in the frequency domain by the amplitude ``gain(f_hz)``."""
    spectrum = np.fft.rfft(rng.standard_normal(n_samples))
    f_hz = np.fft.rfftfreq(n_samples, 1.0 / sample_rate_hz)
    return np.fft.irfft(spectrum * gain(f_hz), n_samples)


def _pink_gain(f_hz: np.ndarray) -> np.ndarray:
    return 1.0 / np.sqrt(np.maximum(f_hz, 20.0))


def synthesize_noise(kind: str, n_samples: int, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
    """``n_samples`` of the synthesized noise ``kind`` (:data:`NOISE_KINDS`) at unit RMS."""
    if kind not in NOISE_KINDS:
        raise ValueError(f"noise kind must be one of {NOISE_KINDS} or a folder of recordings, got {kind!r}")
    n_samples = int(n_samples)
    if n_samples < 2:
        raise ValueError(f"a noise segment needs at least 2 samples, got {n_samples}")
    if kind == "white":
        return _unit_rms(rng.standard_normal(n_samples))
    if kind == "pink":
        return _unit_rms(_shaped(n_samples, sample_rate_hz, rng, _pink_gain))
    if kind == "room":
        corner_hz = 4000.0
        return _unit_rms(_shaped(n_samples, sample_rate_hz, rng,
                                 lambda f: _pink_gain(f) / (1.0 + (f / corner_hz) ** 2)))
    # motor: harmonics of a commutation frequency plus band-limited whine
    t_s = np.arange(n_samples) / sample_rate_hz
    f0_hz = float(rng.uniform(100.0, 300.0))
    wobble = 0.01 * np.sin(2 * np.pi * float(rng.uniform(0.5, 3.0)) * t_s + float(rng.uniform(0, 2 * np.pi)))
    phase0 = 2 * np.pi * f0_hz * (t_s + np.cumsum(wobble) / sample_rate_hz)
    n_harmonics = int(min(10_000.0, 0.45 * sample_rate_hz) // f0_hz)
    k = np.arange(1, n_harmonics + 1)
    phases = rng.uniform(0, 2 * np.pi, n_harmonics)
    tonal = (np.sin(np.outer(phase0, k) + phases) / k).sum(axis=1)
    whine = _shaped(n_samples, sample_rate_hz, rng, lambda f: ((f >= 2000.0) & (f <= 8000.0)).astype(float))
    # a quarter of the power in the whine: unit-RMS parts weighted sqrt(3/4) and sqrt(1/4)
    return _unit_rms(np.sqrt(0.75) * _unit_rms(tonal) + 0.5 * _unit_rms(whine))


def _read_recording(path: Path, sample_rate_hz: int) -> np.ndarray:
    if path.suffix.lower() == ".wav":
        from scipy.io import wavfile

        rate, data = wavfile.read(path)
        data = np.asarray(data)
        if data.ndim > 1:
            data = data[:, 0]
        if data.dtype.kind in "iu":
            info = np.iinfo(data.dtype)
            data = (data.astype(float) - (info.max + info.min + 1) / 2) / (info.max + 1 - (info.max + info.min + 1) / 2)
    else:
        with np.load(path) as z:
            if "waveform" not in z or "sample_rate_hz" not in z:
                raise ValueError(f"{path}: a noise .npz needs 'waveform' and 'sample_rate_hz' arrays")
            data, rate = np.asarray(z["waveform"]), int(z["sample_rate_hz"])
    data = np.asarray(data, dtype=float).ravel()
    if not np.all(np.isfinite(data)) or data.size < 2:
        raise ValueError(f"{path}: a noise recording must hold at least 2 finite samples")
    if int(rate) != sample_rate_hz:
        from scipy.signal import resample_poly

        g = gcd(int(rate), sample_rate_hz)
        data = resample_poly(data, sample_rate_hz // g, int(rate) // g)
    try:
        return _unit_rms(data - data.mean())
    except ValueError:
        raise ValueError(f"{path}: the noise recording is silent") from None


def _recording_files(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.suffix.lower() in (".wav", ".npz"))


def check_noise_source(source: str | os.PathLike) -> str:
    """``source`` as :func:`noise_segment` takes it (a noise kind, or a folder path as text),
    checked before any recording is made: ``ValueError`` for a name that is neither a kind of
    :data:`NOISE_KINDS` nor a folder holding a ``.wav`` or ``.npz`` file."""
    if isinstance(source, str) and source in NOISE_KINDS:
        return source
    root = Path(source).expanduser()
    if not root.is_dir():
        raise ValueError(f"noise source must be one of {NOISE_KINDS} or a folder of .wav/.npz recordings; "
                         f"{os.fspath(source)!r} is neither")
    if not _recording_files(root):
        raise ValueError(f"noise folder {os.fspath(source)!r} holds no .wav or .npz recording")
    return os.fspath(source)


def load_noise_folder(folder: str | os.PathLike, sample_rate_hz: int) -> tuple[np.ndarray, ...]:
    """The ``.wav`` and ``.npz`` noise recordings in ``folder`` (sorted by name), each
    resampled to ``sample_rate_hz``, its mean removed, at unit RMS; loaded once per process."""
    root = Path(folder).expanduser().resolve()
    if not root.is_dir():
        raise FileNotFoundError(f"noise folder {folder!s} does not exist")

    def load() -> tuple[np.ndarray, ...]:
        files = _recording_files(root)
        if not files:
            raise ValueError(f"noise folder {root} holds no .wav or .npz recording")
        return tuple(_read_recording(p, int(sample_rate_hz)) for p in files)

    return _FOLDERS.get_or_build((str(root), int(sample_rate_hz)), load)


def noise_segment(source: str | os.PathLike, n_samples: int, sample_rate_hz: int,
                  rng: np.random.Generator) -> np.ndarray:
    """``n_samples`` of background noise at unit RMS: synthesized (``source`` one of
    :data:`NOISE_KINDS`) or cut from a recording of the folder ``source`` (one drawn, from a
    random offset, looped when shorter)."""
    if isinstance(source, str) and source in NOISE_KINDS:
        return synthesize_noise(source, n_samples, sample_rate_hz, rng)
    recordings = load_noise_folder(source, sample_rate_hz)
    rec = recordings[int(rng.integers(len(recordings)))]
    start = int(rng.integers(rec.size))
    idx = (start + np.arange(int(n_samples))) % rec.size
    return _unit_rms(rec[idx])
