"""Exact discretisation of a linear time-invariant system driven by a sampled signal.

    x' = A x + B u,   y = Cout x + D u.

The input is taken as piecewise linear between samples (first-order hold, "ramp
invariant"), which makes the discretisation exact for such an input:

    x[n+1] = Phi x[n] + Gamma0 u[n] + Gamma1 u[n+1],   Phi = exp(A T).

Zero-order hold (``hold="zoh"``) keeps u constant over a sample (Gamma1 = 0); it is wrong by
tens of percent near Nyquist and exists for comparison.

Complex modes
-------------
A = V diag(lambda) V^-1 (under-, critically and over-damped modes alike).  For zero initial
state the output is a convolution of u with one real impulse response

    h[0] = Re sum_k c_k beta1_k + D,   h[l] = Re sum_k d_k a_k^(l-1)  (l >= 1),   a_k = e^(lambda_k T),

computed for all l at once by a blocked matrix product (rows a_k^(mB), columns a_k^j) and
applied with one FFT convolution.  Conjugate pairs are folded (one eigenvalue per pair, weight
2).  When V is ill-conditioned (defective / nearly repeated eigenvalues, e.g. a mode at
critical damping) the same sums are evaluated with powers of the real matrix Phi obtained from
an augmented matrix exponential instead ("dense" fallback, exact to rounding, slower).
Impulse responses are cut where every term has decayed below 1e-17 of their total.

A system is a list of parts (:class:`EigenPart`, :class:`DensePart`): independent
subsystems on disjoint index sets of one state vector, whose outputs add up.  For a periodic
input, :meth:`DiscreteSystem.periodic_response` gives the exact periodic steady state (one
circular convolution, i.e. one complex gain per harmonic of the loop frequency), and
:class:`SteadyState` holds one.  ``sensors.synthesis.modal_system`` builds the parts of a
modal system; :func:`lti_system` those of any small system (the fingertip drive).

Band-limited periodic inputs
----------------------------
A sound card does not play its samples piecewise linear: it plays the band-limited signal
through them.  For a looped input that signal is a finite Fourier series (harmonics of the
loop frequency up to Nyquist; the Nyquist harmonic taken as a cosine), and each mode's
response to each harmonic is closed form, g / (j w - lambda).  ``bandlimited=True`` in
:meth:`DiscreteSystem.periodic_response`, :meth:`DiscreteSystem.periodic_state` and
:class:`SteadyState` evaluates that exactly, for the band-limited signal whose harmonics are
those of the hold's interpolant of the samples without its images: U_m S(f_m), with
S = sinc^2(f / fs) for the first-order hold (:func:`hold_gain`).  Samples prefiltered by
1 / S (:func:`bandlimited_samples`) therefore stand for the band-limited signal through the
original samples, in the periodic (exact) and in the time-domain (FOH) evaluation alike; the
latter adds only the hold's images (see ``sensors.synthesis.bandlimit``).
"""

from __future__ import annotations

import copy
import math

import numpy as np

from .mkl_eigen import mkl_eig

__all__ = ["DiscreteSystem", "EigenPart", "DensePart", "SteadyState", "SETTLE_E_FOLDS", "MAX_EIGVEC_COND", "lti_system", "lti_parts",
           "force_signal", "hold_gain", "bandlimited_samples", "one_blas_thread", "scipy_linalg",
           "DIRECT_CONVOLUTION_PRODUCTS", "MKL_EIGEN", "VECTORIZED_PHI12", "phi12"]

_HOLDS = ("foh", "zoh")
#: cond(V) above this: the complex-mode sums lose more than ~1e-8 relative -> dense fallback.
MAX_EIGVEC_COND = 1e8
# Impulse responses are cut once every term is below this fraction of the terms' sum.
_DECAY_TOL = 1e-17

#: A system counts as in periodic steady state after its slowest mode decayed this many
#: e-folds under a periodic input: exp(-30) ~ 1e-13 of the transient is left.
SETTLE_E_FOLDS = 30.0

#: Whether the state matrix's eigen-decomposition is MKL's ``dgeev`` when MKL is installed (True,
#: fast: about half the time, ``sensors.synthesis.mkl_eigen``) or SciPy's (False, the reference).
#: The same decomposition to rounding (``tests/test_lti_mkl_eigen.py``).  Read at each call.
MKL_EIGEN = True

#: A drive convolution of at most this many products (signal length times impulse-response
#: length) is summed directly (``np.convolve``) instead of by FFT: a stream's span of one
#: physics step (about 88 samples) costs 8 us instead of 150 us of FFT set-up, and both round
#: at ~1e-16 of the largest sample (the direct sum at least as well).  0: always by FFT (the
#: reference path; ``tests/test_direct_convolution.py``).  Read at each call.
DIRECT_CONVOLUTION_PRODUCTS = 1 << 18

#: Whether phi1/phi2 (each eigen-part's hold gains) sum their Taylor series as one matrix
#: product of the powers of x with the coefficients (True, fast: 8 numpy calls instead of ~150,
#: 0.06-0.08 ms less per part) or term by term (False, the reference).  The sums' order differs,
#: so the two agree to rounding (~4e-16 relative), not bit for bit; each value depends on its own
#: x only (not on the array's length), and both are checked against
#: ``scipy.linalg.expm`` of the augmented matrix in ``tests/test_lti_phi12.py``.  Read at each call.
VECTORIZED_PHI12 = True

#: Whether a modal system's input gains V^-1 B come from its eigenvectors' S-orthogonality when
#: the caller names a signature S with S A symmetric (True, fast), or from an LU factorization
#: of V (False, the reference).  A = [[0, W], [-W, -C]] with C symmetric has A^T = S A S,
#: S = diag(I, -I), so S v_j is a left eigenvector and v_j^T S v_k = 0 for distinct
#: eigenvalues: V^-1 B = (v_k^T S B / v_k^T S v_k)_k, O(n^2) instead of the complex LU, its
#: condition estimate and solve (0.44 of 3.4 ms of a FillLevel-v0 system).  Taken only where
#: the reference takes complex modes too (its 1-norm condition number of V is at most
#: sqrt(n) sum_k 1 / |v_k^T S v_k| < MAX_EIGVEC_COND / 2, a bound the reference's estimate cannot
#: exceed) and where V g reproduces B to 1e-13 (a repeated eigenvalue's vectors need not be
#: S-orthogonal: the LU then decides).  The inverse's rows for state maps stay the reference's
#: (lazy LU).  The gains agree to rounding (``tests/test_symmetric_gains.py``: 1e-11 of the
#: largest, and the transfer function to 1e-9 of the dense one).  Read at each call.
SYMMETRIC_GAINS = True
# V g against B, relative to the largest of |B| and the sum of |v_k g_k| (rounding: ~1e-16).
_GAINS_RESIDUAL = 1e-13

# Taylor terms of phi1, phi2 at |x| < 1: the 25th is below 1/26! ~ 2.5e-27 of the first.
_TAYLOR_TERMS = 25
# (2, terms): 1/(k+1)! and 1/(k+2)!, correctly rounded from exact integers
_TAYLOR_COEFFS = np.array([[1.0 / math.factorial(k + j) for k in range(_TAYLOR_TERMS)] for j in (1, 2)])


# ----------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------

def phi12(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phi1(x) = (e^x - 1)/x and phi2(x) = (e^x - 1 - x)/x^2, accurate for all complex x."""
    x = np.asarray(x, dtype=complex)
    small = np.abs(x) < 1.0
    xs = np.where(small, x, 0.0)
    xl = np.where(small, 1.0, x)
    if VECTORIZED_PHI12:
        flat = xs.reshape(1, -1)
        powers = np.empty((_TAYLOR_TERMS, flat.shape[1]), complex)  # row k: x^k
        powers[:1] = 1.0
        np.cumprod(np.broadcast_to(flat, (_TAYLOR_TERMS - 1, flat.shape[1])), axis=0, out=powers[1:])
        # real coefficients times the (re, im) pairs: one real product for both series, by
        # einsum (in term order per element; BLAS would round by the array's width)
        series = np.einsum("jk,kn->jn", _TAYLOR_COEFFS, powers.view(float)).view(complex)  # (2, n)
        p1, p2 = series[0].reshape(x.shape), series[1].reshape(x.shape)
        em1 = np.expm1(xl)
        return np.where(small, p1, em1 / xl), np.where(small, p2, (em1 - xl) / (xl * xl))
    # Taylor series: phi1 = sum x^k/(k+1)!, phi2 = sum x^k/(k+2)!; 25 terms -> < 1e-25 at |x|<1
    p1 = np.zeros_like(x)
    p2 = np.zeros_like(x)
    term = np.ones_like(x)
    fact1, fact2 = 1.0, 2.0
    for k in range(25):
        p1 = p1 + term / fact1
        p2 = p2 + term / fact2
        term = term * xs
        fact1 *= k + 2
        fact2 *= k + 3
    em1 = np.expm1(xl)
    l1 = em1 / xl
    l2 = (em1 - xl) / (xl * xl)
    return np.where(small, p1, l1), np.where(small, p2, l2)


def _block(n: int) -> tuple[int, int]:
    """Block length B and number of blocks M with M*B >= n, B ~ sqrt(n)."""
    b = max(1, int(np.ceil(np.sqrt(n))))
    return b, -(-n // b)


def _powers(base: np.ndarray, count: int) -> np.ndarray:
    """base_k^j for j < count, shape (K, count), by doubling: log2(count) vector products
    (complex exp is ~5x slower than a product; rounding grows only like log2(count))."""
    out = np.empty((len(base), count), dtype=complex)
    out[:, 0] = 1.0
    s = 1
    step = base.astype(complex)
    while s < count:
        k = min(s, count - s)
        np.multiply(out[:, :k], step[:, None], out=out[:, s:s + k])
        s += k
        step = step * step
    return out


def _blocked_steps(u: np.ndarray) -> tuple[int, int, np.ndarray]:
    """The len(u)-1 steps' end-point forces (u[n], u[n+1]) left-padded with zeros into M
    blocks of B: (B, M, X) with X of shape (2, M, B), the last step in the last column."""
    L = len(u) - 1
    Bk, M = _block(L)
    pad = M * Bk - L
    X = np.zeros((2, M * Bk))
    X[0, pad:] = u[:-1]
    X[1, pad:] = u[1:]
    return Bk, M, X.reshape(2, M, Bk)


def _convolve(u: np.ndarray, h: np.ndarray, n: int) -> np.ndarray:
    """First n samples of the linear convolution u * h."""
    if len(h) == 0:
        return np.zeros(n)
    if len(u) * len(h) <= DIRECT_CONVOLUTION_PRODUCTS:
        return np.convolve(u, h)[:n]
    import scipy.signal as ssig  # ~0.5 s to import (-X importtime): first use only

    if len(h) * 8 < len(u) and len(h) > 64:
        return ssig.oaconvolve(u, h)[:n]
    return ssig.fftconvolve(u, h)[:n]


def force_signal(force_n) -> np.ndarray:
    """A sampled input [N] as a finite 1-D float array (ValueError otherwise)."""
    u = np.asarray(force_n, dtype=float)
    if u.ndim != 1:
        raise ValueError(f"force_n must be a 1-D signal [N], got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("force_n contains NaN or inf")
    return u


def hold_gain(freq_hz, sample_rate_hz: float, hold: str = "foh") -> np.ndarray:
    """Baseband gain of a hold's interpolant of sampled data at ``freq_hz``, relative to the
    band-limited signal through the same samples: sinc^2(f / fs) for the first-order hold
    (piecewise linear, zero phase), sinc(f / fs) e^(-j pi f / fs) for the zero-order hold."""
    if hold not in _HOLDS:
        raise ValueError(f"hold must be one of {_HOLDS}, got {hold!r}")
    x = np.asarray(freq_hz, dtype=float) / float(sample_rate_hz)
    s = np.sinc(x)
    return (s * s).astype(complex) if hold == "foh" else s * np.exp(-1j * np.pi * x)


def bandlimited_samples(period, passes: int = 1, hold: str = "foh") -> np.ndarray:
    """One period of a looped signal prefiltered by 1 / S^passes per harmonic (S:
    :func:`hold_gain`), so that ``passes`` cascaded hold discretisations see the band-limited
    signal through ``period`` in their baseband (exact per harmonic: a circular filter)."""
    u = force_signal(period)
    P = len(u)
    if P == 0:
        return u.copy()
    S = hold_gain(np.arange(P // 2 + 1) / P, 1.0, hold)
    return np.fft.irfft(np.fft.rfft(u) / S ** int(passes), P)


def _harmonics(u: np.ndarray, sample_rate_hz: float, hold: str):
    """The band-limited periodic signal of the samples ``u`` (one period, the hold's
    interpolant without its images): angular frequencies [rad/s] of harmonics 0 .. P // 2,
    their one-sided weights (2, or 1 for DC and Nyquist) and complex amplitudes, so that the
    signal is Re sum_m alpha_m c_m e^(j w_m t) (the Nyquist harmonic a cosine)."""
    P = len(u)
    m = np.arange(P // 2 + 1)
    c = np.fft.rfft(u) / P * hold_gain(m / P, 1.0, hold)
    if P % 2 == 0:
        c[-1] = c[-1].real         # the Nyquist harmonic as a cosine (its sine is 0 at every sample)
    alpha = np.full(len(m), 2.0)
    alpha[0] = 1.0
    if P % 2 == 0:
        alpha[-1] = 1.0
    return 2 * np.pi * m * (sample_rate_hz / P), alpha, c


class EigenPart:
    """Complex-mode form: coordinates z (one eigenvalue per conjugate pair).

    ``idx``: indices of its state in the system's state vector; ``lam`` (K,), ``V`` (n, K) and
    ``Vinv`` (K, n, an array or computed on first use) for the kept eigenvalues, conjugate
    partners folded by the weight w (2 for a pair, 1 if real); ``g``: V^-1 B if known.
    """

    def __init__(self, idx, lam, V, Vinv, B, Cout, D, T, hold, g=None):
        self.idx = idx
        self.lam = lam
        self.w = np.where(lam.imag > 0, 2.0, 1.0)
        self.V = V
        self._vinv = Vinv  # array or LazyInverseRows
        self.T = T
        x = lam * T
        self.a = np.exp(x)
        phi1, phi2 = phi12(x)
        if hold == "foh":
            self.b0, self.b1 = T * (phi1 - phi2), T * phi2
        else:
            self.b0, self.b1 = T * phi1, np.zeros_like(phi1)
        self.g = self.Vinv @ B if g is None else g  # input gain per eigen-coordinate
        self.co = self.w * (Cout @ V)       # output row (weight folded in)
        self.D = float(D)
        self.G0 = self.g * self.b0
        self.G1 = self.g * self.b1

    def with_output(self, Cout, D: float = 0.0) -> "EigenPart":
        """This part with the output row ``Cout`` (its own indices) and feedthrough ``D``:
        the eigen-decomposition, its lazily inverted rows and the input gains are shared."""
        part = copy.copy(self)
        part.co = self.w * (np.asarray(Cout, dtype=float) @ self.V)
        part.D = float(D)
        return part

    @property
    def Vinv(self):
        if isinstance(self._vinv, LazyInverseRows):
            self._vinv = self._vinv.get()
        return self._vinv

    # coordinates ------------------------------------------------------------------------
    def to_coords(self, x):
        return self.Vinv @ x

    def from_coords(self, z):
        return (self.V @ (self.w * z)).real

    def step(self, z):
        return self.a * z

    def direct(self):
        """C Gamma1 + D: the weight of u[n] in y[n]."""
        return float((self.co @ self.G1).real) + self.D

    def output(self, x) -> float:
        """Cout x for a state x of this part (its own indices)."""
        return float((self.co @ self.to_coords(x)).real)

    # sums -------------------------------------------------------------------------------
    def decay_length(self, coeffs: np.ndarray, n: int) -> int:
        mag = np.abs(coeffs).max(axis=0) * np.abs(self.co)
        tot = mag.sum()
        if tot == 0.0:
            return 0
        rate = self.lam.real * self.T  # log|a| per sample
        need = mag > tot * _DECAY_TOL
        if np.any(need & (rate >= 0.0)):
            return n
        with np.errstate(divide="ignore"):
            lk = np.log(tot * _DECAY_TOL / mag[need]) / rate[need]
        return int(min(n, np.ceil(lk.max()) + 2)) if lk.size else 0

    def power_sums(self, vs: np.ndarray, n: int) -> np.ndarray:
        """out[s, l] = Re(C Phi^l v_s), l < n, for coordinate vectors vs (S, K)."""
        S, K = vs.shape
        L = self.decay_length(vs, n)
        if L == 0:
            return np.zeros((S, n))
        Bk, M = _block(L)
        coef = vs * self.co                                            # (S, K)
        aB = np.exp(self.lam * (self.T * Bk))
        rows = coef[:, None, :] * _powers(aB, M).T[None]                # (S, M, K): c a^(mB)
        cols = _powers(self.a, Bk)                                       # (K, Bk): a^j
        # Re(P Q) = Re P Re Q - Im P Im Q as one real matrix product
        P = np.empty((S, M, 2 * K))
        P[:, :, :K] = rows.real
        np.negative(rows.imag, out=P[:, :, K:])
        Q = np.empty((2 * K, Bk))
        Q[:K] = cols.real
        Q[K:] = cols.imag
        out = (P.reshape(S * M, 2 * K) @ Q).reshape(S, M * Bk)
        if L == n:
            return out[:, :n]
        full = np.zeros((S, n))
        full[:, :L] = out[:, :L]
        return full

    def propagate(self, z0, u: np.ndarray) -> np.ndarray:
        """Coordinates after len(u)-1 steps from z0 under the piecewise-linear force u."""
        L = len(u) - 1
        lt = self.lam * self.T
        Bk, M, X = _blocked_steps(u)
        qrev = np.exp(np.outer(np.arange(Bk - 1, -1, -1), lt))         # (Bk, K): a^(B-1-j)
        inner = (X @ qrev.real) + 1j * (X @ qrev.imag)                  # (2, M, K)
        outer = np.exp(np.outer(np.arange(M - 1, -1, -1) * Bk, lt))    # (M, K)
        S = np.einsum("smk,mk->sk", inner, outer)
        z = self.G0 * S[0] + self.G1 * S[1]
        if z0 is not None:
            z = z + np.exp(lt * L) * z0
        return z

    def free(self, z, steps: int):
        """Coordinates ``steps`` samples after z without input (as :meth:`propagate`'s z0 term)."""
        return np.exp(self.lam * self.T * steps) * z

    def periodic_vector(self, v, P: int):
        return v / (1.0 - np.exp(self.lam * self.T * P))

    def periodic_start(self, u_period: np.ndarray) -> np.ndarray:
        """Coordinates at phase 0 of the periodic steady state under the piecewise-linear
        force that repeats ``u_period``: ``periodic_vector(propagate(None, u + u[:1]), P)``,
        the blocked sums taking the powers of a by products (``_powers``, rounding growing
        like log2 of the block length) instead of one complex exponential per mode and
        power, which cost more than the sums for a few dozen modes."""
        u = np.asarray(u_period, dtype=float)
        P = len(u)
        Bk, M, X = _blocked_steps(np.concatenate([u, u[:1]]))
        K = len(self.a)
        q = _powers(self.a, Bk)[:, ::-1]                                        # (K, Bk): a^(B-1-j)
        Q = np.empty((Bk, 2 * K))                                               # real, imaginary parts
        Q[:, :K] = q.real.T
        Q[:, K:] = q.imag.T
        inner = (X.reshape(2 * M, Bk) @ Q).reshape(2, M, 2 * K)                 # one real product
        outer = _powers(np.exp(self.lam * (self.T * Bk)), M)[:, ::-1].T        # (M, K): a^((M-1-m) B)
        S = np.einsum("smk,mk->sk", inner[:, :, :K] + 1j * inner[:, :, K:], outer)
        return self.periodic_vector(self.G0 * S[0] + self.G1 * S[1], P)

    # continuous time (band-limited inputs) ----------------------------------------------
    def frequency_response(self, omega: np.ndarray) -> np.ndarray:
        """Cout (j w - A)^-1 B + D at angular frequencies ``omega`` [rad/s], both members of a
        conjugate pair summed (closed form per mode)."""
        s = 1j * np.asarray(omega, dtype=float)
        cg = (self.co / self.w) * self.g                       # residue of each kept eigenvalue
        H = cg @ (1.0 / (s[None, :] - self.lam[:, None]))
        pair = self.w == 2.0
        if pair.any():
            H = H + np.conj(cg[pair]) @ (1.0 / (s[None, :] - np.conj(self.lam[pair])[:, None]))
        return H + self.D

    def periodic_coords(self, omega, alpha, c, t_s: float) -> np.ndarray:
        """Coordinates at time ``t_s`` of the periodic steady state under the real signal
        Re sum alpha_m c_m e^(j w_m t) (see ``_harmonics``): both signs of each harmonic."""
        e = alpha * c * np.exp(1j * np.asarray(omega) * t_s)
        s = 1j * np.asarray(omega, dtype=float)
        pos = (1.0 / (s[None, :] - self.lam[:, None])) @ e
        neg = (1.0 / (-s[None, :] - self.lam[:, None])) @ np.conj(e)
        return 0.5 * self.g * (pos + neg)

    def transition(self):
        return (self.V @ (self.w[:, None] * self.a[:, None] * self.Vinv)).real


class DensePart:
    """Real state-space form with Phi from an augmented matrix exponential (robust); ``idx``
    as :class:`EigenPart`."""

    def __init__(self, idx, A, B, Cout, D, T, hold):
        n = A.shape[0]
        self.idx = idx
        self.A = A
        self.T = T
        aug = np.zeros((n + 2, n + 2))
        aug[:n, :n] = A
        aug[:n, n] = B
        aug[n, n + 1] = 1.0
        E = scipy_linalg().expm(aug * T)
        self.Phi = E[:n, :n]
        F1, F2 = E[:n, n], E[:n, n + 1]
        if hold == "foh":
            self.G0, self.G1 = F1 - F2 / T, F2 / T
        else:
            self.G0, self.G1 = F1, np.zeros(n)
        self.C = Cout
        self.D = float(D)
        self.B0 = np.asarray(B, dtype=float)
        self._phiB = {}

    def with_output(self, Cout, D: float = 0.0) -> "DensePart":
        """This part with the output row ``Cout`` and feedthrough ``D`` (Phi, the input
        gains and the cached powers of Phi, which depend on A only, are shared)."""
        part = copy.copy(self)
        part.C = np.asarray(Cout, dtype=float)
        part.D = float(D)
        return part

    def to_coords(self, x):
        return np.asarray(x, dtype=float)

    def from_coords(self, z):
        return np.asarray(z, dtype=float)

    def step(self, z):
        return self.Phi @ z

    def direct(self):
        return float(self.C @ self.G1) + self.D

    def output(self, x) -> float:
        return float(self.C @ np.asarray(x, dtype=float))

    def _power(self, k: int) -> np.ndarray:
        if k not in self._phiB:
            self._phiB[k] = scipy_linalg().expm(self.A * (self.T * k))
        return self._phiB[k]

    def power_sums(self, vs: np.ndarray, n: int) -> np.ndarray:
        S = vs.shape[0]
        Bk, M = _block(n)
        cols = np.empty((S, self.Phi.shape[0], Bk))
        cur = np.asarray(vs, dtype=float).T.copy()                # (n_state, S)
        for j in range(Bk):
            cols[:, :, j] = cur.T
            cur = self.Phi @ cur
        PB = self._power(Bk)
        rows = np.empty((M, self.Phi.shape[0]))
        r = self.C.copy()
        for m in range(M):
            rows[m] = r
            r = r @ PB
        out = np.einsum("mi,sij->smj", rows, cols).reshape(S, M * Bk)
        return out[:, :n]

    def propagate(self, z0, u: np.ndarray) -> np.ndarray:
        L = len(u) - 1
        Bk, M, X = _blocked_steps(u)
        ns = self.Phi.shape[0]
        g = np.empty((ns, Bk, 2))                                   # Phi^(B-1-j) Gamma
        cur = np.stack([self.G0, self.G1], axis=1)
        for j in range(Bk - 1, -1, -1):
            g[:, j, :] = cur
            cur = self.Phi @ cur
        inner = np.einsum("ijs,smj->mi", g, X)                      # (M, ns)
        PB = self._power(Bk)
        acc = np.zeros(ns)
        for m in range(M):
            acc = PB @ acc + inner[m]
        if z0 is not None:
            acc = acc + self._power(L) @ z0
        return acc

    def free(self, z, steps: int):
        """State ``steps`` samples after z without input (Phi^steps z; not kept among the
        powers :meth:`_power` caches, as a stream's jumps come at any sample)."""
        return scipy_linalg().expm(self.A * (self.T * int(steps))) @ z

    def periodic_vector(self, v, P: int):
        return np.linalg.solve(np.eye(self.Phi.shape[0]) - self._power(P), v)

    # continuous time (band-limited inputs) ----------------------------------------------
    def _resolvent_b(self, omega: np.ndarray) -> np.ndarray:
        """(j w - A)^-1 B for each w [rad/s], (n, M): back substitution in the complex
        Schur form, vectorised over the frequencies (robust where eigenvectors are not)."""
        if getattr(self, "_schur", None) is None:
            T, Z = scipy_linalg().schur(self.A.astype(complex), output="complex")
            self._schur = (T, Z, Z.conj().T @ self.B0)
        T, Z, zb = self._schur
        s = 1j * np.asarray(omega, dtype=float)
        n = T.shape[0]
        X = np.empty((n, len(s)), dtype=complex)
        for i in range(n - 1, -1, -1):
            X[i] = (zb[i] + T[i, i + 1:] @ X[i + 1:]) / (s - T[i, i])
        return Z @ X

    def frequency_response(self, omega: np.ndarray) -> np.ndarray:
        return self.C @ self._resolvent_b(omega) + self.D

    def periodic_coords(self, omega, alpha, c, t_s: float) -> np.ndarray:
        e = alpha * c * np.exp(1j * np.asarray(omega) * t_s)
        return (self._resolvent_b(omega) @ e).real

    def transition(self):
        return self.Phi


# ----------------------------------------------------------------------------------------
# the discretised system
# ----------------------------------------------------------------------------------------

class DiscreteSystem:
    """An exactly discretised LTI system: parts on index sets of one state vector.

    Build with :func:`lti_system` (any small system) or ``ModalSystem.build`` (an object's
    modes), then evaluate as often as needed.  ``state_size`` is the length of the state
    vectors it takes and returns.
    """

    def __init__(self, parts, state_size: int, sample_rate_hz: float, hold: str):
        self.parts = parts
        self.state_size = int(state_size)
        self.sample_rate_hz = float(sample_rate_hz)
        self.hold = hold

    def with_output(self, Cout, D: float = 0.0) -> "DiscreteSystem":
        """The same state equation observed through another output y = Cout x + D u
        (``state_size`` row; ``D`` goes to the first part): no new eigen-solve or matrix
        exponential, and the numbers of building it anew (the same decomposition of A)."""
        Cout = np.asarray(Cout, dtype=float).reshape(self.state_size)
        parts = [p.with_output(Cout[p.idx], D if i == 0 else 0.0) for i, p in enumerate(self.parts)]
        return DiscreteSystem(parts, self.state_size, self.sample_rate_hz, self.hold)

    def response(self, force_n, initial_state=None, jumps=()) -> np.ndarray:
        """Output for the sampled force [N] (one sample per force sample), float64.

        ``initial_state`` (``state_size``,) is the state at the first sample (default 0).
        Parts of the state a system does not simulate (a ``ModalSystem``'s dropped modes)
        are ignored.  ``jumps``: ``(k, dx)`` pairs, the state jumping by ``dx`` at sample k
        (0 < k < n, before that sample's output): equal, to rounding, to splitting the force
        at k and restarting from :meth:`final_state` plus dx, but with one convolution of the
        whole force (each jump adds only its free response, :meth:`free_state`).
        """
        u = force_signal(force_n)
        n = len(u)
        y = np.zeros(n)
        if n == 0:
            return y
        x0 = None if initial_state is None else np.asarray(initial_state, dtype=float)
        has_u = np.any(u != 0)
        for p in self.parts:
            z0 = None
            if x0 is not None:
                xs = x0[p.idx]
                if np.any(xs != 0):
                    z0 = p.to_coords(xs)
            zj = [(int(k), p.to_coords(dx[p.idx])) for k, dx in jumps if 0 < k < n and np.any(dx[p.idx] != 0)]
            if not has_u and z0 is None and not zj:
                continue
            vecs = []
            if has_u:
                vecs.append(p.step(p.G1) + p.G0)
                if u[0] != 0:
                    vecs.append(p.G1)
            if z0 is not None:
                vecs.append(z0)
            vecs += [z for _, z in zj]
            ps = p.power_sums(np.array(vecs), n)
            k = 0
            if has_u:
                # y[n] = direct u[n] + sum_l ps[0, l] u[n-1-l]  (h[0] = direct, h[l] = ps[l-1])
                y += p.direct() * u
                h = ps[0, : n - 1]
                L = _nonzero_length(h)
                if L:
                    y[1:] += _convolve(u[: n - 1], h[:L], n - 1)
                k = 1
                if u[0] != 0:
                    y -= u[0] * ps[1]
                    k = 2
            if z0 is not None:
                y += ps[k]
                k += 1
            for i, (at, _) in enumerate(zj):
                y[at:] += ps[k + i, : n - at]
        return y

    def free_state(self, state, steps: int) -> np.ndarray:
        """The state ``steps`` samples after ``state`` without input (parts of the state no
        part simulates: 0, as :meth:`final_state` leaves them)."""
        x0 = np.asarray(state, dtype=float)
        x = np.zeros(self.state_size)
        for p in self.parts:
            x[p.idx] = p.from_coords(p.free(p.to_coords(x0[p.idx]), steps))
        return x

    def final_state(self, force_n, initial_state=None) -> np.ndarray:
        """State at the LAST sample of ``force_n`` (after len-1 steps)."""
        u = force_signal(force_n)
        x = np.zeros(self.state_size)
        x0 = None if initial_state is None else np.asarray(initial_state, dtype=float)
        for p in self.parts:
            z0 = None if x0 is None else p.to_coords(x0[p.idx])
            z = z0 if len(u) < 2 else p.propagate(z0, u)
            if z is not None:
                x[p.idx] = p.from_coords(z)
        return x

    def output(self, state, u: float = 0.0) -> float:
        """The output at one sample from the state there and the input there: y = Cout x + D u
        (what :meth:`response` gives at the last sample of an input whose final state this is)."""
        x = np.asarray(state, dtype=float)
        y = 0.0
        for p in self.parts:
            y += p.output(x[p.idx]) + p.D * u
        return float(y)

    def frequency_response(self, freq_hz) -> np.ndarray:
        """The continuous-time system's transfer function Cout (j w - A)^-1 B + D at
        ``freq_hz`` [Hz] (complex; the simulated parts only), in closed form per mode."""
        omega = 2 * np.pi * np.atleast_1d(np.asarray(freq_hz, dtype=float))
        H = np.zeros(omega.shape, dtype=complex)
        for p in self.parts:
            H += p.frequency_response(omega)
        return H

    def periodic_response(self, force_period_n, bandlimited: bool = False, force_spectrum=None) -> np.ndarray:
        """Exact periodic steady state for a force that repeats ``force_period_n`` forever.

        One period of output; equals :meth:`response` of the looped force once the
        transient has decayed.  (Circular convolution with the period-aliased impulse
        response: one complex gain per harmonic of the loop frequency sample_rate_hz / P.)
        ``bandlimited``: the force is the band-limited signal of the hold's interpolant
        without its images (harmonics U_m S(f_m), see the module docstring), evaluated with
        the continuous-time transfer function per harmonic: no images fold into the band.
        ``force_spectrum``: ``np.fft.rfft`` of the force period if the caller has it (the
        same numbers; spares that transform when many systems take one input).
        """
        u = force_signal(force_period_n)
        P = len(u)
        y = np.zeros(P)
        if P == 0 or not np.any(u != 0):
            return y
        U = np.fft.rfft(u) if force_spectrum is None else force_spectrum
        if bandlimited:
            m = np.arange(P // 2 + 1)
            gain = hold_gain(m / P, 1.0, self.hold) * self.frequency_response(m * (self.sample_rate_hz / P))
            return np.fft.irfft(U * gain, P)
        for p in self.parts:
            v = p.periodic_vector(p.step(p.G1) + p.G0, P)
            ps = p.power_sums(np.array([v]), P)[0]
            hp = np.empty(P)
            hp[1:] = ps[: P - 1]
            hp[0] = p.direct() + ps[P - 1]
            y += np.fft.irfft(U * np.fft.rfft(hp), P)
        return y

    def periodic_state(self, force_period_n, bandlimited: bool = False, phase: int = 0) -> np.ndarray:
        """State at phase ``phase`` (default 0) of the periodic steady state under a force
        that repeats ``force_period_n`` forever (the state :meth:`periodic_response` runs
        through).  Sampled: x0 = Phi^P x0 + (one period from rest), solved per part in its
        own coordinates, then propagated to ``phase``; ``bandlimited``: the closed-form sum
        over the harmonics at that phase (as :meth:`periodic_response`)."""
        u = force_signal(force_period_n)
        P = len(u)
        x = np.zeros(self.state_size)
        if P == 0:
            return x
        if bandlimited:
            omega, alpha, c = _harmonics(u, self.sample_rate_hz, self.hold)
            t = (int(phase) % P) / self.sample_rate_hz
            for p in self.parts:
                x[p.idx] = p.from_coords(p.periodic_coords(omega, alpha, c, t))
            return x
        ext = np.concatenate([u, u[:1]])      # samples 0 .. P of the looped force
        for p in self.parts:
            x[p.idx] = p.from_coords(p.periodic_vector(p.propagate(None, ext), P))
        p0 = int(phase) % P
        return x if p0 == 0 else self.final_state(u[:p0 + 1], x)

    def slowest_decay_rate_per_s(self) -> float:
        """The smallest decay rate [1/s] of the simulated modes (0: one does not decay):
        a transient has fallen to exp(-k) of its start after k / rate seconds."""
        if getattr(self, "_slowest", None) is None:
            rates = []
            for p in self.parts:
                lam = p.lam if isinstance(p, EigenPart) else np.linalg.eigvals(p.A)
                rates.append(float(np.min(-np.real(lam))) if len(lam) else np.inf)
            self._slowest = max(0.0, min(rates)) if rates else np.inf
        return self._slowest

    def transition_matrix(self) -> np.ndarray:
        """One-step map Phi of the state (``state_size`` square; states no part simulates:
        identity)."""
        n = self.state_size
        Phi = np.eye(n)
        for p in self.parts:
            Phi[np.ix_(p.idx, p.idx)] = p.transition()
        return Phi

    @property
    def methods_used(self) -> list[str]:
        """'eigen' or 'dense' per part (diagnostics: which path was taken)."""
        return ["eigen" if isinstance(p, EigenPart) else "dense" for p in self.parts]


def _nonzero_length(h: np.ndarray) -> int:
    nz = np.flatnonzero(h)
    return int(nz[-1]) + 1 if nz.size else 0


# Multi-threaded BLAS makes the small dense eigenproblems here several times slower on a
# busy two-core machine (0.15 s vs 0.03 s for 204 x 204): they run on one thread.
_BLAS = None


def one_blas_thread():
    """Context manager: BLAS limited to one thread inside."""
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController  # deferred with scipy.linalg (below)

        scipy_linalg()  # the controller sees only the BLAS libraries loaded when it is made: scipy's too
        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def scipy_linalg():
    """``scipy.linalg``, imported on first use."""
    import scipy.linalg  # ~0.2 s to import (-X importtime): first system built only

    return scipy.linalg


def lti_parts(A, B, Cout, D, T, hold, passive=False, signature=None):
    """The parts of x' = A x + B u, y = Cout x + D u sampled every T seconds (see
    :func:`_lti_parts_one_thread`), computed on one BLAS thread.  ``signature``: a diagonal
    of +-1 with diag(signature) A symmetric, if the caller knows one (:data:`SYMMETRIC_GAINS`)."""
    with one_blas_thread():
        return _lti_parts_one_thread(A, B, Cout, D, T, hold, passive, signature)


def _lti_parts_one_thread(A, B, Cout, D, T, hold, passive=False, signature=None):
    """Complex-mode part of x' = A x + B u, y = Cout x + D u, or the dense part if the
    eigenvector matrix is ill-conditioned (defective or nearly repeated eigenvalues).

    ``passive``: the system cannot gain energy (C_m >= 0), so a positive real part of an
    eigenvalue can only be rounding (undamped modes: +-1e-16 |lambda|); it is set to 0 so that
    60 s of free ringing cannot grow."""
    sla = scipy_linalg()
    idx = np.arange(A.shape[0])
    found = mkl_eig(A) if MKL_EIGEN and np.all(np.isfinite(A)) else None
    lam, V = found if found is not None else sla.eig(A, check_finite=False, overwrite_a=False)
    if passive:
        lam = np.minimum(lam.real, 0.0) + 1j * lam.imag
    V = V / np.linalg.norm(V, axis=0)
    if signature is not None and SYMMETRIC_GAINS:
        part = symmetric_gains_part(idx, A, lam, V, np.asarray(signature, float), B, Cout, D, T, hold)
        if part is not None:
            return [part]
    lu, piv = sla.lu_factor(V, check_finite=False)
    gecon = sla.get_lapack_funcs("gecon", (lu,))
    rcond, _ = gecon(lu, np.linalg.norm(V, 1), norm="1")
    if not np.isfinite(rcond) or rcond * MAX_EIGVEC_COND < 1.0:
        return [DensePart(idx, A, B, Cout, D, T, hold)]
    keep = lam.imag >= 0
    # only V^-1 B is needed for the response; the full inverse (state mapping) is lazy
    g = sla.lu_solve((lu, piv), B.astype(complex), check_finite=False)[keep]
    vinv = LazyInverseRows(lu, piv, keep)
    return [EigenPart(idx, lam[keep], V[:, keep], vinv, B, Cout, D, T, hold, g=g)]


def symmetric_gains_part(idx, A, lam, V, S, B, Cout, D, T, hold):
    """The complex-mode part with V^-1 B from S-orthogonality (:data:`SYMMETRIC_GAINS`), or
    None where that does not apply (the LU path decides then)."""
    SA = S[:, None] * A
    if not np.array_equal(SA, SA.T):
        return None
    n = len(lam)
    keep = lam.imag >= 0
    Vk = V[:, keep]
    SV = S[:, None] * Vk
    den = np.einsum("ik,ik->k", SV, Vk)                    # v_k^T S v_k (no conjugate)
    with np.errstate(divide="ignore"):
        cond = 1.0 / np.abs(den)                           # each eigenvalue's condition number
    weight = np.where(lam[keep].imag > 0, 2.0, 1.0)        # a pair's conjugate has the same
    if not (np.all(np.isfinite(cond)) and math.sqrt(n) * float(weight @ cond) < 0.5 * MAX_EIGVEC_COND):
        return None
    g = (B @ SV) / den
    # B = sum over all eigenvalues of v_j g_j = sum_k weight_k Re(v_k g_k) (B real: a conjugate's gain is conj)
    wg = weight * g
    recon = Vk.real @ wg.real - Vk.imag @ wg.imag
    scale = max(float(np.abs(B).max(initial=0.0)), float(np.abs(wg).sum()))
    if not np.abs(recon - B).max(initial=0.0) <= _GAINS_RESIDUAL * scale:
        return None
    return EigenPart(idx, lam[keep], Vk, LazyInverseRows(None, None, keep, V), B, Cout, D, T, hold, g=g)


class LazyInverseRows:
    """Rows ``keep`` of V^-1 from V's LU factors, computed on first use."""

    def __init__(self, lu, piv, keep, V=None):
        self.lu, self.piv, self.keep, self._rows = lu, piv, keep, None
        self._V = V                   # factored on first use where the part was made without LU

    def get(self):
        if self._rows is None:
            with one_blas_thread():   # as lti_parts: small, one thread
                sla = scipy_linalg()
                if self.lu is None:
                    self.lu, self.piv = sla.lu_factor(self._V, check_finite=False)
                n = self.lu.shape[0]
                self._rows = sla.lu_solve((self.lu, self.piv), np.eye(n), check_finite=False)[self.keep]
        return self._rows


def lti_system(A, B, Cout, D, sample_rate_hz: float, hold: str = "foh", method: str = "auto") -> DiscreteSystem:
    """Exact discretisation of a small LTI system x' = A x + B u, y = Cout x + D u (used by
    the fingertip model). ``method="dense"`` forces the matrix-exponential form that
    ill-conditioned eigenvectors fall back to (``"auto"``: complex modes unless they are
    ill-conditioned)."""
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if method not in ("auto", "dense"):
        raise ValueError(f"method must be 'auto' or 'dense', got {method!r}")
    B, Cout, T = np.asarray(B, float).reshape(n), np.asarray(Cout, float).reshape(n), 1.0 / float(sample_rate_hz)
    if method == "dense":
        parts = [DensePart(np.arange(n), A, B, Cout, float(D), T, hold)]
    else:
        parts = lti_parts(A, B, Cout, float(D), T, hold)
    return DiscreteSystem(parts, n, sample_rate_hz, hold)


class SteadyState:
    """A system in periodic steady state under a looped input: output and state repeat every
    period (the transient decayed below exp(-SETTLE_E_FOLDS)).

    ``output`` holds one period indexed by loop phase; the state at phase 0 is computed on
    first use (:meth:`state_at`: leaving the steady state).  ``bandlimited``: the input
    samples stand for the band-limited signal of their hold (see the module docstring);
    ``input_spectrum``: ``np.fft.rfft(input_period)`` if known (the same output, one FFT fewer).
    """

    def __init__(self, system: DiscreteSystem, input_period: np.ndarray, bandlimited: bool = False,
                 input_spectrum=None) -> None:
        self.system = system
        self.input = input_period
        self.bandlimited = bool(bandlimited)
        self.output = system.periodic_response(input_period, self.bandlimited, input_spectrum)
        self._state0 = None

    def state_at(self, s: int) -> np.ndarray:
        """The state at absolute sample ``s`` (propagated from phase 0; band-limited: in
        closed form at that phase)."""
        p = s % len(self.input)
        if self.bandlimited:
            return self.system.periodic_state(self.input, True, p)
        if self._state0 is None:
            self._state0 = self.system.periodic_state(self.input)
        if p == 0:
            return self._state0.copy()
        return self.system.final_state(self.input[:p + 1], self._state0)
