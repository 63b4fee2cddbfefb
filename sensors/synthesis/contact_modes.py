"""What a contact set does to an object's modes, without synthesizing audio."""

from __future__ import annotations

import numpy as np

from ..modal.damping import modal_damping_parts
from .modal_system import contact_modal_model, modal_state_matrix

__all__ = ["contact_modes"]


def contact_modes(model, contacts=(), contact_model: str = "spring_damper") -> tuple[np.ndarray, np.ndarray]:
    """``(frequencies_hz, decay_rates_per_s)`` of ``model``'s modes under ``contacts``.

    The eigenvalues lambda = -sigma + i 2 pi f of the modal system with the contacts'
    springs (``contact_model="spring_damper"``, default) or without them (``"damping"``, the
    paper's model) and their damping: f is the damped frequency [Hz], sigma the decay rate of
    the amplitude [1/s].  One entry per oscillating mode, and one per real eigenvalue of an
    over-damped mode (f = 0), ascending in frequency.  Rigid-body motion no spring holds is
    not a mode (``sensors.modal.spring_modes.MIN_MODE_FREQUENCY_HZ``).
    """
    contacts = list(contacts)
    modes = contact_modal_model(model, contacts, contact_model)
    d, Q = modal_damping_parts(modes, contacts)
    w = np.asarray(modes.angular_frequencies_rad_s, float)
    lam = np.linalg.eigvals(modal_state_matrix(w, np.diag(d) + Q.T @ Q))
    scale = max(float(np.abs(lam).max(initial=0.0)), 1e-300)
    real = np.abs(lam.imag) <= 1e-12 * scale
    lam = np.where(real, lam.real + 0j, lam)[real | (lam.imag > 0)]   # one per pair, every real root
    f = lam.imag / (2 * np.pi)
    order = np.lexsort((-lam.real, f))                                 # by frequency, then decay
    f, lam = f[order], lam[order]
    return f, -lam.real
