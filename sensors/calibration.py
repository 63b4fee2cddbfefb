"""Calibrate a material (stiffness and damping) from recordings of a grasped object.

What is fitted, and from what:

- **Young's modulus**: with geometry, density and Poisson's ratio fixed, the stiffness matrix
  is proportional to E and the mass matrix does not depend on it, so every modal frequency
  scales with sqrt(E) and the mass-normalised mode shapes do not change. The scale
  ``s = sqrt(E / E_base)`` is found by matching measured frequencies to the model's
  observable modes with a robust score (missing and extra modes cost nothing but a lost
  vote), then refined by a weighted mean of log frequency ratios over the matched pairs.
- **Rayleigh alpha, beta and contact gamma** in one weighted linear least squares: a
  measured mode matched to model mode (or cluster of near-repeated modes) ``c`` in a
  recording with contacts P obeys, to first order in the damping,
  ``sigma = (alpha + beta w^2 + gamma G_cc) / 2`` with ``G = sum_p c_p U_p^T (mu I +
  (1 - mu) n n^T) U_p`` the contact damping per unit gamma of that recording's contacts
  (:func:`sensors.damping.contact_damping_matrix`). gamma is identifiable when the
  recordings differ in grip force or contact set; otherwise it is held at the base value.
  Weights come from each decay rate's standard deviation plus a relative floor for model
  error; uncertainties from the covariance (scaled by the reduced chi-square when the
  scatter exceeds the error bars) and from a bootstrap over modes.

The calibrated :class:`sensors.Material` is written as JSON by :func:`save_material` and read
back by :func:`load_material`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.optimize

from .atomic import atomic_write_text
from .contact import Contact
from .damping import contact_damping_matrix
from .materials import Material, get_material
from .modal_estimation import ModalEstimate, estimate_modes_from_observation
from .observation import AcousticObservation
from .synthesis import modal_state_matrix

__all__ = [
    "MATERIAL_FILE_FORMAT",
    "save_material",
    "load_material",
    "RecordingSetup",
    "StiffnessFit",
    "DampingFit",
    "CalibrationResult",
    "mode_clusters",
    "observability",
    "undamped_frequencies_hz",
    "fit_stiffness",
    "fit_damping",
    "calibrate",
    "log_spectral_distance_db",
]

MATERIAL_FILE_FORMAT = "aas-gym material"


# -- material files ---------------------------------------------------------------------------


def save_material(path: str | os.PathLike, material: Material, *, calibration: dict[str, Any] | None = None) -> Path:
    """Write ``material`` as JSON (atomically), optionally with a calibration report.

    The file holds ``{"format": "aas-gym material", "version": 1, "material": {...},
    "calibration": {...}}``; :func:`load_material` reads it back.
    """
    path = Path(path)
    doc = {"format": MATERIAL_FILE_FORMAT, "version": 1, "material": material.to_dict()}
    if calibration is not None:
        doc["calibration"] = calibration
    atomic_write_text(path, json.dumps(doc, indent=2, default=_json_default) + "\n")
    return path


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")


def load_material(path: str | os.PathLike) -> Material:
    """Read a material file written by :func:`save_material` (or a bare ``Material.to_dict()``
    JSON object) as a :class:`sensors.Material`."""
    with open(path) as fh:
        doc = json.load(fh)
    if isinstance(doc, dict) and doc.get("format") == MATERIAL_FILE_FORMAT:
        if int(doc.get("version", 1)) != 1:
            raise ValueError(f"{path}: unsupported material file version {doc.get('version')!r}")
        doc = doc["material"]
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a material file")
    try:
        return Material.from_dict(doc)
    except KeyError as exc:
        raise ValueError(f"{path}: material lacks field {exc.args[0]!r}") from None


# -- recordings and their contacts ---------------------------------------------------------------


@dataclass
class RecordingSetup:
    """A recording and the contacts it was made with (object frame).

    ``actuator`` and ``mic`` are the two fingertip contacts; ``others`` any further contacts
    (table, other objects). All of them damp the object.
    """

    observation: AcousticObservation
    actuator: Contact
    mic: Contact
    others: tuple[Contact, ...] = ()

    @property
    def contacts(self) -> list[Contact]:
        """Every contact on the object in this recording."""
        return [self.actuator, self.mic, *self.others]

    @classmethod
    def from_observation(cls, observation: AcousticObservation, actuator: Contact | None = None,
                         mic: Contact | None = None, others: Sequence[Contact] | None = None) -> RecordingSetup:
        """Contacts from the arguments, else from ``metadata["contacts"]`` as the simulator
        (and the rig, when it knows the grasp) writes them."""
        meta = (observation.metadata or {}).get("contacts") or {}

        def from_meta(key):
            d = meta.get(key)
            return None if d is None else Contact.from_dict(d)

        actuator = actuator if actuator is not None else from_meta("actuator")
        mic = mic if mic is not None else from_meta("mic")
        if others is None:
            others = [Contact.from_dict(d) for d in meta.get("other", [])]
        if actuator is None or mic is None:
            raise ValueError("the recording has no contacts in its metadata; pass actuator and mic contacts")
        return cls(observation, actuator, mic, tuple(others))


# -- mode bookkeeping -----------------------------------------------------------------------------


def mode_clusters(frequencies_hz: np.ndarray, rtol: float = 2e-3) -> list[np.ndarray]:
    """Groups of consecutive modes within ``rtol`` of each other in frequency.

    Symmetric objects have near-repeated pairs whose basis is arbitrary; only sums over a
    cluster (trace of a damping block, total observability) are meaningful.
    """
    f = np.asarray(frequencies_hz, float)
    order = np.argsort(f)
    groups: list[list[int]] = []
    for i in order:
        if groups and f[i] <= f[groups[-1][-1]] * (1 + rtol):
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    return [np.asarray(g) for g in groups]


def observability(model, actuator: Contact, mic: Contact) -> np.ndarray:
    """Relative displacement response of each mode from the actuator to the microphone,
    ``|(n_a . U_a)(n_m . U_m)| / w^2`` (the static modal flexibility; 0 = at a node)."""
    U = np.asarray(model.mode_shapes_at(np.array([actuator.position_m, mic.position_m])), float)
    b = np.asarray(actuator.normal) @ U[0]
    o = np.asarray(mic.normal) @ U[1]
    w = np.asarray(model.angular_frequencies_rad_s, float)
    return np.abs(b * o) / w**2


# -- Young's modulus -------------------------------------------------------------------------------


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


def _match(log_f: np.ndarray, log_c: np.ndarray, sizes: np.ndarray, log_s: float, tol: float,
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


def _decay_terms(est: ModalEstimate, priors: Sequence[np.ndarray] | None, k: int):
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
        matches = [_match(lf, lc, np.asarray(sz), log_s, tol, *_decay_terms(est, cluster_decay_priors, k))
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


# -- damping -----------------------------------------------------------------------------------------


@dataclass
class DampingFit:
    """Result of :func:`fit_damping`.

    Attributes:
        alpha, beta, gamma: fitted Rayleigh alpha [1/s], beta [s] and contact gamma [s/m].
        covariance: 3x3 covariance of (alpha, beta, gamma) (row/column of a held gamma is 0).
        bootstrap_std: standard deviations of (alpha, beta, gamma) over a bootstrap of modes.
        gamma_fitted: False when gamma was held at its given value.
        n_modes: rows used (after outlier rejection); n_rejected: rows dropped as outliers.
        chi2_reduced: weighted residual sum of squares per degree of freedom.
        frequencies_hz, decay_rates_per_s, predicted: the rows used and the fit's prediction.
        used: mask over the input rows of those used.
        damping_model: ``"diagonal"`` (first order: sigma = C_cc / 2) or ``"exact"`` (the
            eigenvalues of the full damped system, see :func:`calibrate`).
    """

    alpha: float
    beta: float
    gamma: float
    covariance: np.ndarray
    bootstrap_std: np.ndarray
    gamma_fitted: bool
    n_modes: int
    n_rejected: int
    chi2_reduced: float
    frequencies_hz: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    decay_rates_per_s: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    predicted: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    used: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0, bool))
    damping_model: str = "diagonal"

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of (alpha, beta, gamma) from the covariance."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))


def fit_damping(
    frequencies_hz: np.ndarray,
    decay_rates_per_s: np.ndarray,
    decay_rate_std_per_s: np.ndarray | None = None,
    contact_terms: np.ndarray | None = None,
    *,
    gamma: float | None = None,
    rel_floor: float = 0.02,
    outlier_sigma: float = 4.0,
    n_bootstrap: int = 200,
    rng: int | np.random.Generator | None = 0,
) -> DampingFit:
    """Weighted least squares of ``sigma = (alpha + beta w^2 + gamma g) / 2``.

    Args:
        frequencies_hz: modal frequencies [Hz] (w = 2 pi f).
        decay_rates_per_s: measured decay rates sigma [1/s].
        decay_rate_std_per_s: their standard deviations [1/s] (default: only the floor).
        contact_terms: g per row, the diagonal of the contact damping matrix per unit gamma
            [N/kg = m/s^2, so gamma g is in 1/s]; ``None`` means no contact damping term.
        gamma: hold gamma at this value instead of fitting it (needs ``contact_terms``).
        rel_floor: relative error added in quadrature to every decay rate: Rayleigh damping
            is a model, and a real object's decay rates scatter around it by a few per cent.
        outlier_sigma: rows whose residual exceeds this many standard deviations (scaled by
            the median absolute residual when that is larger) are dropped one at a time,
            worst first, refitting in between (mis-matched or badly estimated modes).
        n_bootstrap: bootstrap resamples of the rows for ``bootstrap_std`` (0 = skip).

    alpha, beta and gamma are constrained to be >= 0. Rows far (twice ``outlier_sigma``)
    from a robust Cauchy-loss fit are dropped first, then the worst remaining row at a time.
    """
    f = np.asarray(frequencies_hz, float)
    sig = np.asarray(decay_rates_per_s, float)
    if f.shape != sig.shape or f.ndim != 1:
        raise ValueError("frequencies_hz and decay_rates_per_s must be 1-D arrays of the same length")
    sd = np.zeros_like(sig) if decay_rate_std_per_s is None else np.asarray(decay_rate_std_per_s, float)
    sd = np.sqrt(np.where(np.isfinite(sd), sd, np.inf) ** 2 + (rel_floor * np.abs(sig)) ** 2)
    w2 = (2 * np.pi * f) ** 2
    g = None if contact_terms is None else np.asarray(contact_terms, float)
    fit_gamma = g is not None and gamma is None
    target = sig.copy()
    if g is not None and gamma is not None:
        target = target - 0.5 * gamma * g
    cols = [0.5 * np.ones_like(sig), 0.5 * w2] + ([0.5 * g] if fit_gamma else [])
    A = np.stack(cols, axis=1)
    # column scaling: beta * w^2 ~ 1e2 while beta ~ 1e-7; solve for scaled unknowns
    col_scale = np.maximum(np.abs(A).max(axis=0), 1e-300)
    need = A.shape[1]
    keep = np.isfinite(sd) & np.isfinite(target)
    if keep.sum() < need:
        raise ValueError(f"need at least {need} modes with finite decay rates, got {int(keep.sum())}")

    def solve(rows: np.ndarray) -> np.ndarray:
        Aw = A[rows] / col_scale / sd[rows, None]
        res = scipy.optimize.lsq_linear(Aw, target[rows] / sd[rows], bounds=(0.0, np.inf), method="bvls")
        return res.x / col_scale

    # A robust (Cauchy-loss) fit first: a few wrong rows (a fingertip resonance matched to a
    # model mode) must not drag the start so far that every row looks like an outlier.
    x0 = solve(keep)
    Ak = A[keep] / col_scale / sd[keep, None]
    tk = target[keep] / sd[keep]
    robust = scipy.optimize.least_squares(lambda u: Ak @ u - tk, x0 * col_scale, bounds=(0.0, np.inf),
                                          loss="cauchy", f_scale=2.0)
    r0 = (target - A @ (robust.x / col_scale)) / sd
    spread = max(1.4826 * float(np.median(np.abs(r0[keep]))), 1.0)
    far = keep & (np.abs(r0) > 2 * outlier_sigma * spread)
    rejected = 0
    if keep.sum() - far.sum() >= need + 1:
        keep &= ~far
        rejected = int(far.sum())
    for _ in range(max(3, sig.size // 5)):
        x = solve(keep)
        r = (target - A @ x) / sd
        dof = max(int(keep.sum()) - need, 1)
        chi2 = float(np.sum(r[keep] ** 2) / dof)
        # robust scale (median absolute deviation): outliers must not hide by inflating chi2
        scale = max(1.4826 * float(np.median(np.abs(r[keep]))), 1.0)
        bad = keep & (np.abs(r) > outlier_sigma * scale)
        if not bad.any() or keep.sum() - 1 < need + 1:
            break
        # drop the worst one at a time: one bad row inflates every residual
        worst = np.flatnonzero(keep)[np.argmax(np.abs(r[keep]))]
        keep[worst] = False
        rejected += 1
    Aw = A[keep] / col_scale / sd[keep, None]  # scaled columns: A^T A spans ~20 decades otherwise
    cov_small = np.linalg.pinv(Aw.T @ Aw) / np.outer(col_scale, col_scale) * max(chi2, 1.0)
    boot = np.zeros(need)
    if n_bootstrap > 0:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        idx = np.flatnonzero(keep)
        samples = []
        for _ in range(n_bootstrap):
            pick = gen.choice(idx, idx.size, replace=True)
            if np.unique(pick).size < need:
                continue
            samples.append(solve(pick))  # a row drawn k times weighs k times
        if samples:
            boot = np.std(np.asarray(samples), axis=0, ddof=1)
    cov = np.zeros((3, 3))
    cov[:need, :need] = cov_small
    boot3 = np.zeros(3)
    boot3[:need] = boot
    gamma_val = float(x[2]) if fit_gamma else float(gamma if gamma is not None else 0.0)
    return DampingFit(float(x[0]), float(x[1]), gamma_val, cov, boot3, fit_gamma, int(keep.sum()), rejected, chi2,
                      f[keep], sig[keep], (A @ x)[keep] + (sig - target)[keep], keep.copy())


def _exact_decay_rates(w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Decay rate of each mode of ``q'' + C q' + diag(w^2) q = 0``: -Re of the state-space
    eigenvalue assigned to that mode (by damped frequency) [1/s]."""
    r = w.size
    A = modal_state_matrix(w, C)
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag >= 0]
    # an overdamped mode gives two real eigenvalues; its slower one is what a fit would see
    cost = np.abs(lam.imag[:, None] - w[None, :]) + np.abs(lam.real[:, None]) * 1e-9
    rows, cols = scipy.optimize.linear_sum_assignment(cost)
    sigma = np.full(r, np.nan)
    sigma[cols] = -lam.real[rows]
    return sigma


def _refine_exact(fit: DampingFit, w_model: np.ndarray, G_list: list[np.ndarray], row_rec: np.ndarray,
                  row_members: list[np.ndarray], sigma: np.ndarray, sd: np.ndarray, gamma_held: float | None,
                  freqs_hz: np.ndarray, outlier_sigma: float = 4.0) -> DampingFit:
    """Refit alpha, beta (and gamma) to the exact eigenvalues of the damped modal system of
    each recording, starting from the first-order (diagonal) fit.

    All rows take part again (the diagonal fit may have rejected the contact-coupled ones
    that only the exact model explains): a Cauchy-loss fit first, then the rows it leaves
    far out are dropped and the rest fitted by plain least squares."""
    x0 = np.array([fit.alpha, fit.beta] + ([fit.gamma] if gamma_held is None else []))
    scale = np.maximum(np.abs(x0), [1e-3, 1e-12, 1e-6][:x0.size])
    n_par = x0.size
    finite = np.isfinite(sigma) & np.isfinite(sd)

    def predict(x, rows):
        alpha, beta = x[0], x[1]
        gamma = x[2] if gamma_held is None else gamma_held
        out = np.full(rows.size, np.nan)
        for r in np.unique(row_rec[rows]):
            C = np.diag(alpha + beta * w_model**2) + gamma * G_list[r]
            s_modes = _exact_decay_rates(w_model, C)
            for k in np.flatnonzero(row_rec[rows] == r):
                out[k] = np.nanmean(s_modes[row_members[rows[k]]])
        return out

    def solve(rows, start, loss):
        def resid(xs):
            return (sigma[rows] - predict(xs * scale, rows)) / sd[rows]
        return scipy.optimize.least_squares(resid, start / scale, bounds=(0.0, np.inf), method="trf", loss=loss,
                                            f_scale=2.0)

    rows = np.flatnonzero(finite)
    first = solve(rows, x0, "cauchy")
    r0 = (sigma[rows] - predict(first.x * scale, rows)) / sd[rows]
    spread = max(1.4826 * float(np.median(np.abs(r0))), 1.0)
    keep_rows = rows[np.abs(r0) <= outlier_sigma * spread]
    if keep_rows.size < n_par + 1:
        keep_rows = rows
    sol = solve(keep_rows, first.x * scale, "linear")
    x = sol.x * scale
    r = sol.fun
    chi2 = float(np.sum(r**2) / max(r.size - n_par, 1))
    Js = sol.jac  # w.r.t. the scaled unknowns
    cov_small = np.linalg.pinv(Js.T @ Js) * np.outer(scale, scale) * max(chi2, 1.0)
    cov = np.zeros((3, 3))
    cov[:n_par, :n_par] = cov_small
    used = np.zeros(sigma.size, bool)
    used[keep_rows] = True
    return dataclasses.replace(
        fit, alpha=float(x[0]), beta=float(x[1]), gamma=float(x[2]) if gamma_held is None else float(gamma_held),
        covariance=cov, chi2_reduced=chi2, predicted=predict(x, keep_rows), damping_model="exact",
        n_modes=int(keep_rows.size), n_rejected=int(finite.sum() - keep_rows.size), used=used,
        frequencies_hz=freqs_hz[keep_rows], decay_rates_per_s=sigma[keep_rows])


# -- the whole calibration ------------------------------------------------------------------------------


@dataclass
class CalibrationResult:
    """Everything :func:`calibrate` found.

    Attributes:
        material: the calibrated material.
        base_material: the material it started from.
        stiffness: the Young's modulus fit (``None`` if E was not fitted).
        damping: the alpha / beta / gamma fit.
        estimates: the modal estimate of each recording.
    """

    material: Material
    base_material: Material
    stiffness: StiffnessFit | None
    damping: DampingFit
    estimates: list[ModalEstimate]

    def report(self) -> dict[str, Any]:
        """JSON-friendly summary with uncertainties (stored in the material file)."""
        d = self.damping
        std = d.std
        out: dict[str, Any] = {
            "base_material": self.base_material.to_dict(),
            "alpha": {"value": d.alpha, "std": std[0], "bootstrap_std": d.bootstrap_std[0]},
            "beta": {"value": d.beta, "std": std[1], "bootstrap_std": d.bootstrap_std[1]},
            "gamma": {"value": d.gamma, "std": std[2], "bootstrap_std": d.bootstrap_std[2], "fitted": d.gamma_fitted},
            "damping_modes_used": d.n_modes,
            "damping_modes_rejected": d.n_rejected,
            "damping_chi2_reduced": d.chi2_reduced,
            "modes_found_per_recording": [len(e) for e in self.estimates],
        }
        if self.stiffness is not None:
            s = self.stiffness
            out["youngs_modulus_pa"] = {
                "value": self.material.youngs_modulus_pa,
                "std": self.base_material.youngs_modulus_pa * s.youngs_modulus_factor_std,
                "factor_to_base": s.youngs_modulus_factor,
            }
            out["modes_matched"] = s.n_matched
            out["frequency_rms_relative_misfit"] = s.rms_log_misfit
        return out


def _as_leaks(leak) -> list:
    from .leak import LeakRecording, load_leak

    if leak is None:
        return []
    items = leak if isinstance(leak, (list, tuple)) else [leak]
    return [lk if isinstance(lk, LeakRecording) else load_leak(lk) for lk in items]


def calibrate(
    model,
    recordings: Sequence[RecordingSetup | AcousticObservation],
    base_material: Material | str | None = None,
    *,
    fit_youngs_modulus: bool = True,
    fit_gamma: bool | str = "auto",
    factor_range: tuple[float, float] = (1 / 3, 3.0),
    rel_tol: float = 0.01,
    min_observability: float = 1e-3,
    name: str | None = None,
    estimates: Sequence[ModalEstimate] | None = None,
    damping_model: str = "exact",
    rel_floor: float = 0.02,
    leak=None,
    **estimate_kwargs: Any,
) -> CalibrationResult:
    """Fit E, alpha, beta and gamma of ``model``'s material to recordings of the object.

    Args:
        model: the object's modal model built with ``base_material`` (``sensors.ModalModel``
            or compatible: ``angular_frequencies_rad_s``, ``mode_shapes_at``, ``material``).
        recordings: :class:`RecordingSetup` (or observations with contacts in their metadata).
        base_material: starting material (default: the model's).
        fit_youngs_modulus: fit the E scale (else match at the base E).
        fit_gamma: True, False, or ``"auto"``: fit gamma when the recordings' contact damping
            differs between recordings (grip forces, contact sets) enough to separate it
            from alpha and beta; else hold it at the base value.
        factor_range: search range for E / E_base.
        rel_tol: relative frequency tolerance of the model (mode matching).
        min_observability: model modes (clusters) whose actuator-to-mic response is below this
            fraction of the strongest are not expected in the recording and not matched.
        name: name of the calibrated material (default ``"<base>-calibrated"``).
        estimates: modal estimates already made (skips estimation).
        damping_model: ``"diagonal"``: sigma = C_cc / 2 (first order, linear least squares);
            ``"exact"`` (default): then refine by nonlinear least squares on the eigenvalues
            of the full damped system of each recording, since contact damping couples
            modes and the diagonal is biased when modes are close or contact damping is
            strong (the damped system is 2r x 2r; r is a few hundred at most).
        rel_floor: relative model error of a decay rate (see :func:`fit_damping`).
        leak: the rig's idle leak recording(s) (``sensors.LeakRecording``, a path to one, or
            a sequence of them, one per excitation): removed from each recording made with
            the matching excitation before its modes are estimated.
        **estimate_kwargs: passed to :func:`sensors.modal_estimation.estimate_modes_from_observation`.
    """
    if damping_model not in ("exact", "diagonal"):
        raise ValueError(f"damping_model must be 'exact' or 'diagonal', got {damping_model!r}")
    base = get_material(base_material) if base_material is not None else model.material
    if not isinstance(base, Material):
        raise TypeError(f"base material must be a sensors.Material or a table name, got {type(base).__name__}")
    setups = [r if isinstance(r, RecordingSetup) else RecordingSetup.from_observation(r) for r in recordings]
    if not setups:
        raise ValueError("no recordings")
    if estimates is None:
        leaks = _as_leaks(leak)
        estimates = []
        for s in setups:
            kw = dict(estimate_kwargs)
            if leaks:
                match = [lk for lk in leaks if lk.matches(s.observation.excitation)]
                if not match:
                    raise ValueError(f"no leak recording for the {s.observation.excitation.name} excitation")
                kw["leak"] = match[0]
            estimates.append(estimate_modes_from_observation(s.observation, **kw))
    estimates = list(estimates)
    w_model = np.asarray(model.angular_frequencies_rad_s, float)
    # the model may have been built with another E than the base material's
    model_E = float(model.material.youngs_modulus_pa)
    f_base = w_model / (2 * np.pi) * math.sqrt(base.youngs_modulus_pa / model_E)
    clusters = mode_clusters(f_base)
    cluster_f = np.array([f_base[c].mean() for c in clusters])
    cluster_n = np.array([c.size for c in clusters])

    w_base = 2 * np.pi * f_base
    per_rec_cf, per_rec_sizes, per_rec_ids, per_rec_prior, G_list = [], [], [], [], []
    for s in setups:
        G = contact_damping_matrix(model, s.contacts)
        G_list.append(G)
        prior = 0.5 * (base.alpha + base.beta * w_base**2 + base.gamma * np.diag(G))
        obs = observability(model, s.actuator, s.mic)
        obs_c = np.array([math.sqrt(np.sum(obs[c] ** 2)) for c in clusters])
        visible = obs_c >= min_observability * obs_c.max() if obs_c.max() > 0 else np.zeros(len(clusters), bool)
        ids = np.flatnonzero(visible)
        per_rec_ids.append(ids)
        per_rec_prior.append(np.array([prior[clusters[i]].mean() for i in ids]))
        per_rec_cf.append(cluster_f[ids])
        per_rec_sizes.append(cluster_n[ids])

    if fit_youngs_modulus:
        stiff = fit_stiffness(estimates, per_rec_cf, per_rec_sizes, factor_range=factor_range, rel_tol=rel_tol,
                              cluster_decay_priors=per_rec_prior)
        scale = stiff.scale
        matches = stiff.matches
    else:
        stiff = None
        scale = 1.0
        matches = [_match(np.log(undamped_frequencies_hz(e)), np.log(cf), sz, 0.0, rel_tol,
                          *_decay_terms(e, per_rec_prior, k))
                   for k, (e, cf, sz) in enumerate(zip(estimates, per_rec_cf, per_rec_sizes))]

    rows_f, rows_sig, rows_sd, rows_g, rec_of_row, members = [], [], [], [], [], []
    for r, (est, m, ids, G) in enumerate(zip(estimates, matches, per_rec_ids, G_list)):
        f_undamped = undamped_frequencies_hz(est)
        for i, c_local in m:
            c = clusters[ids[c_local]]
            rows_f.append(f_undamped[i])
            rows_sig.append(est.decay_rates_per_s[i])
            rows_sd.append(est.decay_rate_std_per_s[i])
            rows_g.append(float(np.trace(G[np.ix_(c, c)]) / c.size))
            rec_of_row.append(r)
            members.append(c)
    g = np.asarray(rows_g)
    if fit_gamma == "auto":
        # gamma separates from alpha + beta w^2 only if g varies between recordings for the
        # same modes; require the per-recording mean contact term to differ by 10 %
        rec = np.asarray(rec_of_row)
        means = [g[rec == r].mean() for r in np.unique(rec)] if g.size else []
        fit_gamma = len(means) >= 2 and (max(means) - min(means)) > 0.1 * max(max(means), 1e-300)
    damping = fit_damping(np.asarray(rows_f), np.asarray(rows_sig), np.asarray(rows_sd), g,
                          gamma=None if fit_gamma else base.gamma, rel_floor=rel_floor)
    if damping_model == "exact":
        sd = np.sqrt(np.asarray(rows_sd) ** 2 + (rel_floor * np.asarray(rows_sig)) ** 2)
        damping = _refine_exact(damping, w_model * math.sqrt(base.youngs_modulus_pa / model_E) * scale, G_list,
                                np.asarray(rec_of_row), members, np.asarray(rows_sig), sd,
                                None if fit_gamma else base.gamma, np.asarray(rows_f))
    material = dataclasses.replace(
        base, name=name or f"{base.name}-calibrated", youngs_modulus_pa=base.youngs_modulus_pa * scale**2,
        alpha=damping.alpha, beta=damping.beta, gamma=damping.gamma)
    return CalibrationResult(material, base, stiff, damping, estimates)


def log_spectral_distance_db(recording: AcousticObservation, simulation: AcousticObservation,
                             band_hz: tuple[float, float] = (200.0, 9800.0)) -> float:
    """RMS difference [dB] of the amplitude spectra of two observations of the same excitation
    over ``band_hz``: how well a simulation (e.g. with a calibrated material) reproduces a
    recording; two noisy recordings of one object differ by the noise-limited floor."""
    f, a_rec = recording.spectrum()
    _, a_sim = simulation.spectrum()
    band = (f >= band_hz[0]) & (f <= band_hz[1])
    return float(np.sqrt(np.mean((20 * np.log10(a_sim[band] / a_rec[band])) ** 2)))
