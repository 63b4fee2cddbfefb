"""Short drive convolutions summed directly (``lti.DIRECT_CONVOLUTION_PRODUCTS``) equal the
FFT path (0: the reference) and an independent reference: the exact discretisation of a
damped two-mode system stepped sample by sample with its matrix exponential (scipy's expm),
written here.  Both paths within 1e-12 of the largest output sample."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from sensors.synthesis import lti

FS = 44100.0


def _system():
    """Two damped modes (1.2 and 7.5 kHz), force on both, displacement output."""
    w = 2 * np.pi * np.array([1200.0, 7500.0])
    zeta = np.array([0.01, 0.003])
    A = np.zeros((4, 4))
    A[:2, 2:] = np.eye(2)
    A[2:, :2] = -np.diag(w ** 2)
    A[2:, 2:] = -np.diag(2 * zeta * w)
    return A, np.array([0, 0, 1.0, 0.7]), np.array([1.0, -0.4, 0, 0])


def _stepped(A, B, C, u, x0):
    """First-order-hold exact steps: x_{k+1} = Phi x_k + G0 u_k + G1 u_{k+1} (the augmented
    matrix exponential of [A B 0; 0 0 1/T; 0 0 0])."""
    n, T = len(A), 1.0 / FS
    E = np.zeros((n + 2, n + 2))
    E[:n, :n], E[:n, n], E[n, n + 1] = A * T, B * T, 1.0
    F = expm(E)
    Phi, G1 = F[:n, :n], F[:n, n + 1]
    G0 = F[:n, n] - G1
    y, x = np.zeros(len(u)), x0.copy()
    for k in range(len(u)):
        y[k] = C @ x
        if k + 1 < len(u):
            x = Phi @ x + G0 * u[k] + G1 * u[k + 1]
    return y


@pytest.mark.parametrize("n", [9, 88, 400, 2205])
def test_direct_and_fft_convolutions_match_the_stepped_system(n):
    A, B, C = _system()
    system = lti.lti_system(A, B, C, 0.0, FS)
    rng = np.random.default_rng(n)
    u = rng.standard_normal(n)
    x0 = 1e-7 * rng.standard_normal(4)
    reference = _stepped(A, B, C, u, x0)
    saved = lti.DIRECT_CONVOLUTION_PRODUCTS
    try:
        fast = system.response(u, x0)
        lti.DIRECT_CONVOLUTION_PRODUCTS = 0
        by_fft = system.response(u, x0)
    finally:
        lti.DIRECT_CONVOLUTION_PRODUCTS = saved
    scale = np.abs(reference).max()
    assert np.abs(fast - by_fft).max() < 1e-12 * scale
    assert np.abs(fast - reference).max() < 1e-12 * scale
    assert np.abs(by_fft - reference).max() < 1e-12 * scale
