"""The state matrix's eigen-decomposition by MKL (``sensors.synthesis.lti.MKL_EIGEN``) against
SciPy's (the reference) and against the transfer function solved directly (no
eigen-decomposition): the same system to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from sensors.fem import pardiso
from sensors.synthesis import lti
from sensors.synthesis.lti import lti_system
from sensors.synthesis.mkl_eigen import mkl_eig
from sensors.synthesis.modal_system import modal_state_matrix

FS = 44100.0
FREQ_HZ = np.arange(3000.0, 10000.0, 50.0)


def state_matrix(r, seed):
    """A contact-damped modal state matrix: modes 1-12 kHz, Rayleigh plus a contact factor."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * np.sort(rng.uniform(1e3, 1.2e4, r))
    Q = rng.normal(size=(3 * r, r)) * 2.0
    A = modal_state_matrix(w, np.diag(5.0 + 1e-9 * w ** 2) + Q.T @ Q)
    B = np.concatenate([np.zeros(r), rng.normal(size=r)])
    Cout = np.concatenate([rng.normal(size=r) / w, np.zeros(r)])
    return A, B, Cout


@pytest.fixture
def with_mkl():
    if mkl_eig(np.eye(2)) is None:
        pytest.skip("MKL is not installed: SciPy's path is the only one")


@pytest.mark.parametrize("r", [3, 21, 37])
def test_mkl_decomposition_against_scipy(with_mkl, r):
    import scipy.linalg

    A, _, _ = state_matrix(r, r)
    lam, V = mkl_eig(A)
    ref = scipy.linalg.eigvals(A)
    scale = np.abs(ref).max()
    assert np.abs(np.sort_complex(lam) - np.sort_complex(ref)).max() <= 1e-13 * scale
    assert np.abs(A @ V - V * lam).max() <= 1e-12 * np.abs(A).max()
    assert np.allclose(np.linalg.norm(V, axis=0), 1.0, rtol=0, atol=1e-14)
    pairs = np.flatnonzero(lam.imag > 0)
    assert np.array_equal(lam[pairs + 1], lam[pairs].conj()) and np.array_equal(V[:, pairs + 1], V[:, pairs].conj())


@pytest.mark.parametrize("r", [21, 37])
def test_systems_of_both_paths_and_the_direct_transfer_function(with_mkl, monkeypatch, r):
    A, B, Cout = state_matrix(r, 100 + r)
    H = {}
    for flag in (False, True):
        monkeypatch.setattr(lti, "MKL_EIGEN", flag)
        H[flag] = lti_system(A, B, Cout, 0.0, FS).frequency_response(FREQ_HZ)
    direct = np.array([Cout @ np.linalg.solve(2j * np.pi * f * np.eye(2 * r) - A, B) for f in FREQ_HZ])
    scale = np.abs(direct).max()
    assert np.abs(H[True] - H[False]).max() <= 1e-12 * scale
    assert np.abs(H[True] - direct).max() <= 1e-10 * scale


def test_without_mkl_scipy_decomposes(monkeypatch):
    monkeypatch.setattr(pardiso, "LIBRARY", [None])          # a machine without MKL
    A, B, Cout = state_matrix(5, 7)
    assert mkl_eig(A) is None
    direct = np.array([Cout @ np.linalg.solve(2j * np.pi * f * np.eye(10) - A, B) for f in FREQ_HZ])
    got = lti_system(A, B, Cout, 0.0, FS).frequency_response(FREQ_HZ)
    assert np.abs(got - direct).max() <= 1e-10 * np.abs(direct).max()
