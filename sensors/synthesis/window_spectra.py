"""Window spectra of an LTI system's output in closed form: no samples synthesized.

A system of :mod:`sensors.synthesis.lti` in complex modes advances each coordinate as

    z[n+1] = a z[n] + G0 u[n] + G1 u[n+1],   y[n] = Re(co . z[n]) + D u[n],   z[0] = 0.

For an input u = u_ss + u_tr, u_ss repeating one period of P samples and u_tr a sum of
decaying exponentials  sum_l gamma_l exp(s_l n)  (a driving system's own transient), the
coordinate is the periodic steady state plus, per exponential, a particular solution and the
mode's own decay from rest (``z_ss0`` is the steady state at phase 0):

    z[n] = z_ss[n] + sum_l K_l exp(s_l n) - a^n (z_ss0 + sum_l K_l),
    K_l = gamma_l (G0 + G1 e^{s_l}) / (e^{s_l} - a).

The DFT of window k (samples kP .. kP + P - 1) at a bin w = exp(-2 pi i m / P) (w^P = 1)
then has a closed form: the steady state's is (G0 w + G1) U_ss(w) / (1 - a w), and an
exponential r^n contributes r^(kP) (1 - r^P) / (1 - r w).  Nothing here depends on how the
system was built (poles, input and output vectors of each part only): any modal system of
``ModalSystem.build`` made of complex-mode parts qualifies (:func:`closed_form_supported`).

Evaluated per part with the output row first (``FACTORED_WINDOWS``): every term of a mode's
window spectrum at a bin is a coefficient over (1 - a w) (the steady state's (G0 w + G1) U_ss,
the decay's -start r^(kP) (1 - r^P), r = a), so the output's is one product of the
coefficient rows with the reciprocals 1 / (1 - a w), and likewise at conj(w).

A system settled under the band-limited signal of its input samples (``SteadyState(...,
bandlimited=True)``) has the steady state of each harmonic from the continuous-time transfer
function instead: :func:`bandlimited_steady_spectra`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lti import DiscreteSystem, EigenPart, hold_gain

__all__ = ["Exponentials", "bandlimited_steady_spectra", "bin_phasors", "closed_form_supported", "periodic_transient", "window_spectra"]

#: :func:`window_spectra`: True takes each part's output row first (one reciprocal per mode and
#: bin, one product per window), False sums each mode's coordinate spectra per window and then
#: the output (the reference; the same sums to rounding, ``tests/test_closed_form_drive.py``).
#: Read at each call.
FACTORED_WINDOWS = True

# |1 - a w| or |e^s - a| below this: a pole sits on a bin or two poles coincide; the closed
# form would divide by (nearly) zero, and the caller takes the time-domain chain instead.
_MIN_DENOMINATOR = 1e-9


@dataclass(frozen=True)
class Exponentials:
    """A real signal as a sum of complex exponentials: x[n] = sum_l gain[l] exp(log_pole[l] n)
    (conjugate terms included, so the sum is real)."""

    gain: np.ndarray
    log_pole: np.ndarray

    @classmethod
    def none(cls) -> "Exponentials":
        return cls(np.zeros(0, complex), np.zeros(0, complex))

    def bound(self) -> float:
        """An upper bound of |x[n]| for n >= 0 (every term decays or stays)."""
        return float(np.abs(self.gain).sum())

    def at(self, n: int) -> float:
        return float(np.sum(self.gain * np.exp(self.log_pole * n)).real)


def bin_phasors(bins: np.ndarray, period_samples: int) -> np.ndarray:
    """w = exp(-2 pi i m / P) for the integer DFT bins m of a P-sample window."""
    return np.exp(-2j * np.pi * np.asarray(bins, dtype=float) / period_samples)


def closed_form_supported(system: DiscreteSystem) -> bool:
    """Whether every part of ``system`` is in complex modes (a dense fallback part is not:
    its outputs go through the time-domain chain)."""
    return all(isinstance(p, EigenPart) for p in system.parts)


def periodic_transient(system: DiscreteSystem, state0_periodic: np.ndarray) -> Exponentials:
    """The output transient of ``system`` started from rest under a periodic input whose
    steady state passes phase 0 in ``state0_periodic``: y[n] - y_ss[n] = Cout Phi^n (0 - x_ss0)."""
    gains, poles = [], []
    for p in system.parts:
        z0 = p.to_coords(np.asarray(state0_periodic, dtype=float)[p.idx])
        c = -p.co * z0                        # Re(c e^{s n}): weight of conjugate pairs folded in co
        s = p.lam * p.T
        gains += [c / 2, np.conj(c) / 2]
        poles += [s, np.conj(s)]
    if not gains:
        return Exponentials.none()
    return Exponentials(np.concatenate(gains), np.concatenate(poles))


def bandlimited_steady_spectra(system: DiscreteSystem, input_period: np.ndarray, bins: np.ndarray,
                               n_windows: int) -> np.ndarray:
    """The window spectra (as :func:`window_spectra`) of ``system`` in the periodic steady
    state of ``SteadyState(system, input_period, bandlimited=True)``: per bin m, U_m S(f_m)
    H(f_m) (hold gain S, continuous-time transfer function H), the same in every window.
    Any part qualifies (dense ones too: H is evaluated per part)."""
    u = np.asarray(input_period, dtype=float)
    P = len(u)
    m = np.asarray(bins, dtype=int)
    gain = hold_gain(m / P, 1.0, system.hold) * system.frequency_response(m * (system.sample_rate_hz / P))
    return np.tile(np.fft.rfft(u)[m] * gain, (n_windows, 1))


def _window_geometric(log_pole: np.ndarray, w: np.ndarray, k: int, P: int) -> np.ndarray:
    """(len(log_pole), len(w)): sum_{n=kP}^{kP+P-1} r^n w^(n-kP), r = exp(log_pole)."""
    r = np.exp(log_pole)
    head = np.exp(log_pole * (k * P)) * -np.expm1(log_pole * P)
    return head[:, None] / (1.0 - r[:, None] * w[None, :])


def window_spectra(system: DiscreteSystem, input_period: np.ndarray | None, input_transient: Exponentials,
                   bins: np.ndarray, n_windows: int, from_rest: bool = True,
                   input_spectrum: np.ndarray | None = None, input_start=None) -> np.ndarray | None:
    """The DFT of the output over windows k = 0 .. n_windows - 1 at ``bins`` (complex,
    ``(n_windows, len(bins))``, unscaled: sum over the window of y[n] w^(n - kP)).

    The input is ``input_period`` (P samples, repeated) plus ``input_transient``; the system
    starts from rest (``from_rest``) or in its periodic steady state (then the transient must
    be empty).  ``None`` where the closed form does not apply (a dense part, a pole on a bin,
    a system pole on a transient pole): use the time-domain chain.  ``input_spectrum``: the
    input period's DFT at ``bins`` if the caller has it (else ``np.fft.rfft`` of the period).
    ``input_start``: where the input is a driving system's steady output, that drive
    (``sensors.synthesis.exciter_sums.SteadyDrive``): its ``start(part)`` gives each part's
    phase-0 state without the period's samples (``input_period`` may then be ``None``, with
    ``input_spectrum`` given).  ``FACTORED_WINDOWS`` selects the evaluation (module docstring).
    """
    if not closed_form_supported(system):
        return None
    if input_start is None:
        u = np.asarray(input_period, dtype=float)
        P = len(u)
        if FACTORED_WINDOWS:
            def start(p):
                return p.periodic_start(u)
        else:
            ext = np.concatenate([u, u[:1]])

            def start(p):
                return p.periodic_vector(p.propagate(None, ext), P)
    else:
        if input_spectrum is None:
            raise ValueError("input_start needs input_spectrum (the input period's DFT at the bins)")
        P = input_start.period_samples
        start = input_start.start
    w = bin_phasors(bins, P)
    spec = np.fft.rfft(u)[np.asarray(bins, dtype=int)] if input_spectrum is None else input_spectrum  # U_ss(w)
    gam = input_transient.gain
    if not from_rest and gam.size:
        raise ValueError("a system in periodic steady state has an input without transient")
    evaluate = _factored if FACTORED_WINDOWS else _per_window
    return evaluate(system, P, start, input_transient, w, spec, n_windows, from_rest)


def _per_window(system, P, start_of, input_transient, w, spec, n_windows, from_rest):
    """The reference: each mode's coordinate spectra per window, then the output row."""
    wc = np.conj(w)
    gam, sl = input_transient.gain, input_transient.log_pole
    out = np.zeros((n_windows, len(w)), complex)
    geo_in = [(_window_geometric(sl, w, k, P), _window_geometric(sl, wc, k, P)) for k in range(n_windows)]
    D_total = 0.0
    for p in system.parts:
        a = p.a
        den, denc = 1.0 - a[:, None] * w[None, :], 1.0 - a[:, None] * wc[None, :]
        if min(np.abs(den).min(initial=np.inf), np.abs(denc).min(initial=np.inf)) < _MIN_DENOMINATOR:
            return None
        z_ss = (p.G0[:, None] * w + p.G1[:, None]) * spec / den            # (K, M) at w
        z_ssc = (p.G0[:, None] * wc + p.G1[:, None]) * np.conj(spec) / denc  # at conj(w)
        if from_rest:
            if gam.size:
                gap = np.exp(sl)[None, :] - a[:, None]                       # (K, L)
                if np.abs(gap).min() < _MIN_DENOMINATOR:
                    return None
                Kc = gam[None, :] * (p.G0[:, None] + p.G1[:, None] * np.exp(sl)[None, :]) / gap
            else:
                Kc = np.zeros((len(a), 0), complex)
            start = start_of(p) + Kc.sum(axis=1)                             # the mode's own decay
            log_a = p.lam * p.T
        for k in range(n_windows):
            Z, Zc = z_ss, z_ssc
            if from_rest:
                ga, gac = _window_geometric(log_a, w, k, P), _window_geometric(log_a, wc, k, P)
                gi, gic = geo_in[k]
                Z = Z + Kc @ gi - start[:, None] * ga
                Zc = Zc + Kc @ gic - start[:, None] * gac
            out[k] += 0.5 * (p.co @ Z + np.conj(p.co @ Zc))
        D_total += p.D
    if D_total != 0.0:
        for k in range(n_windows):
            out[k] += D_total * (spec + (gam @ geo_in[k][0] if gam.size else 0.0))
    return out


def _factored(system, P, start_of, input_transient, w, spec, n_windows, from_rest):
    """The same sums with the output row taken first: every term of a part's coordinate
    spectra at a bin is a mode's coefficient over (1 - a w), so one reciprocal per mode and
    bin (at w and conj(w) side by side) and one matrix product replace the per-window
    mode-by-bin temporaries; the input transient's window sums likewise (one reciprocal per
    pole and bin, a factor per window)."""
    M = len(w)
    ww = np.concatenate([w, np.conj(w)])                                     # bins at w, then at conj(w)
    gam, sl = input_transient.gain, input_transient.log_pole
    W = int(n_windows)
    out = np.zeros((W, M), complex)
    if gam.size:
        # the input transient's window sums: exp(s kP) (1 - exp(s P)) / (1 - exp(s) w)
        inv_in = 1.0 / (1.0 - np.exp(sl)[:, None] * ww)                     # (L, 2M)
        heads = np.exp(np.outer(np.arange(W) * P, sl)) * -np.expm1(sl * P)   # (W, L)
    D_total = 0.0
    for p in system.parts:
        a, co = p.a, p.co
        # |1 - a w| >= 1 - |a| on the unit circle: the bins' check only where that is too small
        if np.abs(a).max(initial=0.0) > 1.0 - _MIN_DENOMINATOR and \
                np.abs(1.0 - a[:, None] * ww).min(initial=np.inf) < _MIN_DENOMINATOR:
            return None
        inv = 1.0 / (1.0 - a[:, None] * ww)                                  # (K, 2M)
        if from_rest:
            if gam.size:
                gap = np.exp(sl)[None, :] - a[:, None]                       # (K, L)
                if np.abs(gap).min() < _MIN_DENOMINATOR:
                    return None
                Kc = gam * (p.G0[:, None] + p.G1[:, None] * np.exp(sl)) / gap
            start = start_of(p)                                              # steady state at phase 0
            if gam.size:
                start = start + Kc.sum(axis=1)                               # the mode's own decay
            log_a = p.lam * p.T
            rows = np.empty((2 + W, len(a)), complex)
            rows[2:] = (co * start * -np.expm1(log_a * P)) * np.exp(np.outer(np.arange(W) * P, log_a))
        else:
            rows = np.empty((2, len(a)), complex)
        rows[0] = co * p.G0
        rows[1] = co * p.G1
        R = rows @ inv                                                       # (2 + W, 2M)
        steady = spec * (w * R[0, :M] + R[1, :M])                            # co . z_ss at w
        steady_c = np.conj(spec) * (ww[M:] * R[0, M:] + R[1, M:])            # ... at conj(w)
        if not from_rest:
            out += 0.5 * (steady + np.conj(steady_c))
        else:
            Z = np.concatenate([steady, steady_c]) - R[2:]                   # (W, 2M)
            if gam.size:
                Z += (heads * (co @ Kc)) @ inv_in                            # particular solutions
            out += 0.5 * (Z[:, :M] + np.conj(Z[:, M:]))
        D_total += p.D
    if D_total != 0.0:
        out += D_total * (spec + ((heads * gam) @ inv_in[:, :M] if gam.size else 0.0))
    return out
