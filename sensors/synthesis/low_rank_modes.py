"""Exact complex modes of a lightly damped modal system whose damping is diagonal plus low rank.

The scaled modal state x = [Omega q; q'] evolves with

    A = [[0, Omega], [-Omega, -(diag(d) + Q^T Q)]],

where diag(d) is the Rayleigh part and Q^T Q (Q: k x r, k << r) the contact damping. A dense
eigen-decomposition of A costs O((2r)^3). Here A = A0 + U V^T with A0 the diagonally damped
matrix (closed-form 2 x 2 blocks) and a rank-k update, so by the matrix determinant lemma

    det(lambda I - A) = prod_i (lambda - lambda0_i) * det(I_k - V'^T (lambda I - Lambda0)^-1 U'),

a k x k determinant per evaluation (U', V' are U, V in the eigenbasis of A0). The roots are
found all at once by the Aberth-Ehrlich iteration (cubic convergence; its mutual repulsion
keeps close modes apart), and each eigenvector follows from the k x k null vector.  Cost
O(r^2 k^2) per sweep instead of O(r^3).

The iteration starts from quasi-degenerate perturbation theory (:mod:`sensors.synthesis.perturbation`):
second order for isolated modes and the eigenvalues of a small effective matrix for each
cluster of nearly repeated modes (a tube's pairs, which first-order starts put 1e-4 off, so
that they needed six sweeps). After each sweep every root's eigenvector is computed (one step
of inverse iteration on the k x k matrix) with its residual and condition number; a root is
converged when its step was at rounding level or when condition number x residual, a
first-order bound on its error, is below 1e-13. From these starts one sweep converges all but
a fifth of the roots. The k x k eliminations, the pole sums and the vectors are loops compiled
by numba (:mod:`sensors.synthesis.low_rank_kernels`): LAPACK's per-call cost dominates at k ~ 12.

The result is checked, never trusted: every eigenpair's residual, the eigenvalues' sum
against trace(A) (a missed or doubled root changes it), that no two roots coincide, and the
eigenvector condition numbers.
Any failure returns ``None`` and the caller takes the dense path.
"""
from __future__ import annotations

import numpy as np

from . import low_rank_kernels
from .._infra.jit import jitted
from .perturbation import start_roots

# Relative Aberth step below which a root counts as converged.
_STEP_TOL = 1e-9
# A root is also converged once condition number x relative residual (a first-order bound on
# its relative error) is below this; the roots of a sweep from good starts usually are.
_CERTIFIED = 1e-13
# Two roots closer than this (relative) count as one eigenvalue found twice: dense path.
_DISTINCT = 1e-12
_MAX_SWEEPS = 60
# Accept only if every relative residual and the trace check are below these.
_RESIDUAL_TOL = 1e-10
_TRACE_TOL = 1e-9
# Eigenvalue condition (1 / |cos| between left and right vectors) above this -> dense path,
# as the dense path's own threshold on cond(V).
_MAX_CONDITION = 1e8


def low_rank_modes(w: np.ndarray, d: np.ndarray, Q: np.ndarray):
    """Eigenvalues with Im >= 0, right vectors V (2r, r) and left rows W (r, 2r), W V = I,
    of the state matrix above; ``None`` if the fast path does not apply or fails its checks.

    Args:
        w: (r,) undamped angular frequencies [rad/s], positive.
        d: (r,) diagonal (Rayleigh) damping [1/s].
        Q: (k, r) factor of the contact damping, C = diag(d) + Q^T Q [1/s].
    """
    w = np.asarray(w, float)
    d = np.asarray(d, float)
    Q = np.asarray(Q, float)
    r = w.size
    if r == 0 or Q.ndim != 2 or Q.shape[1] != r or not (np.all(np.isfinite(Q)) and np.all(np.isfinite(d))):
        return None
    disc = np.sqrt((d * d - 4 * w * w).astype(complex))
    lp, lm = (-d + disc) / 2, (-d - disc) / 2
    # Over- or near-critically damped modes have (nearly) real, defective pairs: dense path.
    if np.any(np.abs(lp - lm) < 1e-3 * np.abs(lp)) or np.any(lp.imag <= 0):
        return None
    det = w * (lm - lp)
    # Modes the contacts do not touch are decoupled from all others (their row of Q^T Q is
    # zero): their closed-form 2 x 2 eigenpairs are exact. The rest go to the root finder.
    qn = np.einsum("ki,ki->i", Q, Q)
    c = np.flatnonzero(qn > 1e-28 * max(float(qn.max(initial=0.0)), 1e-300))
    if c.size == r:  # the usual grasp: every mode touched
        return _coupled_modes(w, d, Q, lp, lm, det)
    lam = lp.copy()
    V = np.zeros((2 * r, r), complex)
    W = np.zeros((r, 2 * r), complex)
    ii = np.arange(r)
    # eigenvector [w; l+] of [[0, w], [-w, -d]], left row (1/det) [l-, -w] (unit column norm)
    scale = np.sqrt(w**2 + np.abs(lp) ** 2)
    V[ii, ii], V[r + ii, ii] = w / scale, lp / scale
    W[ii, ii], W[ii, r + ii] = lm / det * scale, -w / det * scale
    if c.size:
        out = _coupled_modes(w[c], d[c], Q[:, c], lp[c], lm[c], det[c])
        if out is None:
            return None
        lam[c] = out[0]
        rows = np.concatenate([c, r + c])
        V[:, c] = 0.0
        W[c, :] = 0.0
        V[np.ix_(rows, c)] = out[1]
        W[np.ix_(c, rows)] = out[2]
    return lam, V, W


def _kernel(name: str):
    # error_model="numpy": a zero gap gives inf or nan, which the checks below catch
    return jitted(vars(low_rank_kernels), name, callees=("recip", "_unpack", "_eliminate"), cache=True,
                  error_model="numpy")


def _coupled_modes(w, d, Q, lp, lm, det):
    """The root finder and eigenvectors for modes that all touch the contacts."""
    r = w.size
    k = Q.shape[0]
    # In A0's eigenbasis the update's row for pole (i, +-) is s_+- q_i q_i^T (q_i = Q[:, i]);
    # the k x k matrices are symmetric: products over the k (k + 1) / 2 packed entries.
    sp, sm = lp * w / det, -lm * w / det
    iu, ju = np.triu_indices(k)
    QQ = Q.T[:, iu] * Q.T[:, ju]                                    # (r, k (k+1) / 2)
    lam = start_roots(lp, lm, w, det, Q)
    VT = np.empty((r, 2 * r), complex)
    Wl = np.empty((r, 2 * r), complex)
    cond = np.empty(r)
    res = np.empty(r)
    sweep_terms, pole_terms, vectors = _kernel("sweep_terms"), _kernel("pole_terms"), _kernel("vectors")
    newton_traces, null_vectors, residuals = _kernel("newton_traces"), _kernel("null_vectors"), _kernel("residuals")
    idx = np.arange(r)
    for _ in range(_MAX_SWEEPS):
        n = idx.size
        # Aberth sweep over the roots not yet converged: M(L) and dM/dL, Newton, repulsion
        L = lam[idx]
        S = np.empty((4, n, r))
        pole_sum, repulsion = sweep_terms(L, idx, lam, lp, lm, sp, sm, S)
        R = (S.reshape(4 * n, r) @ QQ).reshape(4, n, -1)
        tr = np.empty(n, complex)
        newton_traces(R, iu, ju, k, tr)
        newton = 1.0 / (pole_sum + tr)
        step = newton / (1.0 - newton * repulsion)
        if not np.all(np.isfinite(step)):
            return None
        lam[idx] = L - step
        # eigenvectors at the new roots from the null vector y of M(lambda)
        S = np.empty((2, n, r))
        RP, RM = np.empty((n, r), complex), np.empty((n, r), complex)
        pole_terms(lam[idx], lp, lm, sp, sm, S, RP, RM)
        R = (S.reshape(2 * n, r) @ QQ).reshape(2, n, -1)
        y = np.empty((n, k), complex)
        null_vectors(R, iu, ju, k, y)
        vectors(idx, lam, RP, RM, lp, lm, w, w / det, 1.0 / det, y.real @ Q + 1j * (y.imag @ Q), VT, Wl, cond)
        low = VT[idx, r:]
        qv = low.real @ Q.T + 1j * (low.imag @ Q.T)                  # (roots, k)
        residuals(idx, lam, w, d, np.abs(d).max(), VT, qv.real @ Q + 1j * (qv.imag @ Q), res)
        # Converged: the step at rounding level, or the residual's first-order bound on the
        # root's error (condition number x residual) far below it.
        done = (np.abs(step) <= _STEP_TOL * np.abs(L)) | (cond[idx] * res[idx] <= _CERTIFIED)
        idx = idx[~done]
        if idx.size == 0:
            break
    else:
        return None
    if not (cond.max() <= _MAX_CONDITION and res.max() <= _RESIDUAL_TOL):
        return None
    # a missed or doubled root changes the trace; two roots on one eigenvalue are never apart
    trace = -(d.sum() + np.sum(Q * Q))
    if abs(2 * lam.real.sum() - trace) > _TRACE_TOL * abs(trace) or not _apart(lam):
        return None
    return lam, VT.T, Wl


def _apart(lam: np.ndarray) -> bool:
    """Whether no two roots coincide (relative distance above rounding)."""
    if lam.size < 2:
        return True
    order = np.argsort(lam.imag)
    gaps = np.abs(np.diff(lam[order]))
    return bool(np.all(gaps > _DISTINCT * np.abs(lam[order][1:])))
