"""Time-frequency observations of a recording: an amplitude spectrogram and a mel
spectrogram over the paper's band (3-10 kHz), with fixed shapes for a given length.

Both use scipy.signal's STFT: Hann windows of :data:`N_FFT` samples (23 ms at 44.1 kHz),
hop :data:`HOP_SAMPLES` (half a window), no padding, so ``n_samples`` give
``1 + (n_samples - N_FFT) // HOP_SAMPLES`` frames (85 for 1 s at 44.1 kHz). Amplitudes are
scaled so that a sine of amplitude A centred on a bin reads A (as the 140 features).

- spectrogram: the STFT bins whose frequency lies in [3000, 10000) Hz
  (:func:`spectrogram_frequencies_hz`; 163 bins of 43.07 Hz at 44.1 kHz).
- mel: :data:`N_MELS` triangular filters on that spectrogram, their centres equally spaced
  on the HTK mel scale ``mel = 2595 log10(1 + f / 700)`` between 3000 and 10000 Hz
  (:func:`mel_frequencies_hz`), each weighting the STFT amplitudes with a peak of 1 (no
  area normalization, as HTK).
"""

from __future__ import annotations

import numpy as np

from .features import DEFAULT_F_MAX_HZ, DEFAULT_F_MIN_HZ

__all__ = ["HOP_SAMPLES", "N_FFT", "N_MELS", "hz_to_mel", "mel_filterbank", "mel_frequencies_hz", "mel_to_hz",
           "mel_spectrogram", "n_frames", "spectrogram", "spectrogram_frequencies_hz"]

#: STFT window length [samples].
N_FFT = 1024
#: STFT hop [samples].
HOP_SAMPLES = 512
#: Mel bands.
N_MELS = 64


def hz_to_mel(f_hz):
    """HTK mel scale: ``2595 log10(1 + f / 700)``."""
    return 2595.0 * np.log10(1.0 + np.asarray(f_hz, dtype=float) / 700.0)


def mel_to_hz(mel):
    """Inverse of :func:`hz_to_mel`."""
    return 700.0 * (10.0 ** (np.asarray(mel, dtype=float) / 2595.0) - 1.0)


def n_frames(n_samples: int) -> int:
    """STFT frames of a recording of ``n_samples`` (at least one window)."""
    if n_samples < N_FFT:
        raise ValueError(f"a spectrogram needs at least {N_FFT} samples, got {n_samples}")
    return 1 + (int(n_samples) - N_FFT) // HOP_SAMPLES


def _stft_frequencies_hz(sample_rate_hz: float) -> np.ndarray:
    return np.fft.rfftfreq(N_FFT, 1.0 / sample_rate_hz)


def _band(sample_rate_hz: float) -> np.ndarray:
    f = _stft_frequencies_hz(sample_rate_hz)
    return (f >= DEFAULT_F_MIN_HZ) & (f < DEFAULT_F_MAX_HZ)


def spectrogram_frequencies_hz(sample_rate_hz: float = 44100) -> np.ndarray:
    """The spectrogram's frequency axis [Hz]: STFT bins in [3000, 10000) Hz."""
    return _stft_frequencies_hz(sample_rate_hz)[_band(sample_rate_hz)]


def _amplitude_stft(waveform: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """(frames, N_FFT // 2 + 1) amplitudes, a centred sine of amplitude A reading A."""
    from scipy.signal import stft  # first use only (scipy.signal is slow to import)

    x = np.asarray(waveform, dtype=float)
    n_frames(x.size)
    # scaling="spectrum" divides by the window's sum: a sine of amplitude A reads A / 2.
    _, _, z = stft(x, fs=sample_rate_hz, window="hann", nperseg=N_FFT, noverlap=N_FFT - HOP_SAMPLES,
                   boundary=None, padded=False, scaling="spectrum")
    return 2.0 * np.abs(z).T


def spectrogram(waveform: np.ndarray, sample_rate_hz: float = 44100) -> np.ndarray:
    """Amplitude spectrogram in the band, shape ``(n_frames(n), len(spectrogram_frequencies_hz))``
    (time first)."""
    return _amplitude_stft(waveform, sample_rate_hz)[:, _band(sample_rate_hz)]


def mel_frequencies_hz(n_mels: int = N_MELS, f_min_hz: float = DEFAULT_F_MIN_HZ,
                       f_max_hz: float = DEFAULT_F_MAX_HZ) -> np.ndarray:
    """Centre frequencies [Hz] of the mel filters (their axis in the observation)."""
    return mel_to_hz(np.linspace(hz_to_mel(f_min_hz), hz_to_mel(f_max_hz), n_mels + 2)[1:-1])


def mel_filterbank(sample_rate_hz: float = 44100, n_mels: int = N_MELS, f_min_hz: float = DEFAULT_F_MIN_HZ,
                   f_max_hz: float = DEFAULT_F_MAX_HZ, n_fft: int = N_FFT) -> np.ndarray:
    """Triangular filters ``(n_mels, n_fft // 2 + 1)`` on the rfft bins: filter ``m`` rises
    linearly in Hz from edge ``m`` to its centre (weight 1) and falls to edge ``m + 2``, the
    ``n_mels + 2`` edges equally spaced in HTK mel from ``f_min_hz`` to ``f_max_hz``."""
    if not 0 <= f_min_hz < f_max_hz <= sample_rate_hz / 2:
        raise ValueError(f"need 0 <= f_min_hz < f_max_hz <= Nyquist, got {f_min_hz}, {f_max_hz} at {sample_rate_hz} Hz")
    edges = mel_to_hz(np.linspace(hz_to_mel(f_min_hz), hz_to_mel(f_max_hz), n_mels + 2))
    f = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
    lower, centre, upper = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    rising = (f - lower) / (centre - lower)
    falling = (upper - f) / (upper - centre)
    return np.maximum(0.0, np.minimum(rising, falling))


def mel_spectrogram(waveform: np.ndarray, sample_rate_hz: float = 44100) -> np.ndarray:
    """Mel amplitude spectrogram, shape ``(n_frames(n), N_MELS)`` (time first)."""
    return _amplitude_stft(waveform, sample_rate_hz) @ mel_filterbank(sample_rate_hz).T
