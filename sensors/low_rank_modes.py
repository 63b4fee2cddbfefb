"""Exact complex modes of a lightly damped modal system whose damping is diagonal plus low rank.

The scaled modal state x = [Omega q; q'] evolves with

    A = [[0, Omega], [-Omega, -(diag(d) + Q^T Q)]],

where diag(d) is the Rayleigh part and Q^T Q (Q: k x r, k << r) the contact damping. A dense
eigen-decomposition of A costs O((2r)^3). Here A = A0 + U V^T with A0 the diagonally damped
matrix (closed-form 2 x 2 blocks) and a rank-k update, so by the matrix determinant lemma

    det(lambda I - A) = prod_i (lambda - lambda0_i) * det(I_k - V'^T (lambda I - Lambda0)^-1 U'),

a k x k determinant per evaluation (U', V' are U, V in the eigenbasis of A0). The roots are
found all at once by the Aberth-Ehrlich iteration (cubic convergence, started from first-order
perturbation theory; its mutual repulsion keeps close modes apart), and each eigenvector
follows from the k x k null vector.  Cost O(r^2 k^2) per sweep instead of O(r^3).

The result is checked, never trusted: every eigenpair's residual, the eigenvalues' sum
against trace(A) (a missed or doubled root changes it) and the eigenvector condition numbers.
Any failure returns ``None`` and the caller takes the dense path.
"""
from __future__ import annotations

import numpy as np

from .lazy_jit import jitted

# Relative Aberth step below which a root counts as converged.
_STEP_TOL = 1e-9
_MAX_SWEEPS = 60
# Accept only if every relative residual and the trace check are below these.
_RESIDUAL_TOL = 1e-10
_TRACE_TOL = 1e-9
# Eigenvalue condition (1 / |cos| between left and right vectors) above this -> dense path,
# as the dense path's own threshold on cond(V).
_MAX_CONDITION = 1e8


# compiled by numba on first use (sensors.lazy_jit), error_model="numpy": a zero gap gives inf, caught below
def _sweep_terms(L, idx, lam, lp, lm, sp, sm, S1, S2):
    """For each active root L[a]: S1[a, i] = sum over the two poles of mode i of s / (L - pole),
    S2 the same with (L - pole)^2, and return sum_i 1/(L - pole) and the Aberth repulsion
    sum over every other current root (and its conjugate)."""
    na, r = S1.shape
    pole_sum = np.empty(na, np.complex128)
    repulsion = np.empty(na, np.complex128)
    for a in range(na):
        x = L[a]
        acc = 0j
        for i in range(r):
            rp = 1.0 / (x - lp[i])
            rm = 1.0 / (x - lm[i])
            acc += rp + rm
            S1[a, i] = rp * sp[i] + rm * sm[i]
            S2[a, i] = rp * rp * sp[i] + rm * rm * sm[i]
        pole_sum[a] = acc
        rep = 0j
        me = idx[a]
        for j in range(r):
            if j != me:
                rep += 1.0 / (x - lam[j])
            rep += 1.0 / (x - np.conj(lam[j]))
        repulsion[a] = rep
    return pole_sum, repulsion


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
    coupled = qn > 1e-28 * max(float(qn.max(initial=0.0)), 1e-300)
    lam = lp.copy()
    V = np.zeros((2 * r, r), complex)
    W = np.zeros((r, 2 * r), complex)
    ii = np.arange(r)
    # eigenvector [w; l+] of [[0, w], [-w, -d]], left row (1/det) [l-, -w] (unit column norm)
    scale = np.sqrt(w**2 + np.abs(lp) ** 2)
    V[ii, ii], V[r + ii, ii] = w / scale, lp / scale
    W[ii, ii], W[ii, r + ii] = lm / det * scale, -w / det * scale
    c = np.flatnonzero(coupled)
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


def _coupled_modes(w, d, Q, lp, lm, det):
    """The root finder and eigenvectors for modes that all touch the contacts."""
    r = w.size
    k = Q.shape[0]
    # In A0's eigenbasis the update's row for pole (i, +-) is s_+- q_i q_i^T (q_i = Q[:, i]).
    sp, sm = lp * w / det, -lm * w / det
    QQ = (Q.T[:, :, None] * Q.T[:, None, :]).reshape(r, k * k)
    lam = lp + sp * np.einsum("ki,ki->i", Q, Q)   # first-order perturbation
    eye = np.eye(k)
    active = np.ones(r, bool)
    sweep_terms = jitted(globals(), "_sweep_terms", cache=True, error_model="numpy")
    for _ in range(_MAX_SWEEPS):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        L = lam[idx]
        S1 = np.empty((idx.size, r), complex)
        S2 = np.empty((idx.size, r), complex)
        pole_sum, repulsion = sweep_terms(L, idx, lam, lp, lm, sp, sm, S1, S2)
        M = eye - (S1.real @ QQ + 1j * (S1.imag @ QQ)).reshape(-1, k, k)
        dM = (S2.real @ QQ + 1j * (S2.imag @ QQ)).reshape(-1, k, k)
        try:
            tr = np.einsum("aii->a", np.linalg.solve(M, dM))
        except np.linalg.LinAlgError:
            return None
        newton = 1.0 / (pole_sum + tr)
        step = newton / (1.0 - newton * repulsion)
        if not np.all(np.isfinite(step)):
            return None
        lam[idx] = L - step
        active[idx] = np.abs(step) > _STEP_TOL * np.abs(L)
    else:
        return None
    # Eigenvectors from the null vector y of M(lambda) (complex symmetric: left = right),
    # by one step of inverse iteration (M is singular to rounding at a converged root).
    Rp = 1.0 / (lam[:, None] - lp[None, :])
    Rm = 1.0 / (lam[:, None] - lm[None, :])
    S1 = Rp * sp + Rm * sm
    M = eye - (S1.real @ QQ + 1j * (S1.imag @ QQ)).reshape(-1, k, k)
    probe = np.broadcast_to(np.linspace(1.0, 2.0, k)[None, :, None], (r, k, 1))
    try:
        y = np.linalg.solve(M, probe)[:, :, 0]
    except np.linalg.LinAlgError:
        y = np.linalg.svd(M)[2][:, -1, :].conj()
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    qy = y @ Q                                           # (r_eig, r_mode): q_i^T y
    # right vector in A0's basis: z_(i,+-) = R_+- u_(i,+-)^T y, u_(i,+) = (w/det) q_i, u_(i,-) = -(w/det) q_i
    zp = Rp * (w / det) * qy
    zm = -Rm * (w / det) * qy
    # left vector: t_(i,+-) = R_+- v_(i,+-)^T y, v_(i,+-) = l_+- q_i
    tp = Rp * lp * qy
    tm = Rm * lm * qy
    # back to the scaled state: X0 column (i,+-) = [w_i e_i; l_+- e_i]; X0^-1 rows (1/det)[[lm, -w], [-lp, w]]
    V = np.concatenate([w * (zp + zm), lp * zp + lm * zm], axis=1).T          # (2r, r)
    Wl = np.concatenate([(tp * lm - tm * lp) / det, (-tp + tm) * w / det], axis=1)  # (r, 2r)
    V /= np.linalg.norm(V, axis=0)
    dots = np.einsum("jn,nj->j", Wl, V)
    cond = np.linalg.norm(Wl, axis=1) / np.abs(dots)
    if not np.all(np.isfinite(cond)) or cond.max() > _MAX_CONDITION:
        return None
    Wl = Wl / dots[:, None]
    # residual of every pair, with A applied in O(r k) per vector
    qv = Q @ V[r:]                                                   # (k, r_eig)
    AV = np.concatenate([w[:, None] * V[r:], -w[:, None] * V[:r] - d[:, None] * V[r:] - Q.T @ qv])
    res = np.linalg.norm(AV - V * lam, axis=0) / (np.abs(lam) + np.abs(d).max())
    trace = -(d.sum() + np.sum(Q * Q))
    if res.max() > _RESIDUAL_TOL or abs(2 * lam.real.sum() - trace) > _TRACE_TOL * abs(trace):
        return None
    return lam, V, Wl
