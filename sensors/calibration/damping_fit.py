"""Rayleigh alpha, beta and contact gamma from measured decay rates."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize

from ..synthesis.modal_system import modal_state_matrix


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


def exact_decay_rates(w: np.ndarray, C: np.ndarray) -> np.ndarray:
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


def refine_damping_exact(fit: DampingFit, w_model: np.ndarray | list[np.ndarray], G_list: list[np.ndarray],
                         row_rec: np.ndarray,
                         row_members: list[np.ndarray], sigma: np.ndarray, sd: np.ndarray, gamma_held: float | None,
                         freqs_hz: np.ndarray, outlier_sigma: float = 4.0) -> DampingFit:
    """Refit alpha, beta (and gamma) to the exact eigenvalues of the damped modal system of
    each recording, starting from the first-order (diagonal) fit.

    ``w_model`` [rad/s]: the undamped modes of every recording, or a list with one array per
    recording (under contact springs each recording has its own coupled modes).

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
            w = w_model[r] if isinstance(w_model, list) else w_model
            C = np.diag(alpha + beta * w**2) + gamma * G_list[r]
            s_modes = exact_decay_rates(w, C)
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
