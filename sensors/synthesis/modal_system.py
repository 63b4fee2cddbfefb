"""Modal synthesis: the object's response at the microphone to a sampled force.

Solves  q'' + C_m q' + Lambda q = U_d^T f(t)  for the mass-normalised modal coordinates q and
reads  y = n_mic . U_mic q  (displacement; velocity and acceleration as options).

State and discretisation
------------------------
The state is scaled to x = [Omega q; q'] (Omega = diag(w)), so that

    x' = A x + B u,   A = [[0, Omega], [-Omega, -C_m]],   B = [0; b],

and the modal energy is E = |x|^2 / 2.  Undamped, A is skew-symmetric (normal, eigenvectors
perfectly conditioned); damping C_m >= 0 makes d|x|^2/dt = -2 q'^T C_m q' <= 0, so the exact
one-step map is a contraction in this norm.

The force is taken as piecewise linear between samples (first-order hold, "ramp invariant"),
which makes the discretisation exact for such a force:

    x[n+1] = Phi x[n] + Gamma0 u[n] + Gamma1 u[n+1],   Phi = exp(A T).

Zero-order hold (``hold="zoh"``) keeps u constant over a sample (Gamma1 = 0); it is wrong by
tens of percent near Nyquist and exists for comparison.

Exact method
------------
A = V diag(lambda) V^-1 (complex modes; under-, critically and over-damped modes alike).  For
zero initial state the output is a convolution of u with one real impulse response

    h[0] = Re sum_k c_k beta1_k + D,   h[l] = Re sum_k d_k a_k^(l-1)  (l >= 1),   a_k = e^(lambda_k T),

computed for all l at once by a blocked matrix product (rows a_k^(mB), columns a_k^j) and
applied with one FFT convolution.  Conjugate pairs are folded (one eigenvalue per pair, weight
2).  When V is ill-conditioned (defective / nearly repeated eigenvalues, e.g. a mode at
critical damping) the same sums are evaluated with powers of the real matrix Phi obtained from
an augmented matrix exponential instead ("dense" fallback, exact to rounding, slower).

Diagonal method
---------------
Keeps only diag(C_m) (the usual approximation): independent 2x2 systems with closed-form
eigenvalues; modes near critical damping use the dense fallback.

Fast paths (change no result beyond rounding)
---------------------------------------------
- modes decoupled (through C_m) from every mode that the drive reaches, or from every mode the
  microphone sees, contribute exactly nothing and are dropped;
- zero force and zero initial state -> zeros without building anything;
- impulse responses are cut where every term has decayed below 1e-17 of their total.
Modes at or above Nyquist are dropped by default (``max_frequency_hz``): a sampled signal
cannot carry them, and their only effect on the samples is a quasi-static compliance far below
the band (reported by ``benchmarks/synthesis.py`` under mode truncation).

Contacts may change over time (piecewise-constant contact sets): each segment gets its own
system and the full modal state is carried across the switch.  For a static grasp under a
periodic force, :func:`periodic_response` gives the exact periodic steady state (one circular
convolution, i.e. one complex gain per harmonic of the loop frequency).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..modal.contact import Contact
from ..modal.damping import check_on_surface, modal_damping_matrix, modal_damping_parts
from .low_rank_modes import low_rank_modes

__all__ = ["ModalSystem", "modal_response", "periodic_response", "modal_state_energy", "modal_state_matrix"]

_OUTPUTS = ("displacement", "velocity", "acceleration")
_METHODS = ("exact", "diagonal")
_HOLDS = ("foh", "zoh")
# cond(V) above this: the complex-mode sums lose more than ~1e-8 relative -> dense fallback.
_MAX_EIGVEC_COND = 1e8
# Relative size below which a gain or a coupling counts as exactly zero (rounding level).
_NEGLIGIBLE = 1e-13
# The low-rank complex-mode path (sensors.synthesis.low_rank_modes) pays off from about this many
# modes, while the contact factor has at most this many rows per mode (benchmarks/synthesis.py).
LOW_RANK_MIN_MODES = 40
LOW_RANK_MAX_RATIO = 0.5
# Impulse responses are cut once every term is below this fraction of the terms' sum.
_DECAY_TOL = 1e-17


# ----------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------

def _phi12(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phi1(x) = (e^x - 1)/x and phi2(x) = (e^x - 1 - x)/x^2, accurate for all complex x."""
    x = np.asarray(x, dtype=complex)
    small = np.abs(x) < 1.0
    xs = np.where(small, x, 0.0)
    xl = np.where(small, 1.0, x)
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
    import scipy.signal as ssig  # ~0.5 s to import (-X importtime): first use only

    if len(h) * 8 < len(u) and len(h) > 64:
        return ssig.oaconvolve(u, h)[:n]
    return ssig.fftconvolve(u, h)[:n]


def _as_contacts(contacts) -> list[Contact]:
    out = list(contacts)
    for c in out:
        if not isinstance(c, Contact):
            raise TypeError(f"expected sensors.Contact, got {type(c).__name__}")
    return out


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be a finite 3-vector, got {v}")
    length = float(np.linalg.norm(v))
    if abs(length - 1.0) > 1e-4:
        raise ValueError(f"{what} must be a unit vector (|n| = {length:.6g})")
    return v / length


def _point(p, what: str) -> np.ndarray:
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be a finite 3-vector [m], got {p}")
    return p


def _force(force_n) -> np.ndarray:
    u = np.asarray(force_n, dtype=float)
    if u.ndim != 1:
        raise ValueError(f"force_n must be a 1-D signal [N], got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("force_n contains NaN or inf")
    return u


def modal_state_energy(x: np.ndarray) -> np.ndarray:
    """Modal energy |x|^2 / 2 [J] of a scaled state x = [w q; q'] (along the last axis).

    With mass-normalised modes (U^T M U = I) this is the object's kinetic plus strain energy
    in the kept modes.
    """
    x = np.asarray(x)
    return 0.5 * np.sum(x * x, axis=-1)


# ----------------------------------------------------------------------------------------
# parts: independent linear subsystems whose outputs add up
# ----------------------------------------------------------------------------------------

class _EigenPart:
    """Complex-mode form: coordinates z (one eigenvalue per conjugate pair)."""

    def __init__(self, idx, lam, V, Vinv, B, Cout, D, T, hold, g=None):
        # idx: indices into the global state; lam (K,), V (n, K), Vinv (K, n) for the kept
        # eigenvalues; conjugate partners folded by the weight w (2 for a pair, 1 if real).
        self.idx = idx
        self.lam = lam
        self.w = np.where(lam.imag > 0, 2.0, 1.0)
        self.V = V
        self._vinv = Vinv  # array or _LazyInverseRows
        self.T = T
        x = lam * T
        self.a = np.exp(x)
        phi1, phi2 = _phi12(x)
        if hold == "foh":
            self.b0, self.b1 = T * (phi1 - phi2), T * phi2
        else:
            self.b0, self.b1 = T * phi1, np.zeros_like(phi1)
        self.g = self.Vinv @ B if g is None else g  # input gain per eigen-coordinate
        self.co = self.w * (Cout @ V)       # output row (weight folded in)
        self.D = float(D)
        self.G0 = self.g * self.b0
        self.G1 = self.g * self.b1

    @property
    def Vinv(self):
        if isinstance(self._vinv, _LazyInverseRows):
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

    def periodic_vector(self, v, P: int):
        return v / (1.0 - np.exp(self.lam * self.T * P))

    def transition(self):
        return (self.V @ (self.w[:, None] * self.a[:, None] * self.Vinv)).real


class _DensePart:
    """Real state-space form with Phi from an augmented matrix exponential (robust)."""

    def __init__(self, idx, A, B, Cout, D, T, hold):
        n = A.shape[0]
        self.idx = idx
        self.A = A
        self.T = T
        aug = np.zeros((n + 2, n + 2))
        aug[:n, :n] = A
        aug[:n, n] = B
        aug[n, n + 1] = 1.0
        E = _sla().expm(aug * T)
        self.Phi = E[:n, :n]
        F1, F2 = E[:n, n], E[:n, n + 1]
        if hold == "foh":
            self.G0, self.G1 = F1 - F2 / T, F2 / T
        else:
            self.G0, self.G1 = F1, np.zeros(n)
        self.C = Cout
        self.D = float(D)
        self._phiB = {}

    def to_coords(self, x):
        return np.asarray(x, dtype=float)

    def from_coords(self, z):
        return np.asarray(z, dtype=float)

    def step(self, z):
        return self.Phi @ z

    def direct(self):
        return float(self.C @ self.G1) + self.D

    def _power(self, k: int) -> np.ndarray:
        if k not in self._phiB:
            self._phiB[k] = _sla().expm(self.A * (self.T * k))
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

    def periodic_vector(self, v, P: int):
        return np.linalg.solve(np.eye(self.Phi.shape[0]) - self._power(P), v)

    def transition(self):
        return self.Phi


# ----------------------------------------------------------------------------------------
# the system for one contact set
# ----------------------------------------------------------------------------------------

@dataclass
class _Setup:
    w: np.ndarray      # (r,) angular frequencies of the kept modes
    C: np.ndarray      # (r, r) damping
    b: np.ndarray      # (r,) modal input gain per newton
    o: np.ndarray      # (r,) modal output gain (displacement per modal coordinate)
    d: np.ndarray | None = None  # (r,) Rayleigh part of C and (k, r) the factor of its
    Q: np.ndarray | None = None  # contact part, C = diag(d) + Q^T Q, when C is not given


class ModalSystem:
    """The discretised modal system for one contact set, drive point and microphone.

    Build once per grasp (``ModalSystem.build``), then call :meth:`response` as often as
    needed.  State vectors are the scaled state x = [w q; q'] of ALL the model's modes
    (length 2 r_model); modes dropped by a fast path simply keep a zero state.
    """

    def __init__(self, parts, n_modes: int, kept: np.ndarray, sample_rate_hz: float, hold: str):
        self.parts = parts
        self.n_modes = n_modes
        self.kept = kept  # indices of modes that take part in the synthesis
        self.sample_rate_hz = float(sample_rate_hz)
        self.hold = hold

    # construction -----------------------------------------------------------------------
    @classmethod
    def build(cls, model, sample_rate_hz: float, drive_point_m, drive_normal, mic_point_m, mic_normal,
              contacts: Sequence[Contact] = (), method: str = "exact",
              output: str = "displacement", hold: str = "foh",
              max_frequency_hz: float | None = None, damping=None,
              keep_unobservable: bool = False, initial_state=None) -> "ModalSystem":
        """Discretise the modal system of ``model`` at ``sample_rate_hz`` [Hz].

        The drive force pushes INTO the object at ``drive_point_m`` (along ``-drive_normal``,
        as a finger does); the output is the motion of the object at ``mic_point_m`` along
        ``+mic_normal`` (outward).  ``damping`` overrides C_m (r x r) if given.
        ``keep_unobservable`` keeps modes the microphone cannot see (needed when the state
        is carried into a later contact set); modes with a nonzero ``initial_state`` count as
        reached by the drive.
        """
        if method not in _METHODS:
            raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
        if output not in _OUTPUTS:
            raise ValueError(f"output must be one of {_OUTPUTS}, got {output!r}")
        if hold not in _HOLDS:
            raise ValueError(f"hold must be one of {_HOLDS}, got {hold!r}")
        sample_rate_hz = float(sample_rate_hz)
        if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
            raise ValueError(f"sample_rate_hz must be a positive sample rate [Hz], got {sample_rate_hz}")
        dp, mp = _point(drive_point_m, "drive_point_m"), _point(mic_point_m, "mic_point_m")
        dn, mn = _unit(drive_normal, "drive_normal"), _unit(mic_normal, "mic_normal")
        contacts = _as_contacts(contacts)
        check_on_surface(model, np.array([dp, mp]), "drive/mic point")

        w_all = np.asarray(model.angular_frequencies_rad_s, dtype=float)
        r_all = len(w_all)
        if damping is None:
            d_all, Q_all = modal_damping_parts(model, contacts)
            C_all = np.diag(d_all) + Q_all.T @ Q_all
        else:
            d_all, Q_all, C_all = None, None, np.asarray(damping, float)
        Ush = np.asarray(model.mode_shapes_at(np.array([dp, mp])), dtype=float)  # (2, 3, r)
        b_all = -dn @ Ush[0]
        o_all = mn @ Ush[1]
        fmax = sample_rate_hz / 2.0 if max_frequency_hz is None else float(max_frequency_hz)
        kept = np.flatnonzero(w_all < 2 * np.pi * fmax)
        excited = np.zeros(r_all, bool)
        if initial_state is not None:
            x0 = np.asarray(initial_state, dtype=float).reshape(2, r_all)
            excited = np.any(x0 != 0, axis=0)
        kept = _relevant_modes(kept, C_all, b_all, o_all, keep_unobservable, excited)
        su = _Setup(w_all[kept], C_all[np.ix_(kept, kept)], b_all[kept], o_all[kept],
                    None if d_all is None else d_all[kept], None if Q_all is None else Q_all[:, kept])
        parts = _build_parts(su, method, output, 1.0 / sample_rate_hz, hold)
        # map part-local state indices (over kept modes) to the global scaled state
        glob = np.concatenate([kept, r_all + kept])
        for p in parts:
            p.idx = glob[p.idx]
        return cls(parts, r_all, kept, sample_rate_hz, hold)

    # evaluation -------------------------------------------------------------------------
    def response(self, force_n, initial_state=None) -> np.ndarray:
        """Output for the sampled force [N] (one sample per force sample), float64.

        ``initial_state`` (2 r_model,) is the scaled state at the first sample (default 0).
        Modes dropped at build time (unreachable or unobservable) are not simulated: build
        with the same ``initial_state`` (and ``keep_unobservable``) to keep modes that only
        the initial state excites.
        """
        u = _force(force_n)
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
            if not has_u and z0 is None:
                continue
            vecs = []
            if has_u:
                vecs.append(p.step(p.G1) + p.G0)
                if u[0] != 0:
                    vecs.append(p.G1)
            if z0 is not None:
                vecs.append(z0)
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
        return y

    def final_state(self, force_n, initial_state=None) -> np.ndarray:
        """Scaled state at the LAST sample of ``force_n`` (after len-1 steps)."""
        u = _force(force_n)
        x = np.zeros(2 * self.n_modes)
        x0 = None if initial_state is None else np.asarray(initial_state, dtype=float)
        for p in self.parts:
            z0 = None if x0 is None else p.to_coords(x0[p.idx])
            z = z0 if len(u) < 2 else p.propagate(z0, u)
            if z is not None:
                x[p.idx] = p.from_coords(z)
        return x

    def periodic_response(self, force_period_n) -> np.ndarray:
        """Exact periodic steady state for a force that repeats ``force_period_n`` forever.

        One period of output; equals :meth:`response` of the looped force once the
        transient has decayed.  (Circular convolution with the period-aliased impulse
        response: one complex gain per harmonic of the loop frequency sample_rate_hz / P.)
        """
        u = _force(force_period_n)
        P = len(u)
        y = np.zeros(P)
        if P == 0 or not np.any(u != 0):
            return y
        for p in self.parts:
            v = p.periodic_vector(p.step(p.G1) + p.G0, P)
            ps = p.power_sums(np.array([v]), P)[0]
            hp = np.empty(P)
            hp[1:] = ps[: P - 1]
            hp[0] = p.direct() + ps[P - 1]
            y += np.fft.irfft(np.fft.rfft(u) * np.fft.rfft(hp), P)
        return y

    def periodic_state(self, force_period_n) -> np.ndarray:
        """Scaled state at phase 0 of the periodic steady state under a force that repeats
        ``force_period_n`` forever (the state :meth:`periodic_response` runs through):
        x0 = Phi^P x0 + (one period from rest), solved per part in its own coordinates."""
        u = _force(force_period_n)
        P = len(u)
        x = np.zeros(2 * self.n_modes)
        if P == 0:
            return x
        ext = np.concatenate([u, u[:1]])      # samples 0 .. P of the looped force
        for p in self.parts:
            x[p.idx] = p.from_coords(p.periodic_vector(p.propagate(None, ext), P))
        return x

    def slowest_decay_rate_per_s(self) -> float:
        """The smallest decay rate [1/s] of the simulated modes (0: one does not decay):
        a transient has fallen to exp(-k) of its start after k / rate seconds."""
        if getattr(self, "_slowest", None) is None:
            rates = []
            for p in self.parts:
                lam = p.lam if isinstance(p, _EigenPart) else np.linalg.eigvals(p.A)
                rates.append(float(np.min(-np.real(lam))) if len(lam) else np.inf)
            self._slowest = max(0.0, min(rates)) if rates else np.inf
        return self._slowest

    def transition_matrix(self) -> np.ndarray:
        """One-step map Phi of the scaled state (2 r_model square; dropped modes: identity)."""
        n = 2 * self.n_modes
        Phi = np.eye(n)
        for p in self.parts:
            Phi[np.ix_(p.idx, p.idx)] = p.transition()
        return Phi

    @property
    def methods_used(self) -> list[str]:
        """'eigen' or 'dense' per part (diagnostics: which path was taken)."""
        return ["eigen" if isinstance(p, _EigenPart) else "dense" for p in self.parts]


def _nonzero_length(h: np.ndarray) -> int:
    nz = np.flatnonzero(h)
    return int(nz[-1]) + 1 if nz.size else 0


def _relevant_modes(kept, C, b, o, keep_unobservable, excited):
    """Drop groups of modes (connected through C) that the drive cannot reach or the mic
    cannot see: they contribute exactly zero."""
    if len(kept) == 0:
        return kept
    Ck = C[np.ix_(kept, kept)]
    off = np.abs(Ck - np.diag(np.diag(Ck)))
    scale = np.abs(Ck).max()
    link = off > _NEGLIGIBLE * scale
    np.fill_diagonal(link, True)
    if link.all(axis=1).any():  # a mode coupled to every other (any grasp's contacts): one group
        ncomp, lab = 1, np.zeros(len(kept), int)
    else:
        from scipy.sparse.csgraph import connected_components  # ~0.1 s to import: first use only

        ncomp, lab = connected_components(link, directed=False)
    bk, ok = np.abs(b[kept]), np.abs(o[kept])
    reach = np.zeros(ncomp, bool)
    seen = np.zeros(ncomp, bool)
    np.logical_or.at(reach, lab, (bk > _NEGLIGIBLE * max(bk.max(), 1e-300)) | excited[kept])
    np.logical_or.at(seen, lab, ok > _NEGLIGIBLE * max(ok.max(), 1e-300))
    keep = reach[lab] & (seen[lab] | keep_unobservable)
    return kept[keep]


def modal_state_matrix(w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """State matrix A = [[0, Omega], [-Omega, -C]] of q'' + C q' + Omega^2 q = 0 in the scaled
    state x = [Omega q; q'] (see the module docstring): the one place it is built."""
    w = np.asarray(w, dtype=float)
    r = w.size
    A = np.zeros((2 * r, 2 * r))
    A[:r, r:] = np.diag(w)
    A[r:, :r] = -np.diag(w)
    A[r:, r:] = -np.asarray(C, dtype=float)
    return A


def _state_matrices(su: _Setup, output: str):
    r = len(su.w)
    A = modal_state_matrix(su.w, su.C)
    B = np.concatenate([np.zeros(r), su.b])
    if output == "displacement":
        Cout, D = np.concatenate([su.o / su.w, np.zeros(r)]), 0.0
    elif output == "velocity":
        Cout, D = np.concatenate([np.zeros(r), su.o]), 0.0
    else:  # q'' = -Omega (Omega q) - C q' + b u
        Cout, D = np.concatenate([-su.o * su.w, -(su.o @ su.C)]), float(su.o @ su.b)
    return A, B, Cout, D


def _build_parts(su: _Setup, method: str, output: str, T: float, hold: str):
    r = len(su.w)
    if r == 0:
        return []
    if method == "diagonal":
        su = _Setup(su.w, np.diag(np.diag(su.C)), su.b, su.o)
        return _diagonal_parts(su, output, T, hold)
    A, B, Cout, D = _state_matrices(su, output)
    if su.Q is not None and r >= LOW_RANK_MIN_MODES and su.Q.shape[0] <= LOW_RANK_MAX_RATIO * r:
        with _one_blas_thread():
            modes = low_rank_modes(su.w, su.d, su.Q)
        if modes is not None:
            lam, V, W = modes
            lam = np.minimum(lam.real, 0.0) + 1j * lam.imag  # passive, as in _lti_parts
            return [_EigenPart(np.arange(2 * r), lam, V, W, B, Cout, D, T, hold)]
    return _lti_parts(A, B, Cout, D, T, hold, passive=True)


# Multi-threaded BLAS makes the small dense eigenproblems here several times slower on a
# busy two-core machine (0.15 s vs 0.03 s for 204 x 204): they run on one thread.
_BLAS = None


def _one_blas_thread():
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController  # deferred with scipy.linalg (below)

        _sla()  # the controller sees only the BLAS libraries loaded when it is made: scipy's too
        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def _sla():
    import scipy.linalg  # ~0.2 s to import (-X importtime): first system built only

    return scipy.linalg


def _lti_parts(A, B, Cout, D, T, hold, passive=False):
    with _one_blas_thread():
        return _lti_parts_one_thread(A, B, Cout, D, T, hold, passive)


def _lti_parts_one_thread(A, B, Cout, D, T, hold, passive=False):
    """Complex-mode part of x' = A x + B u, y = Cout x + D u, or the dense part if the
    eigenvector matrix is ill-conditioned (defective or nearly repeated eigenvalues).

    ``passive``: the system cannot gain energy (C_m >= 0), so a positive real part of an
    eigenvalue can only be rounding (undamped modes: +-1e-16 |lambda|); it is set to 0 so that
    60 s of free ringing cannot grow."""
    sla = _sla()
    idx = np.arange(A.shape[0])
    lam, V = sla.eig(A, check_finite=False, overwrite_a=False)
    if passive:
        lam = np.minimum(lam.real, 0.0) + 1j * lam.imag
    V = V / np.linalg.norm(V, axis=0)
    lu, piv = sla.lu_factor(V, check_finite=False)
    gecon = sla.get_lapack_funcs("gecon", (lu,))
    rcond, _ = gecon(lu, np.linalg.norm(V, 1), norm="1")
    if not np.isfinite(rcond) or rcond * _MAX_EIGVEC_COND < 1.0:
        return [_DensePart(idx, A, B, Cout, D, T, hold)]
    keep = lam.imag >= 0
    # only V^-1 B is needed for the response; the full inverse (state mapping) is lazy
    g = sla.lu_solve((lu, piv), B.astype(complex), check_finite=False)[keep]
    vinv = _LazyInverseRows(lu, piv, keep)
    return [_EigenPart(idx, lam[keep], V[:, keep], vinv, B, Cout, D, T, hold, g=g)]


class _LazyInverseRows:
    """Rows ``keep`` of V^-1 from V's LU factors, computed on first use."""

    def __init__(self, lu, piv, keep):
        self.lu, self.piv, self.keep, self._rows = lu, piv, keep, None

    def get(self):
        if self._rows is None:
            n = self.lu.shape[0]
            with _one_blas_thread():   # as _lti_parts: small, one thread
                self._rows = _sla().lu_solve((self.lu, self.piv), np.eye(n), check_finite=False)[self.keep]
        return self._rows


def _diagonal_parts(su: _Setup, output: str, T: float, hold: str):
    """Closed-form eigen-decomposition of each 2x2 block [[0, w], [-w, -c]]."""
    r = len(su.w)
    w, c = su.w, np.diag(su.C)
    disc = np.sqrt((c * c - 4 * w * w).astype(complex))
    l1, l2 = (-c + disc) / 2, (-c - disc) / 2
    near_critical = np.abs(l1 - l2) < 1e-5 * (np.abs(l1) + np.abs(l2))
    good = np.flatnonzero(~near_critical)
    parts = []
    A, B, Cout, D = _state_matrices(su, output)
    if good.size:
        # one eigenvalue for an under-damped pair (Im > 0), both for an over-damped mode
        over = good[np.abs(disc[good].imag) == 0]
        ev_mode = np.concatenate([good, over])
        ev_lam = np.concatenate([np.where(l1[good].imag >= 0, l1[good], l2[good]), l2[over]])
        ev_other = np.concatenate([np.where(l1[good].imag >= 0, l2[good], l1[good]), l1[over]])
        K = len(ev_mode)
        V = np.zeros((2 * r, K), complex)
        Vinv = np.zeros((K, 2 * r), complex)
        kk = np.arange(K)
        wm = w[ev_mode]
        # eigenvector [w; lambda]; inverse rows from the 2x2 inverse of [[w, w], [l, l']]
        V[ev_mode, kk] = wm
        V[r + ev_mode, kk] = ev_lam
        det = wm * (ev_other - ev_lam)
        Vinv[kk, ev_mode] = ev_other / det
        Vinv[kk, r + ev_mode] = -wm / det
        idx = np.arange(2 * r)
        parts.append(_EigenPart(idx, ev_lam, V, Vinv, B, Cout, 0.0, T, hold))
    bad = np.flatnonzero(near_critical)
    if bad.size:
        sub = np.concatenate([bad, r + bad])
        parts.append(_DensePart(sub, A[np.ix_(sub, sub)], B[sub], Cout[sub], 0.0, T, hold))
    if D != 0.0:
        parts[0].D = D
    return parts


# ----------------------------------------------------------------------------------------
# public functions
# ----------------------------------------------------------------------------------------

def lti_system(A, B, Cout, D, sample_rate_hz: float, hold: str = "foh", method: str = "auto") -> "ModalSystem":
    """Exact discretisation of a small LTI system x' = A x + B u, y = Cout x + D u (even
    state size) with the same machinery (used by the fingertip model). ``method="dense"``
    forces the matrix-exponential form that ill-conditioned eigenvectors fall back to
    (``"auto"``: complex modes unless they are ill-conditioned)."""
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    if n % 2:
        raise ValueError("lti_system needs an even state size")
    if method not in ("auto", "dense"):
        raise ValueError(f"method must be 'auto' or 'dense', got {method!r}")
    B, Cout, T = np.asarray(B, float).reshape(n), np.asarray(Cout, float).reshape(n), 1.0 / float(sample_rate_hz)
    if method == "dense":
        parts = [_DensePart(np.arange(n), A, B, Cout, float(D), T, hold)]
    else:
        parts = _lti_parts(A, B, Cout, float(D), T, hold)
    return ModalSystem(parts, n // 2, np.arange(n // 2), sample_rate_hz, hold)


def _schedule(contacts, sample_rate_hz: float, n: int):
    """[(start_sample, [Contact...]), ...] from a contact list or a (time_s, contacts) list."""
    items = list(contacts)
    if all(isinstance(c, Contact) for c in items):
        return [(0, items)]
    sched = []
    for it in items:
        if not (isinstance(it, (tuple, list)) and len(it) == 2):
            raise TypeError("contacts must be a sequence of Contact or of (start_time_s, contacts)")
        t, cs = it
        t = float(t)
        if not np.isfinite(t):
            raise ValueError("contact switch time must be finite")
        sched.append((int(round(t * sample_rate_hz)), _as_contacts(cs)))
    starts = [s for s, _ in sched]
    if not sched or starts[0] != 0 or any(b <= a for a, b in zip(starts, starts[1:])):
        raise ValueError("contact schedule must start at t = 0 s with increasing switch times")
    return [(s, cs) for s, cs in sched if s < n] or [(0, sched[0][1])]


def modal_response(model, force_n, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                   contacts=(), method: str = "exact", output: str = "displacement",
                   hold: str = "foh", max_frequency_hz: float | None = None,
                   initial_state=None) -> np.ndarray:
    """Object response at the microphone to a sampled force, zero initial state.

    Parameters
    ----------
    model : modal model (``angular_frequencies_rad_s``, ``material``, ``mode_shapes_at``,
        optionally ``surface_distance_m``).
    force_n : (N,) force [N] at the drive point, pushing INTO the object (along
        ``-drive_normal``); piecewise linear between samples (``hold="foh"``, exact) or
        held constant over each sample (``"zoh"``).
    sample_rate_hz : sample rate [Hz].
    drive_point_m, drive_normal, mic_point_m, mic_normal : object frame; normals are unit
        outward normals.
    contacts : sequence of :class:`Contact` (static), or a schedule
        ``[(start_time_s, [Contact, ...]), ...]`` starting at 0 s: piecewise-constant contact
        sets, the modal state carried across each switch.
    method : ``"exact"`` (coupled damping, complex modes) or ``"diagonal"`` (diag(C_m) only).
    output : ``"displacement"`` [m] (default, the paper's choice), ``"velocity"`` [m/s] or
        ``"acceleration"`` [m/s^2] of the object at the mic point along ``+mic_normal``.
    max_frequency_hz : drop modes at or above this frequency (default: Nyquist, sample_rate_hz/2).
    initial_state : optional scaled state [w q; q'] (2 r,) at the first sample.

    Returns
    -------
    (N,) float64, one output sample per force sample.
    """
    u = _force(force_n)
    n = len(u)
    if n == 0:
        return np.zeros(0)
    sample_rate_hz = float(sample_rate_hz)
    sched = _schedule(contacts, sample_rate_hz, n)
    if not np.any(u != 0) and (initial_state is None or not np.any(initial_state)):
        # fast path, but still validate the geometry so bad input fails the same way
        for _, cs in sched:
            modal_damping_matrix(model, cs)
        check_on_surface(model, np.array([_point(drive_point_m, "drive_point_m"),
                                          _point(mic_point_m, "mic_point_m")]), "drive/mic point")
        _unit(drive_normal, "drive_normal"), _unit(mic_normal, "mic_normal")
        return np.zeros(n)
    y = np.zeros(n)
    x = initial_state
    bounds = [s for s, _ in sched] + [n]
    for i, (s, cs) in enumerate(sched):
        e = bounds[i + 1]
        last = i == len(sched) - 1
        sysm = ModalSystem.build(model, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                                 cs, method=method, output=output, hold=hold,
                                 max_frequency_hz=max_frequency_hz, keep_unobservable=not last,
                                 initial_state=x)
        y[s:e] = sysm.response(u[s:e], x)
        if not last:
            # the force is continuous through the switch sample e: propagate over [s, e]
            x = sysm.final_state(u[s:e + 1], x)
    return y


def periodic_response(model, force_period_n, sample_rate_hz, drive_point_m, drive_normal, mic_point_m,
                      mic_normal, contacts=(), method: str = "exact",
                      output: str = "displacement", hold: str = "foh",
                      max_frequency_hz: float | None = None) -> np.ndarray:
    """Exact periodic steady state (one period) for a static grasp under a looping force.

    Same arguments as :func:`modal_response`; ``force_period_n`` is one period of the
    looping force.  Equals the time-domain response once the transient has decayed.
    """
    sysm = ModalSystem.build(model, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                             contacts, method=method, output=output, hold=hold,
                             max_frequency_hz=max_frequency_hz)
    return sysm.periodic_response(force_period_n)
