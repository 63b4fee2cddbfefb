"""The sampled periodic steady state of a complex-mode system in closed form per harmonic.

``DiscreteSystem.periodic_response`` (sampled, not band-limited) forms the period-aliased
impulse response h_P[l] (l < P) by power sums and transforms it with an FFT.  For an
:class:`~sensors.synthesis.lti.EigenPart` its transform has a closed form: with
h_P[0] = d + Re sum_k c_k a_k^(P-1), h_P[l] = Re sum_k c_k a_k^(l-1) (0 < l < P),
c_k = co_k (a_k G1_k + G0_k) / (1 - a_k^P) and w = exp(-2 pi i m / P),

    H[m] = d + w/2 sum_k [ r_k / (1 - a_k w) + conj(r_k) / (1 - conj(a_k) w) ],
    r_k = co_k (a_k G1_k + G0_k)

(a geometric sum over one period; the 1 / (1 - a^P) of the aliasing cancels).  The per-mode
residues do not depend on the input, and the evaluation is a few vectorised operations per
harmonic: no power sums, no FFT of the impulse response, and no truncation at a decay
length (the power sums stop where the impulse response falls below 1e-17 of its start).

Used by the closed-form features (``feature_recording``), where every randomized object mass
gives a new fingertip model and so a new drive steady state per episode.  The time-domain
chain keeps ``periodic_response`` (the dataset bytes depend on it).
"""

from __future__ import annotations

import numpy as np

from .lti import DiscreteSystem, EigenPart

__all__ = ["closed_form_periodic_supported", "impulse_spectrum", "sampled_periodic_response"]


def closed_form_periodic_supported(system: DiscreteSystem) -> bool:
    """True when every part of ``system`` is in complex-mode form (the closed form applies)."""
    return all(isinstance(p, EigenPart) for p in system.parts)


def impulse_spectrum(system: DiscreteSystem, P: int) -> np.ndarray:
    """``np.fft.rfft`` of the period-aliased impulse response of ``system`` over a loop of
    ``P`` samples (P // 2 + 1 complex values), in closed form per mode (module docstring)."""
    m = np.arange(P // 2 + 1)
    w = np.exp(-2j * np.pi * m / P)                        # (M,)
    H = np.zeros(m.shape, dtype=complex)
    for p in system.parts:
        if not isinstance(p, EigenPart):
            raise TypeError("the closed form needs complex-mode parts (closed_form_periodic_supported)")
        r = p.co * (p.a * p.G1 + p.G0)                     # (K,), conjugate weight folded in co
        acc = (r[:, None] / (1.0 - p.a[:, None] * w[None, :])).sum(axis=0)
        acc += (np.conj(r)[:, None] / (1.0 - np.conj(p.a)[:, None] * w[None, :])).sum(axis=0)
        H += 0.5 * w * acc + p.direct()
    return H


def sampled_periodic_response(system: DiscreteSystem, force_spectrum: np.ndarray, P: int) -> np.ndarray:
    """One period of the sampled (first-order-hold) periodic steady state of ``system`` under
    an input of period ``P`` samples with ``np.fft.rfft`` ``force_spectrum``: what
    ``system.periodic_response(u, force_spectrum=U)`` gives, its impulse spectrum in closed form."""
    return np.fft.irfft(force_spectrum * impulse_spectrum(system, P), P)
