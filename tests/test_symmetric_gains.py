"""lti_parts' input gains from S-orthogonality (SYMMETRIC_GAINS): A = [[0, W], [-W, -C]] with C
symmetric has diag(I, -I) A symmetric, so V^-1 B follows from v_k^T S B / v_k^T S v_k.  Checked
against the LU reference (1e-11 of the largest gain) and the transfer function against the dense
one, Cout (j w - A)^-1 B (1e-9 relative); systems it does not apply to take the reference."""

import numpy as np
import pytest

from sensors.synthesis import lti
from sensors.synthesis.modal_system import modal_state_matrix


def _system(rng, r, repeated=False, k=3):
    w = np.sort(rng.uniform(2 * np.pi * 200, 2 * np.pi * 15000, r))
    if repeated:                                   # tube-like pairs: equal frequencies
        w[1::2] = w[0::2][: len(w[1::2])]
    d = 4.0 + 3e-7 * w ** 2
    Q = rng.normal(size=(k, r)) * 20.0
    C = np.diag(d) + Q.T @ Q
    A = modal_state_matrix(w, C)
    B = np.concatenate([np.zeros(r), rng.normal(size=r)])
    Cout = np.concatenate([rng.normal(size=r) / w, np.zeros(r)])
    return A, B, Cout


def _parts(A, B, Cout, fast, signature=True):
    saved = lti.SYMMETRIC_GAINS
    lti.SYMMETRIC_GAINS = fast
    try:
        S = np.repeat([1.0, -1.0], len(A) // 2) if signature else None
        return lti.lti_parts(A, B, Cout, 0.0, 1 / 44100, "foh", passive=True, signature=S)
    finally:
        lti.SYMMETRIC_GAINS = saved


def _response(parts, omega):
    return sum(p.frequency_response(omega) for p in parts)


def _dense(A, B, Cout, omega):
    n = len(A)
    return np.array([Cout @ np.linalg.solve(1j * om * np.eye(n) - A, B) for om in omega])


@pytest.mark.parametrize("seed", range(8))
def test_gains_agree_with_the_lu_reference_and_the_dense_transfer_function(seed):
    rng = np.random.default_rng(seed)
    A, B, Cout = _system(rng, int(rng.integers(8, 45)), k=int(rng.integers(1, 10)))
    fast, ref = _parts(A, B, Cout, True), _parts(A, B, Cout, False)
    assert len(fast) == len(ref) == 1 and isinstance(fast[0], lti.EigenPart)
    assert isinstance(fast[0]._vinv, lti.LazyInverseRows) and fast[0]._vinv.lu is None   # the fast path ran
    assert np.array_equal(fast[0].lam, ref[0].lam)
    g, g_ref = fast[0].g, ref[0].g
    assert np.abs(g - g_ref).max() <= 1e-11 * np.abs(g_ref).max()
    # the state map's rows stay the reference's (the same LU, made on first use)
    assert np.array_equal(fast[0].Vinv, ref[0].Vinv)
    omega = 2 * np.pi * np.linspace(3000, 9950, 40)
    H = _dense(A, B, Cout, omega)
    assert np.abs(_response(fast, omega) - H).max() <= 1e-9 * np.abs(H).max()


def test_vectors_of_a_repeated_eigenvalue_that_are_not_s_orthogonal_are_declined():
    """Two undamped modes at one frequency: any basis of the double eigenvalue's eigenspace is
    a valid V, but the formula needs an S-orthogonal one.  A basis mixed with a complex weight
    keeps every v_k^T S v_k well away from 0 (the condition bound passes) and breaks
    v_1^T S v_2 = 0: the residual check must decline it (the reference's LU then gives the
    gains); the unmixed basis is accepted and exact."""
    w = 2 * np.pi * np.array([1000.0, 1000.0, 2500.0])
    A = modal_state_matrix(w, np.zeros((3, 3)))
    B = np.array([0, 0, 0, 1.0, 0.5, 0.2])
    Cout = np.array([1.0, -0.3, 0.4, 0, 0, 0]) / np.concatenate([w, w])
    lam, V = lti.mkl_eig(A)
    V = V / np.linalg.norm(V, axis=0)
    S = np.repeat([1.0, -1.0], 3)
    idx = np.arange(6)
    good = lti.symmetric_gains_part(idx, A, lam, V, S, B, Cout, 0.0, 1 / 44100, "foh")
    omega = 2 * np.pi * np.linspace(3000, 9950, 20)
    assert good is not None
    H = _dense(A, B, Cout, omega)
    assert np.abs(good.frequency_response(omega) - H).max() <= 1e-9 * np.abs(H).max()
    up = np.flatnonzero((lam.imag > 0) & np.isclose(lam.imag, w[0]))
    assert len(up) == 2
    i, j = up
    mixed = V.copy()
    mixed[:, j] = (V[:, i] + 0.5j * V[:, j]) / np.linalg.norm(V[:, i] + 0.5j * V[:, j])
    conj = np.flatnonzero(np.isclose(lam, np.conj(lam[j])))
    mixed[:, conj[0]] = np.conj(mixed[:, j])
    assert np.abs(A @ mixed[:, j] - lam[j] * mixed[:, j]).max() < 1e-9 * np.abs(A).max()   # still an eigenvector
    assert lti.symmetric_gains_part(idx, A, lam, mixed, S, B, Cout, 0.0, 1 / 44100, "foh") is None


def test_systems_it_does_not_apply_to_take_the_reference():
    rng = np.random.default_rng(2)
    A, B, Cout = _system(rng, 16)
    A_ns = A.copy()
    A_ns[20, 25] += 1.0                         # C no longer symmetric
    for M, sig in ((A_ns, True), (A, False)):
        fast, ref = _parts(M, B, Cout, True, sig), _parts(M, B, Cout, False, sig)
        assert np.array_equal(fast[0].g, ref[0].g) and fast[0]._vinv.lu is not None


def test_repeated_frequencies_stay_exact():
    """Equal undamped frequencies (a tube's pairs): whichever path a system takes, its transfer
    function is the dense one's."""
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        A, B, Cout = _system(rng, 12, repeated=True, k=1)
        fast = _parts(A, B, Cout, True)
        omega = 2 * np.pi * np.linspace(3000, 9950, 30)
        H = _dense(A, B, Cout, omega)
        if all(isinstance(p, lti.EigenPart) for p in fast):
            assert np.abs(_response(fast, omega) - H).max() <= 1e-8 * np.abs(H).max()
