"""Round-trip latency and synchronization from a recording of a looping excitation.

The rig plays the excitation from its first sample when the output starts; the recording
holds silence (or noise) until the first period arrives ``latency`` samples later, then the
excitation repeats every period. The matched filter (cross-correlation with one period)
peaks at ``latency + k * period``: the first significant peak is the latency, and the
spacing of the following peaks shows whether the stream stayed sample-synchronized
(a dropped or inserted sample moves every later peak).
"""

from __future__ import annotations

import numpy as np

from sensors import Excitation

# A matched-filter peak of noise alone is a few times its median (Gaussian maximum over
# ~1e5 lags ~ 4.5 sigma, median 0.67 sigma); a played excitation is orders above.
MIN_PEAK_TO_MEDIAN = 12.0


def excitation_correlation(recording: np.ndarray, excitation: Excitation) -> np.ndarray:
    """|cross-correlation| of ``recording`` with one excitation period, one value per lag
    0 .. len(recording) - period (polarity does not matter: a rig may invert)."""
    x = np.asarray(recording, dtype=float)
    e = excitation.signal
    if x.ndim != 1:
        raise ValueError(f"recording must be one channel, got shape {x.shape}")
    if x.size < e.size:
        return np.zeros(0)
    from scipy.signal import correlate  # ~0.4 s to import (-X importtime): first use only

    return np.abs(correlate(x, e, mode="valid", method="fft"))


def find_latency(recording: np.ndarray, excitation: Excitation, *, threshold: float = 0.5,
                 min_peak_to_median: float = MIN_PEAK_TO_MEDIAN, complete_ratio: float = 0.9) -> int | None:
    """Samples from the start of ``recording`` to the first complete excitation period, or
    ``None`` if no excitation stands out of the recording.

    The first lag whose matched-filter output reaches ``threshold`` times the largest one
    starts the search; the latency is the peak within half a period after it, moved on by
    whole periods while its peak is below ``complete_ratio`` times the next period's.
    """
    c = excitation_correlation(recording, excitation)
    if c.size == 0:
        return None
    peak = float(c.max())
    if peak <= 0.0 or peak < min_peak_to_median * float(np.median(c)):
        return None
    first = int(np.argmax(c >= threshold * peak))
    P = excitation.period_samples
    half = max(1, P // 2)
    lag = first + int(np.argmax(c[first:first + half]))
    # A first period damaged at the stream start (a device dropping the first buffer)
    # matches less well than the next one: align to the first period as good as its successor.
    while lag + P < c.size:
        lo, hi = lag + P - 2, min(c.size, lag + P + 3)
        if c[lag] >= complete_ratio * float(c[lo:hi].max()):
            break
        lag = lo + int(np.argmax(c[lo:hi]))
    return lag


def period_lags(recording: np.ndarray, excitation: Excitation, latency_samples: int,
                search_samples: int | None = None) -> np.ndarray:
    """Latency measured on each complete period after the first arrival (samples).

    Equal values mean the stream stayed sample-synchronized; their spread is the drift.
    ``search_samples`` bounds the search around each expected peak (default a quarter period).
    """
    c = excitation_correlation(recording, excitation)
    P = excitation.period_samples
    w = search_samples if search_samples is not None else max(1, P // 4)
    lags = []
    k = 0
    while latency_samples + k * P < c.size:
        centre = latency_samples + k * P
        lo, hi = max(0, centre - w), min(c.size, centre + w + 1)
        lags.append(lo + int(np.argmax(c[lo:hi])) - k * P)
        k += 1
    return np.asarray(lags, dtype=int)


def period_mismatch(recording: np.ndarray, period_samples: int, lags) -> np.ndarray:
    """Relative RMS difference of each complete aligned period from the one before it
    (one value per period after the first).

    A looped excitation through a linear, time-invariant path (a loopback, a held object in
    its steady state) records the same samples every period; dropped, inserted or corrupted
    samples that leave the latency unchanged (e.g. a block lost and one repeated in the same
    period) show here and not in the lags. ``lags``: :func:`period_lags` (period k starts at
    sample ``lags[k] + k * period_samples``)."""
    x = np.asarray(recording, dtype=float)
    P = int(period_samples)
    periods = [x[int(lag) + k * P:int(lag) + (k + 1) * P] for k, lag in enumerate(lags)]
    periods = [p for p in periods if p.size == P]
    out = []
    for a, b in zip(periods, periods[1:]):
        ref = max(float(np.sqrt(np.mean(a * a))), float(np.sqrt(np.mean(b * b))), 1e-12)
        out.append(float(np.sqrt(np.mean((b - a) ** 2))) / ref)
    return np.asarray(out)
