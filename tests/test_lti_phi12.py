"""The hold gains phi1(x) = (e^x - 1)/x and phi2(x) = (e^x - 1 - x)/x^2 of ``sensors.synthesis.lti``:
the vectorized Taylor sum (``VECTORIZED_PHI12``) and the term-by-term reference against an
independent evaluation, the matrix exponential of the augmented matrix [[x, 1, 0], [0, 0, 1],
[0, 0, 0]], whose first row is [e^x, phi1(x), phi2(x)]."""
import numpy as np
import pytest
import scipy.linalg

from sensors.synthesis import lti


def _expm_reference(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p1 = np.empty(x.size, complex)
    p2 = np.empty(x.size, complex)
    for i, xi in enumerate(x.ravel()):
        m = np.array([[xi, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]], complex)
        e = scipy.linalg.expm(m)
        p1[i], p2[i] = e[0, 1], e[0, 2]
    return p1.reshape(x.shape), p2.reshape(x.shape)


def _arguments() -> np.ndarray:
    rng = np.random.default_rng(7)
    # lambda T of modal parts: lightly damped, |x| from 1e-6 to a few; both sides of |x| = 1
    r = np.concatenate([10 ** rng.uniform(-6, 0.6, 300), [0.999999, 1.0, 1.000001, 0.5]])
    angle = rng.uniform(np.pi / 2, np.pi, r.size)  # Re x <= 0 (passive)
    x = r * np.exp(1j * angle)
    return np.concatenate([x, [-1e-3 + 0.0j, -0.7 + 0.0j, 1e-12j, -2.0 + 0.3j]])


@pytest.fixture
def restore_flag():
    old = lti.VECTORIZED_PHI12
    yield
    lti.VECTORIZED_PHI12 = old


@pytest.mark.parametrize("vectorized", [True, False])
def test_phi12_matches_augmented_expm(vectorized, restore_flag):
    lti.VECTORIZED_PHI12 = vectorized
    x = _arguments()
    p1, p2 = lti.phi12(x)
    r1, r2 = _expm_reference(x)
    assert np.max(np.abs(p1 - r1) / np.abs(r1)) < 1e-13
    assert np.max(np.abs(p2 - r2) / np.abs(r2)) < 1e-13


@pytest.mark.parametrize("shape", [(1,), (), (3, 4), (0,), (304,)])
def test_vectorized_phi12_equals_reference(shape, restore_flag):
    x = _arguments()[: int(np.prod(shape))].reshape(shape)
    lti.VECTORIZED_PHI12 = False
    ref = lti.phi12(x)
    lti.VECTORIZED_PHI12 = True
    fast = lti.phi12(x)
    for a, b in zip(fast, ref):
        assert a.shape == b.shape == np.shape(x)
        # the sums' order differs: agreement to rounding (the series' terms are <= 1 at |x| < 1)
        assert np.all(np.abs(a - b) <= 1e-15 * np.abs(b))


def test_vectorized_phi12_value_depends_on_its_argument_only(restore_flag):
    """A mode's hold gains must not depend on how many modes share its part (reproducible
    features whatever the system's size)."""
    lti.VECTORIZED_PHI12 = True
    x = _arguments()
    full = lti.phi12(x)
    for start, size in [(0, 1), (5, 2), (17, 3), (40, 9), (100, 33)]:
        part = lti.phi12(x[start:start + size].copy())
        for a, b in zip(part, full):
            assert np.array_equal(a, b[start:start + size])
