"""The loops of :mod:`sensors.synthesis.low_rank_modes`, compiled by numba on first use
(:mod:`sensors._infra.jit`, ``error_model="numpy"``: a zero gap gives inf or nan, which the
caller checks for): plain Python here, ``jitted(vars(low_rank_kernels), name)`` there.

Notation as in :mod:`sensors.synthesis.low_rank_modes`: r modes with poles lp (Im > 0) and lm, weights
sp, sm of the contact update in A0's eigenbasis, Q (k, r) the contact factor, roots lam.
"""
from __future__ import annotations

import numpy as np


def recip(z):
    """1 / z as conj(z) / |z|^2: one real division instead of numba's branchy complex one
    (the gaps here are between poles of audio-rate modes, far from over- and underflow)."""
    s = 1.0 / (z.real * z.real + z.imag * z.imag)
    return complex(z.real * s, -z.imag * s)


def sweep_terms(L, idx, lam, lp, lm, sp, sm, S):
    """For each active root L[a] and mode i, with t = s / (L - pole) over the two poles of i:
    S[0] + i S[1] = sum t and S[2] + i S[3] = sum t / (L - pole) (real and imaginary parts
    apart, one real matrix product away from the k x k matrices); return sum_i 1/(L - pole)
    and the Aberth repulsion, sum over every other current root (and its conjugate)."""
    na, r = S.shape[1], S.shape[2]
    pole_sum = np.empty(na, np.complex128)
    repulsion = np.empty(na, np.complex128)
    for a in range(na):
        x = L[a]
        acc = 0j
        for i in range(r):
            rp = recip(x - lp[i])
            rm = recip(x - lm[i])
            acc += rp + rm
            t1 = rp * sp[i] + rm * sm[i]
            t2 = rp * rp * sp[i] + rm * rm * sm[i]
            S[0, a, i] = t1.real
            S[1, a, i] = t1.imag
            S[2, a, i] = t2.real
            S[3, a, i] = t2.imag
        pole_sum[a] = acc
        rep = 0j
        me = idx[a]
        for j in range(r):
            if j != me:
                rep += recip(x - lam[j])
            rep += recip(x - np.conj(lam[j]))
        repulsion[a] = rep
    return pole_sum, repulsion


def pole_terms(L, lp, lm, sp, sm, S, RP, RM):
    """S[0] + i S[1] = sum over the two poles of s / (L - pole) (the k x k matrix's weights at
    the roots L), and the reciprocals RP = 1 / (L - lp), RM = 1 / (L - lm) for the vectors."""
    for a in range(L.size):
        x = L[a]
        for i in range(lp.size):
            rp = recip(x - lp[i])
            rm = recip(x - lm[i])
            RP[a, i], RM[a, i] = rp, rm
            t = rp * sp[i] + rm * sm[i]
            S[0, a, i] = t.real
            S[1, a, i] = t.imag


def _unpack(R, a, c, iu, ju, sign, diagonal, out):
    """out (k x k) = sign (R[c, a] + i R[c + 1, a]) unpacked from the upper triangle (iu, ju),
    plus ``diagonal`` on the diagonal."""
    for t in range(iu.size):
        i, j = iu[t], ju[t]
        v = sign * (R[c, a, t] + 1j * R[c + 1, a, t])
        out[i, j] = v
        out[j, i] = v
    for i in range(out.shape[0]):
        out[i, i] += diagonal


def _eliminate(M, B):
    """Gaussian elimination with partial pivoting on [M | B] in place: M becomes U, B becomes
    L^-1 P B. Pivots by |re| + |im| (as LAPACK). Returns the smallest pivot (0: singular)."""
    k = M.shape[0]
    smallest = np.inf
    for p in range(k):
        best, piv = -1.0, p
        for i in range(p, k):
            m = abs(M[i, p].real) + abs(M[i, p].imag)
            if m > best:
                best, piv = m, i
        if piv != p:
            for j in range(k):
                M[p, j], M[piv, j] = M[piv, j], M[p, j]
            for j in range(B.shape[1]):
                B[p, j], B[piv, j] = B[piv, j], B[p, j]
        smallest = min(smallest, best)
        if best == 0.0:
            continue
        inv = recip(M[p, p])
        for i in range(p + 1, k):
            f = M[i, p] * inv
            if f != 0:
                for j in range(p + 1, k):
                    M[i, j] -= f * M[p, j]
                for j in range(B.shape[1]):
                    B[i, j] -= f * B[p, j]
    return smallest


def newton_traces(R, iu, ju, k, tr):
    """tr[a] = trace(M_a^-1 dM_a) with M_a = I - (R[0, a] + i R[1, a]) and dM_a = R[2, a] + i R[3, a]
    (symmetric, packed as the upper triangle iu, ju): d/dlambda log det M at each root, by
    elimination with partial pivoting and, per column j, back substitution down to row j only."""
    M = np.empty((k, k), np.complex128)
    B = np.empty((k, k), np.complex128)
    x = np.empty(k, np.complex128)
    for a in range(R.shape[1]):
        _unpack(R, a, 0, iu, ju, -1.0, 1.0, M)
        _unpack(R, a, 2, iu, ju, 1.0, 0.0, B)
        _eliminate(M, B)   # a zero pivot gives inf / nan in the trace: the caller's check
        acc = 0j
        for j in range(k):
            for i in range(k - 1, j - 1, -1):
                v = B[i, j]
                for m in range(i + 1, k):
                    v -= M[i, m] * x[m]
                x[i] = v * recip(M[i, i])
            acc += x[j]
        tr[a] = acc


def null_vectors(R, iu, ju, k, y):
    """y[a]: unit null vector of M_a = I - (R[0, a] + i R[1, a]) by one step of inverse
    iteration from a fixed probe (M_a is singular to rounding at a converged root; an exactly
    zero pivot is replaced by a tiny one, as LAPACK's inverse iteration does)."""
    M = np.empty((k, k), np.complex128)
    b = np.empty((k, 1), np.complex128)
    for a in range(R.shape[1]):
        _unpack(R, a, 0, iu, ju, -1.0, 1.0, M)
        scale = 0.0
        for i in range(k):
            b[i, 0] = 1.0 + i / max(k - 1, 1)
            for j in range(k):
                scale = max(scale, abs(M[i, j].real) + abs(M[i, j].imag))
        _eliminate(M, b)
        tiny = 1e-300 + 1e-16 * scale
        norm2 = 0.0
        for i in range(k - 1, -1, -1):
            v = b[i, 0]
            for m in range(i + 1, k):
                v -= M[i, m] * y[a, m]
            piv = M[i, i] if abs(M[i, i].real) + abs(M[i, i].imag) > tiny else complex(tiny)
            y[a, i] = v * recip(piv)
            norm2 += y[a, i].real * y[a, i].real + y[a, i].imag * y[a, i].imag
        s = 1.0 / np.sqrt(norm2)
        for i in range(k):
            y[a, i] *= s


def vectors(rows, lam, RP, RM, lp, lm, w, wdet, rdet, qy, VT, Wl, cond):
    """For the roots a = rows[t]: right vector VT[a] (a unit row) and left row Wl[a]
    (Wl[a] . VT[a] = 1) in the scaled state, from qy[t, i] = q_i^T y (y: null vector of the
    root's k x k matrix) and RP, RM (rows t) from :func:`pole_terms` (wdet = w / det,
    rdet = 1 / det), and cond[a] = |Wl_a| |V_a| / |Wl_a V_a| (inf if degenerate)."""
    r = lp.size
    for t in range(rows.size):
        a = rows[t]
        norm2 = 0.0
        for i in range(r):
            rp, rm = RP[t, i], RM[t, i]
            g = wdet[i] * qy[t, i]
            # right: z_(i,+-) = +-R_+- (w/det) q_i^T y; X0 column (i,+-) = [w e_i; l_+- e_i]
            zp, zm = rp * g, -rm * g
            v1 = w[i] * (zp + zm)
            v2 = lp[i] * zp + lm[i] * zm
            VT[a, i], VT[a, r + i] = v1, v2
            norm2 += v1.real * v1.real + v1.imag * v1.imag + v2.real * v2.real + v2.imag * v2.imag
            # left: t_(i,+-) = R_+- l_+- q_i^T y; X0^-1 rows (1/det) [[lm, -w], [-lp, w]]
            tp, tm = rp * lp[i] * qy[t, i], rm * lm[i] * qy[t, i]
            Wl[a, i] = (tp * lm[i] - tm * lp[i]) * rdet[i]
            Wl[a, r + i] = (tm - tp) * wdet[i]
        scale = 1.0 / np.sqrt(norm2)
        dot = 0j
        wn2 = 0.0
        for i in range(2 * r):
            VT[a, i] *= scale
            dot += Wl[a, i] * VT[a, i]
            wn2 += Wl[a, i].real * Wl[a, i].real + Wl[a, i].imag * Wl[a, i].imag
        c = np.sqrt(wn2) / abs(dot)
        cond[a] = c if c < np.inf else np.inf  # nan (a zero vector) counts as degenerate
        rdot = 1.0 / dot
        for i in range(2 * r):
            Wl[a, i] *= rdot


def residuals(rows, lam, w, d, dmax, VT, GV, res):
    """res[a] = ||A v - lambda v|| / (|lambda| + dmax) for the unit rows v = VT[a], a = rows[t],
    with A = [[0, Omega], [-Omega, -diag(d) - G]] applied in O(r) per entry (GV[t] = G v_low)."""
    r = w.size
    for t in range(rows.size):
        a = rows[t]
        x = lam[a]
        acc = 0.0
        for i in range(r):
            top = w[i] * VT[a, r + i] - x * VT[a, i]
            bottom = -w[i] * VT[a, i] - d[i] * VT[a, r + i] - GV[t, i] - x * VT[a, r + i]
            acc += top.real * top.real + top.imag * top.imag + bottom.real * bottom.real + bottom.imag * bottom.imag
        res[a] = np.sqrt(acc) / (abs(x) + dmax)
