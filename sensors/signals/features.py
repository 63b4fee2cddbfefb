"""From a recording to the paper's spectral feature vector.

A recording is cut into windows of one excitation period (0.5 s), aligned to the start of
the excitation (``start_s`` absorbs the playback/recording latency). Each window's amplitude
spectrum is evaluated exactly at the feature frequencies 3000, 3050, ..., 9950 Hz (140
values): with a 0.5 s window at 44.1 kHz these are FFT bins; for any other window length the
discrete-time Fourier transform is evaluated at those frequencies (chirp-z), so there is no
interpolation error. The amplitude is scaled so that a sine of amplitude A at a feature
frequency reads A.
"""

from __future__ import annotations

import math

import numpy as np

from .._infra.checks import real_number
from .._infra.deprecation import renamed_keywords

DEFAULT_F_MIN_HZ = 3000.0
DEFAULT_F_MAX_HZ = 10000.0
DEFAULT_STEP_HZ = 50.0

#: How feature amplitudes are presented to a learner (see :func:`scale_features`).
FEATURE_SCALES = ("linear", "db", "normalized")
#: 0 dB of the ``"db"`` scale, in waveform units (full scale 1): about the amplitude of one
#: feature bin of white noise of std 1e-4 over a 0.5 s window, so sensed peaks read tens of dB.
DB_REFERENCE = 1e-6
#: Amplitudes below this read as this (-60 dB): silence and all-zero observations stay finite.
DB_FLOOR = 1e-9


#: Most features one vector may have (the paper's has 140); bounds the spectrum's memory.
MAX_FEATURES = 100_000


def feature_frequencies_hz(
    f_min_hz: float = DEFAULT_F_MIN_HZ, f_max_hz: float = DEFAULT_F_MAX_HZ, step_hz: float = DEFAULT_STEP_HZ
) -> np.ndarray:
    """Centre frequencies of the features: ``f_min_hz`` up to (excluding) ``f_max_hz``."""
    for name, value in (("f_min_hz", f_min_hz), ("f_max_hz", f_max_hz), ("step_hz", step_hz)):
        real_number(value, name)
    if step_hz <= 0:
        raise ValueError(f"step_hz must be positive, got {step_hz}")
    if not 0 <= f_min_hz < f_max_hz:
        raise ValueError(f"need 0 <= f_min_hz < f_max_hz, got f_min_hz={f_min_hz}, f_max_hz={f_max_hz}")
    n_float = (f_max_hz - f_min_hz) / step_hz
    if not n_float <= MAX_FEATURES:
        raise ValueError(f"the band {f_min_hz:g}..{f_max_hz:g} Hz in steps of {step_hz:g} Hz is {n_float:.3g} "
                         f"features, above the limit of {MAX_FEATURES:,}: take a larger step_hz or a narrower band")
    n = int(round(n_float))
    if not math.isclose(n * step_hz, f_max_hz - f_min_hz, rel_tol=1e-9):
        raise ValueError(f"(f_max_hz - f_min_hz) = {f_max_hz - f_min_hz} Hz is not a multiple of step_hz = {step_hz} Hz")
    return f_min_hz + step_hz * np.arange(n)


def validate_waveform(waveform: np.ndarray, name: str = "waveform") -> np.ndarray:
    """``waveform`` as a 1-D float array; TypeError or ValueError naming ``name`` if it is not real,
    not one channel, empty or not finite."""
    x = np.asarray(waveform)
    if x.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be a real numeric array, got dtype {x.dtype}")
    x = x.astype(float, copy=False)
    if x.ndim != 1:
        raise ValueError(f"{name} must be 1-D (one channel), got shape {x.shape}")
    if x.size == 0:
        raise ValueError(f"{name} is empty")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or infinite samples")
    return x


def _validate_fs(sample_rate_hz: float, f_needed_hz: float) -> float:
    sample_rate_hz = real_number(sample_rate_hz, "sample_rate_hz")
    if sample_rate_hz <= 0:
        raise ValueError(f"sample_rate_hz must be a positive sample rate in Hz, got {sample_rate_hz!r}")
    if f_needed_hz >= sample_rate_hz / 2:
        raise ValueError(
            f"sample_rate_hz={sample_rate_hz:g} Hz is too low for the feature band: f_max_hz reaches {f_needed_hz:g} Hz, "
            f"above the Nyquist frequency {sample_rate_hz / 2:g} Hz"
        )
    return sample_rate_hz


@renamed_keywords({"fs": "sample_rate_hz"})
def segment(waveform: np.ndarray, sample_rate_hz: float, period_s: float = 0.5, start_s: float = 0.0) -> np.ndarray:
    """Windows of one excitation period, shape ``(n_windows, window_samples)``.

    ``start_s`` is where the first excitation period begins in the recording (latency).
    Incomplete trailing windows are dropped.
    """
    x = validate_waveform(waveform)
    sample_rate_hz = real_number(sample_rate_hz, "sample_rate_hz", above=0.0)
    if real_number(period_s, "period_s") <= 0:
        raise ValueError(f"period_s must be a positive duration, got {period_s!r}")
    real_number(start_s, "start_s", minimum=0.0)
    if not (period_s + start_s) * sample_rate_hz <= x.size + 1:  # floats: 1e308 s must not reach int()
        raise ValueError(
            f"recording too short: {x.size} samples ({x.size / sample_rate_hz:.4g} s) from start_s={start_s} s "
            f"hold no complete window of period_s={period_s} s")
    length = int(round(period_s * sample_rate_hz))
    start = int(round(start_s * sample_rate_hz))
    if length < 2:
        raise ValueError(f"period_s={period_s} s is shorter than two samples at sample_rate_hz={sample_rate_hz:g} Hz")
    n_windows = (x.size - start) // length if x.size > start else 0
    if n_windows < 1:
        raise ValueError(
            f"recording too short: {x.size} samples ({x.size / sample_rate_hz:.4g} s) from start_s={start_s} s "
            f"hold no complete window of period_s={period_s} s ({length} samples)"
        )
    return x[start:start + n_windows * length].reshape(n_windows, length)


def _amplitude_at(windows: np.ndarray, sample_rate_hz: float, freqs_hz: np.ndarray) -> np.ndarray:
    """|DTFT| of each window at ``freqs_hz`` (equally spaced), scaled to sine amplitude."""
    length = windows.shape[1]
    bins = freqs_hz * length / sample_rate_hz
    if np.allclose(bins, np.round(bins), rtol=0, atol=1e-9):
        spectrum = np.fft.rfft(windows, axis=1)[:, np.round(bins).astype(int)]
    elif freqs_hz.size == 1:
        n = np.arange(length)
        spectrum = windows @ np.exp(-2j * np.pi * freqs_hz[0] * n / sample_rate_hz)[:, None]
    else:
        from scipy.signal import zoom_fft  # ~0.5 s to import (-X importtime): first use only

        step = freqs_hz[1] - freqs_hz[0]
        spectrum = zoom_fft(windows, [freqs_hz[0], freqs_hz[-1] + step], m=freqs_hz.size, fs=sample_rate_hz, endpoint=False, axis=1)
    return 2.0 * np.abs(spectrum) / length


@renamed_keywords({"fs": "sample_rate_hz"})
def spectral_features(
    waveform: np.ndarray,
    sample_rate_hz: float = 44100,
    *,
    period_s: float = 0.5,
    start_s: float = 0.0,
    f_min_hz: float = DEFAULT_F_MIN_HZ,
    f_max_hz: float = DEFAULT_F_MAX_HZ,
    step_hz: float = DEFAULT_STEP_HZ,
    average: bool = True,
) -> np.ndarray:
    """The paper's feature vector: FFT amplitude at 3000, 3050, ..., 9950 Hz.

    Args:
        waveform: one-channel recording.
        sample_rate_hz: its sample rate in Hz.
        period_s: excitation period = window length, seconds.
        start_s: where the first excitation period starts in the recording, seconds.
        f_min_hz, f_max_hz, step_hz: feature band (``f_max_hz`` excluded) and spacing.
        average: mean amplitude over windows (shape ``(n_features,)``); otherwise one row
            per window (shape ``(n_windows, n_features)``).
    """
    if not isinstance(average, (bool, np.bool_)):
        raise TypeError(f"average must be True or False, got {average!r}")
    freqs = feature_frequencies_hz(f_min_hz, f_max_hz, step_hz)
    sample_rate_hz = _validate_fs(sample_rate_hz, freqs[-1])
    windows = segment(waveform, sample_rate_hz, period_s, start_s)
    amplitude = _amplitude_at(windows, sample_rate_hz, freqs)
    if not np.all(np.isfinite(amplitude)):
        raise ValueError("waveform too large for the spectrum (it overflowed to inf/NaN): scale it to full scale 1")
    return amplitude.mean(axis=0) if average else amplitude


def scale_features(amplitude: np.ndarray, scale: str = "linear") -> np.ndarray:
    """Feature amplitudes on a scale a learner can use next to proprioception of order 1.

    ``"linear"``: the amplitudes as they are (1e-7 to 1e-4 in simulation).
    ``"db"``: ``20 log10(max(A, DB_FLOOR) / DB_REFERENCE)``, level relative to 1e-6 (tens of
    dB for a sensed grasp, -60 dB for silence): keeps the absolute level, which carries the
    material's damping.
    ``"normalized"``: each vector divided by its Euclidean norm (all-zero stays zero): the
    spectral shape only, blind to gain differences between rigs.
    Works on one vector or on rows (last axis = features).
    """
    a = np.asarray(amplitude, dtype=float)
    if scale == "linear":
        return a
    if scale == "db":
        return 20.0 * np.log10(np.maximum(a, DB_FLOOR) / DB_REFERENCE)
    if scale == "normalized":
        norm = np.linalg.norm(a, axis=-1, keepdims=True)
        return np.divide(a, norm, out=np.zeros_like(a), where=norm > 0)
    raise ValueError(f"feature scale must be one of {FEATURE_SCALES}, got {scale!r}")


@renamed_keywords({"fs": "sample_rate_hz"})
def amplitude_spectrum(
    waveform: np.ndarray, sample_rate_hz: float = 44100, *, period_s: float = 0.5, start_s: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Full-resolution amplitude spectrum averaged over windows: ``(frequencies_hz, amplitude)``."""
    sample_rate_hz = _validate_fs(sample_rate_hz, 0.0)
    windows = segment(waveform, sample_rate_hz, period_s, start_s)
    amplitude = 2.0 * np.abs(np.fft.rfft(windows, axis=1)).mean(axis=0) / windows.shape[1]
    return np.fft.rfftfreq(windows.shape[1], 1.0 / sample_rate_hz), amplitude


def smooth_spectrum(amplitude: np.ndarray, window_length: int = 51, polyorder: int = 3) -> np.ndarray:
    """Savitzky-Golay smoothed spectrum, as in the paper's figure (for plots)."""
    a = np.asarray(amplitude, dtype=float)
    window_length = min(window_length, a.shape[-1] - (1 - a.shape[-1] % 2))
    if window_length <= polyorder:
        return a.copy()
    from scipy.signal import savgol_filter  # ~0.5 s to import (-X importtime): first use only

    return savgol_filter(a, window_length, polyorder, axis=-1)
