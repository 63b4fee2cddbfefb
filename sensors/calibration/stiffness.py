"""Young's modulus from matched modal frequencies (every frequency scales with sqrt(E))."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.optimize

from .estimation import ModalEstimate


@dataclass
class StiffnessFit:
    """Result of :func:`fit_stiffness`.

    Attributes:
        scale: frequency scale s = sqrt(E / E_base).
        scale_std: its standard deviation.
        matches: per recording, ``(measured index, cluster index)`` pairs.
        n_measured: measured modes offered per recording.
        rms_log_misfit: RMS of log(f_measured / (s f_model)) over matched pairs.
    """

    scale: float
    scale_std: float
    matches: list[list[tuple[int, int]]]
    n_measured: list[int]
    rms_log_misfit: float

    @property
    def youngs_modulus_factor(self) -> float:
        """E / E_base = s^2."""
        return self.scale**2

    @property
    def youngs_modulus_factor_std(self) -> float:
        """Standard deviation of E / E_base (2 s std(s))."""
        return 2 * self.scale * self.scale_std

    @property
    def n_matched(self) -> int:
        return sum(len(m) for m in self.matches)


def match_modes(log_f: np.ndarray, log_c: np.ndarray, sizes: np.ndarray, log_s: float, tol: float,
           log_sigma: np.ndarray | None = None, log_sigma_prior: np.ndarray | None = None) -> list[tuple[int, int]]:
    """One-to-one assignment of measured modes to clusters (a cluster of n modes takes up to
    n measured modes) minimising the log-frequency distance, pairs farther than 3 tol dropped.

    With decay rates and a prior decay rate per cluster, a decay far from the prior costs a
    little too: between two measured modes equally close in frequency (an object mode and a
    heavily damped fingertip resonance) the plausible one wins.
    """
    if log_f.size == 0 or log_c.size == 0:
        return []
    cols = np.repeat(np.arange(log_c.size), sizes)
    d = np.abs(log_f[:, None] - (log_s + log_c[cols])[None, :])
    big = 1e6
    cost = np.where(d <= 3 * tol, (d / tol) ** 2, big)
    if log_sigma is not None and log_sigma_prior is not None:
        # a factor 3 from the table's damping costs as much as one tolerance in frequency
        extra = ((log_sigma[:, None] - log_sigma_prior[cols][None, :]) / math.log(3.0)) ** 2
        cost = np.where(cost < big, cost + extra, big)
    rows, cc = scipy.optimize.linear_sum_assignment(cost)
    return [(int(r), int(cols[c])) for r, c in zip(rows, cc) if cost[r, c] < big]


def undamped_frequencies_hz(estimate: ModalEstimate) -> np.ndarray:
    """Undamped natural frequencies |s| / 2 pi = sqrt(f_d^2 + (sigma / 2 pi)^2) [Hz] of
    estimated modes (exact for a viscously damped single mode)."""
    f = np.asarray(estimate.frequencies_hz, float)
    return np.sqrt(f**2 + (np.asarray(estimate.decay_rates_per_s, float) / (2 * np.pi)) ** 2)


def log_decay_terms(est: ModalEstimate, priors: Sequence[np.ndarray] | None, k: int):
    """Log decay rates [log 1/s] of the measured modes and of recording ``k``\'s prior per cluster,
    the last two arguments of :func:`match_modes`; (None, None) without priors."""
    if priors is None:
        return None, None
    with np.errstate(divide="ignore"):
        return np.log(np.maximum(est.decay_rates_per_s, 1e-9)), np.log(np.maximum(np.asarray(priors[k], float), 1e-9))


def fit_stiffness(
    measured: Sequence[ModalEstimate],
    cluster_frequencies_hz: Sequence[np.ndarray],
    cluster_sizes: Sequence[np.ndarray] | None = None,
    *,
    factor_range: tuple[float, float] = (1 / 3, 3.0),
    rel_tol: float = 0.01,
    cluster_decay_priors: Sequence[np.ndarray] | None = None,
) -> StiffnessFit:
    """Frequency scale s = sqrt(E / E_base) from measured modes of one or more recordings.

    Args:
        measured: one modal estimate per recording.
        cluster_frequencies_hz: per recording, the model's observable mode (cluster)
            frequencies at E_base [Hz].
        cluster_sizes: modes per cluster (default 1).
        factor_range: search range of E / E_base.
        rel_tol: relative frequency tolerance of a match (the model's own accuracy).
        cluster_decay_priors: per recording, an expected decay rate per cluster [1/s] (the
            base material's); breaks ties between measured modes close in frequency.

    The score of a scale is the number of measured modes that have a model mode within
    ``rel_tol`` (Gaussian-weighted), summed over recordings: missing modes (nodes, outside
    the band) and extra ones (fingertip, leak) lower the score of every scale alike.
    """
    if len(measured) != len(cluster_frequencies_hz):
        raise ValueError("one list of model frequencies per modal estimate")
    if cluster_sizes is None:
        cluster_sizes = [np.ones(len(c), int) for c in cluster_frequencies_hz]
    # compare undamped natural frequencies: a mode decaying at sigma rings at
    # w_d = sqrt(w0^2 - sigma^2), 0.1-0.5 % below w0 for wood
    log_fs = [np.log(undamped_frequencies_hz(m)) for m in measured]
    log_cs = [np.log(np.asarray(c, float)) for c in cluster_frequencies_hz]
    lo, hi = 0.5 * math.log(factor_range[0]), 0.5 * math.log(factor_range[1])
    grid = np.arange(lo, hi + rel_tol / 8, rel_tol / 8)
    coarse_tol = 2 * rel_tol
    score = np.zeros(grid.size)
    for lf, lc in zip(log_fs, log_cs):
        if lf.size == 0 or lc.size == 0:
            continue
        d = lf[None, :, None] - grid[:, None, None] - lc[None, None, :]
        score += np.exp(-0.5 * (d / coarse_tol) ** 2).max(axis=2).sum(axis=1)
    if not np.any(score > 0):
        raise ValueError("no measured modes to match")
    log_s = float(grid[np.argmax(score)])
    for tol in (coarse_tol, rel_tol, rel_tol):
        matches = [match_modes(lf, lc, np.asarray(sz), log_s, tol, *log_decay_terms(est, cluster_decay_priors, k))
                   for k, (lf, lc, sz, est) in enumerate(zip(log_fs, log_cs, cluster_sizes, measured))]
        ratios, weights = [], []
        for m, lf, lc, est in zip(matches, log_fs, log_cs, measured):
            for i, c in m:
                ratios.append(lf[i] - lc[c])
                # relative frequency error: measurement std plus the tolerance as model error
                rel_sd = math.hypot(est.frequency_std_hz[i] / est.frequencies_hz[i], 0.25 * rel_tol)
                weights.append(1.0 / rel_sd**2)
        if not ratios:
            raise ValueError("no measured mode matches a model mode at the best scale")
        ratios_a, w = np.asarray(ratios), np.asarray(weights)
        log_s = float(np.sum(w * ratios_a) / np.sum(w))
    resid = ratios_a - log_s
    n = ratios_a.size
    # standard error of the weighted mean, inflated by the scatter when it exceeds the weights
    chi2 = float(np.sum(w * resid**2) / max(n - 1, 1))
    log_s_std = math.sqrt(max(chi2, 1.0) / np.sum(w))
    s = math.exp(log_s)
    return StiffnessFit(s, s * log_s_std, matches, [lf.size for lf in log_fs], float(np.sqrt(np.mean(resid**2))))
