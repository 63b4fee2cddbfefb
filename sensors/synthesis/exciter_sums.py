"""Phase-0 states of periodic steady states from one period's geometric sums, without samples.

A complex mode z[n+1] = a z[n] + G0 u[n] + G1 u[n+1] under an input repeating the P samples
u passes phase 0 of its periodic steady state at

    z0 = (G0 T_a + G1 (a T_a + u[0] (1 - a^P))) / (1 - a^P),   T_p = sum_{n<P} p^(P-1-n) u[n]

(the sum over u[n+1] is the one over u[n] shifted by a sample: p T_p + u[0] (1 - p^P)).  So
one number per pole, T_p, is all a mode needs of the input (:class:`ExciterSums`: the period
blocked once, then a real matrix product for any set of poles).

The object is driven by the fingertip drive's steady output y[n] = Re(c . x[n]) + D u[n],
x_j[n+1] = a_j x_j[n] + v_j[n] (the drive's complex modes, v_j = g0_j u[n] + g1_j u[n+1]).
For an object pole b the sum of a periodic x_j follows from its recurrence,

    T_b(x_j) = (T_b(v_j) - x_j[0] (1 - b^P)) / (b - a_j),

(and likewise for conj(x_j)), so the object's phase-0 state needs the exciter's sums at its
own poles and the drive's phase-0 state, never the drive's P samples
(:class:`SteadyDrive`).  The same sums as ``EigenPart.periodic_start`` of the drive's
period, to rounding (``tests/test_exciter_sums.py``).
"""

from __future__ import annotations

import numpy as np

from .lti import EigenPart

__all__ = ["ExciterSums", "SteadyDrive"]


def _falling_powers(base: np.ndarray, count: int) -> np.ndarray:
    """Row r of the (count, K) result holds base^(count-1-r): by doubling, log2(count) vector
    products (rounding growing like log2(count), no complex exponential per power)."""
    out = np.empty((count, len(base)), dtype=complex)
    out[count - 1] = 1.0
    done, step = 1, base.astype(complex)
    while done < count:
        k = min(done, count - done)
        np.multiply(out[count - k:], step, out=out[count - done - k:count - done])
        done += k
        step = step * step
    return out


class ExciterSums:
    """One input period ``u`` (P samples, looped), blocked for its geometric sums: M blocks of
    B ~ sqrt(P) samples, left-padded with zeros (read-only, 8 M B bytes, about 8 P)."""

    def __init__(self, period: np.ndarray) -> None:
        u = np.asarray(period, dtype=float)
        P = len(u)
        self.period_samples = P
        self.first = float(u[0])
        self.input_max = float(np.abs(u).max(initial=0.0))       # max |u|
        self.block = max(1, int(np.ceil(np.sqrt(P))))
        self.blocks_n = -(-P // self.block)
        X = np.zeros(self.blocks_n * self.block)
        X[len(X) - P:] = u
        self._blocks = X.reshape(self.blocks_n, self.block)
        self._blocks.setflags(write=False)

    def sums(self, log_poles: np.ndarray) -> np.ndarray:
        """T_p = sum_{n<P} p^(P-1-n) u[n] for the poles p = exp(log_poles): per block one
        real matrix product with p^(B-1-j), then the blocks weighted by p^((M-1-m) B)."""
        lp = np.asarray(log_poles, dtype=complex)
        K, B, M = len(lp), self.block, self.blocks_n
        # p^(B-1-j) and (p^B)^(M-1-m) in one doubling run (M <= B: the last M rows)
        powers = _falling_powers(np.exp(np.concatenate([lp, lp * B])), B)
        # complex (B, K) seen as real (B, 2K) with each pole's real and imaginary parts side by
        # side: the product's rows are then the complex block sums seen as real
        inner = (self._blocks @ np.ascontiguousarray(powers[:, :K]).view(float)).view(complex)   # (M, K)
        return np.einsum("mk,mk->k", powers[B - M:, K:], inner)

    def start(self, part: EigenPart) -> np.ndarray:
        """The coordinates of ``part`` at phase 0 of its periodic steady state under this
        period (``part.periodic_start(u)``)."""
        log_a = part.lam * part.T
        T = self.sums(log_a)
        gap = -np.expm1(log_a * self.period_samples)                     # 1 - a^P
        return (part.G0 * T + part.G1 * (part.a * T + self.first * gap)) / gap


class SteadyDrive:
    """A driving system in complex modes (``drive``, observed at the output that drives) in its
    periodic steady state under the period of ``sums``, passing phase 0 at ``start_coords``:
    :meth:`start` gives the phase-0 state of any system this output drives (module docstring).
    """

    def __init__(self, sums: ExciterSums, drive: EigenPart, start_coords: np.ndarray) -> None:
        self.sums = sums
        self.drive = drive
        self.start_coords = start_coords
        self.period_samples = sums.period_samples
        self.first_output = float((drive.co @ start_coords).real) + drive.D * sums.first   # y[0]
        # the drive's modes and their conjugates side by side: y = D u + sum_j c_j x_j / 2
        self._modes = [np.concatenate([v, np.conj(v)]) for v in (drive.G0, drive.G1, drive.a, start_coords)]
        self._halves = 0.5 * np.concatenate([drive.co, np.conj(drive.co)])

    def start(self, part: EigenPart) -> np.ndarray:
        """The coordinates of ``part`` at phase 0 of its periodic steady state under the
        drive's steady output (``part.periodic_start(y)`` for y the output's period).  It divides
        by b - a_j for each pole b of ``part`` and a_j of the drive (and conj(a_j)): the caller
        keeps them apart (``window_spectra`` does: the drive's transient has those poles)."""
        g0, g1, a, x0 = self._modes
        log_b = part.lam * part.T
        b = part.a
        T = self.sums.sums(log_b)                                         # T_b(u)
        gap = -np.expm1(log_b * self.period_samples)                      # 1 - b^P
        T_next = b * T + self.sums.first * gap                            # T_b(u[n+1])
        Tx = (T[:, None] * g0 + T_next[:, None] * g1 - gap[:, None] * x0) / (b[:, None] - a)   # (K, 2J): T_b(x_j)
        Ty = Tx @ self._halves + self.drive.D * T
        return (part.G0 * Ty + part.G1 * (b * Ty + self.first_output * gap)) / gap
