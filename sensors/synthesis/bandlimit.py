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
error; the time-domain runs (transients: a grasp starting, contacts changing) do.  For the
project's objects and fingertip e(f) is 1e-4 to 1e-2 across 3-10 kHz (the images fall on the
mass line of the modes, 10-30 dB below the band); ``tests/test_bandlimited_drive.py`` checks
the bound against the exact steady state.  A stream leaving its time-domain runs for the exact
steady state therefore changes by at most that much.

For a signal that does not loop (a one-shot force handed to ``sensors.modal_response``), the
prefilter cannot be circular: :func:`oneshot_bandlimited_samples` applies a zero-phase FIR,
fitted by least squares to 1 / S^passes over 0 .. 0.45 fs.  Its own error there is below
1e-3 (passes=1) of the signal's largest harmonic (measured in the tests); above 0.45 fs, where
1 / S^passes rises to 2.5 (one pass), it is not controlled.
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
