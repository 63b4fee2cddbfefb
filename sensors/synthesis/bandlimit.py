"""How far the time-domain (first-order-hold) evaluation is from the band-limited signal a sound
card plays, and the one-shot version of the band-limited prefilter.

The band-limited drive (``sensors.synthesis.drive``) hands each first-order-hold (FOH)
discretisation samples prefiltered by 1 / S(f), S = sinc^2(f / fs) (``lti.hold_gain``): the
hold's piecewise-linear interpolant then has the band-limited signal as its baseband.  What
remains are the interpolant's images at f + k fs (k != 0), which the continuous system filters
and the sampling folds back onto f.  For an LTI system with transfer function H the sampled
output at a frequency f in band is therefore off by exactly

    e(f) = | sum_{k != 0} H(f + k fs) S(f + k fs) | / | H(f) S(f) |          (:func:`image_error`)

relative to the band-limited truth (a cascade of two holds: the two errors add to first
order).  The periodic steady states are evaluated per harmonic instead and carry no such
error; the time-domain runs (transients: a grasp starting, contacts changing) do.  Across the
feature band (3-10 kHz, 50 Hz steps) e(f) is 7e-5 to 1.8e-2 (median 2.6e-3) for the default
fingertip and 1e-5 to 3e-2 (median 7e-4) for the 200 x 20 x 20 mm steel and aluminium bars
held at 40 N (their worst bins lie between modes, where the response itself is weakest);
``tests/test_bandlimited_drive.py`` checks the bound against the exact steady state.  A
stream leaving its time-domain runs for the exact steady state (after the transient has
decayed by ``SETTLE_E_FOLDS`` e-folds) therefore changes by at most that much, and where that
switch falls depends on how the stream is chunked: a streamed and a batch recording of the
same grasp agree to a few 1e-4 of the peak, no longer to rounding.

For a signal that does not loop (a one-shot force handed to ``sensors.modal_response``), the
prefilter cannot be circular: :func:`oneshot_bandlimited_samples` applies a zero-phase FIR of
49 taps, fitted by least squares to 1 / S^passes over 0 .. 0.45 fs.  Its response is within
9e-6 (one pass) and 2.1e-5 (two passes) of 1 / S^passes there (relative, per frequency;
``tests/test_bandlimited_drive.py`` checks it on a one-shot signal); above 0.45 fs, where
1 / S^passes rises to 2.5 (one pass), it is not controlled.  The response of a system to such
samples is then off from the band-limited one by that plus e(f).
"""

from __future__ import annotations

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from .lti import DiscreteSystem, force_signal, hold_gain

__all__ = ["image_error", "oneshot_bandlimited_samples", "oneshot_prefilter_taps"]

#: Half length of the one-shot prefilter (taps on each side of the centre).
ONESHOT_HALF_TAPS = 24
#: The band over which the one-shot prefilter is fitted, as a fraction of the sample rate.
ONESHOT_BAND = 0.45

_TAPS: LRU = LRU(CACHE_SIZES["synthesis.prefilter_taps"])


def image_error(system: DiscreteSystem, freq_hz, n_images: int = 32) -> np.ndarray:
    """e(f) of the module docstring: the relative error at ``freq_hz`` [Hz] (in band) of the
    first-order-hold evaluation of ``system`` on prefiltered samples against its response to
    the band-limited signal (images k = -n_images .. n_images)."""
    f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
    fs = system.sample_rate_hz
    k = np.array([j for j in range(-n_images, n_images + 1) if j != 0], dtype=float)
    fi = (f[:, None] + k[None, :] * fs).ravel()
    images = (system.frequency_response(fi) * hold_gain(fi, fs, system.hold)).reshape(len(f), len(k)).sum(axis=1)
    base = system.frequency_response(f) * hold_gain(f, fs, system.hold)
    return np.abs(images) / np.abs(base)


def oneshot_prefilter_taps(passes: int = 1, half_taps: int = ONESHOT_HALF_TAPS) -> np.ndarray:
    """The symmetric FIR (2 half_taps + 1 taps) whose response is 1 / sinc^(2 passes)(f/fs)
    over 0 .. ``ONESHOT_BAND`` fs in the least-squares sense."""
    def fit():
        f = np.linspace(0.0, ONESHOT_BAND, 2000)
        target = 1.0 / np.sinc(f) ** (2 * int(passes))
        k = np.arange(half_taps + 1)
        M = np.cos(2 * np.pi * f[:, None] * k[None, :]) * np.where(k == 0, 1.0, 2.0)
        c = np.linalg.lstsq(M, target, rcond=None)[0]
        taps = np.concatenate([c[:0:-1], c])
        taps.setflags(write=False)
        return taps
    return _TAPS.get_or_build((int(passes), int(half_taps)), fit)


def oneshot_bandlimited_samples(signal, passes: int = 1) -> np.ndarray:
    """``signal`` (a one-shot, zero before and after) prefiltered for ``passes`` first-order
    holds by the zero-phase FIR :func:`oneshot_prefilter_taps` (same length; the filter looks
    ``ONESHOT_HALF_TAPS`` samples ahead, which a one-shot array allows)."""
    u = force_signal(signal)
    taps = oneshot_prefilter_taps(passes)
    return np.convolve(u, taps, mode="same")
