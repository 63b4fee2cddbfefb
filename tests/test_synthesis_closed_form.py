"""Per-mode closed-form references: impulse, step and sine, for under-, critically and
over-damped single modes, for both synthesis methods."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import quad

from sensors.synthesis.modal_system import ModalSystem, modal_response, periodic_response


class OneMode:
    """One mode, shape constant in space: U(p) = s * e_y, damping c = alpha."""

    def __init__(self, f_hz, zeta, shape=0.7):
        self.angular_frequencies_rad_s = np.array([2 * np.pi * f_hz])
        self.frequencies_hz = np.array([f_hz])
        w = self.angular_frequencies_rad_s[0]
        self.material = SimpleNamespace(alpha=2 * zeta * w, beta=0.0, gamma=0.0)
        self.s = shape

    def mode_shapes_at(self, p):
        p = np.atleast_2d(p)
        out = np.zeros((len(p), 3, 1))
        out[:, 1, 0] = self.s
        return out


DRIVE = (np.zeros(3), np.array([0.0, -1.0, 0.0]))  # force pushes along +y
MIC = (np.zeros(3), np.array([0.0, 1.0, 0.0]))      # read +y displacement
REGIMES = [0.02, 1.0, 3.0]                          # under, critical, over damped


def roots(w, zeta):
    d = np.sqrt(complex(zeta * zeta - 1.0))
    return w * (-zeta + d), w * (-zeta - d)


def impulse_resp(t, w, zeta):
    """Unit-impulse displacement response of q'' + 2 zeta w q' + w^2 q = delta."""
    if zeta == 1.0:
        return t * np.exp(-w * t)
    l1, l2 = roots(w, zeta)
    return ((np.exp(l1 * t) - np.exp(l2 * t)) / (l1 - l2)).real


def step_resp(t, w, zeta):
    if zeta == 1.0:
        return (1 - (1 + w * t) * np.exp(-w * t)) / w**2
    l1, l2 = roots(w, zeta)
    return ((1 + (l2 * np.exp(l1 * t) - l1 * np.exp(l2 * t)) / (l1 - l2)) / w**2).real


def run(model, u, sample_rate_hz, method):
    return modal_response(model, u, sample_rate_hz, *DRIVE, *MIC, method=method)


@pytest.mark.parametrize("method", ["exact", "diagonal"])
@pytest.mark.parametrize("zeta", REGIMES)
def test_step(method, zeta):
    sample_rate_hz, f = 44100, 1500.0
    m = OneMode(f, zeta)
    u = np.full(3000, 2.5)  # constant force from t = 0
    y = run(m, u, sample_rate_hz, method)
    t = np.arange(len(u)) / sample_rate_hz
    ref = 2.5 * m.s * m.s * step_resp(t, 2 * np.pi * f, zeta)
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("method", ["exact", "diagonal"])
@pytest.mark.parametrize("zeta", REGIMES)
def test_impulse(method, zeta):
    """A one-sample pulse is a triangle of width T under first-order hold: compare with the
    closed-form impulse response integrated against it by adaptive quadrature."""
    sample_rate_hz, f = 44100, 2000.0
    w = 2 * np.pi * f
    T = 1 / sample_rate_hz
    m = OneMode(f, zeta)
    u = np.zeros(2000)
    u[0] = 3.0
    y = run(m, u, sample_rate_hz, method)
    n = np.array([1, 2, 5, 17, 100, 401, 1999])
    ref = np.array([quad(lambda s: impulse_resp(k * T - s, w, zeta) * 3.0 * (1 - s / T), 0, T,
                         epsabs=0, epsrel=1e-13)[0] for k in n]) * m.s**2
    assert np.allclose(y[n], ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    # and close to an ideal impulse of the same area (3 T / 2) at the triangle's centroid
    ideal = 1.5 * T * m.s**2 * impulse_resp(n[3:] * T - T / 3, w, zeta)
    assert np.allclose(y[n[3:]], ideal, rtol=0, atol=5e-3 * np.abs(ref).max())


@pytest.mark.parametrize("method", ["exact", "diagonal"])
@pytest.mark.parametrize("zeta", REGIMES)
def test_sine_from_rest(method, zeta):
    """Sine force switched on at t = 0: steady state + transient matched to rest, in closed
    form.  Sampled at 2 MHz so that linear interpolation of the sine is within 5e-6."""
    sample_rate_hz, f, fd = 2_000_000, 3000.0, 2300.0
    w, W = 2 * np.pi * f, 2 * np.pi * fd
    m = OneMode(f, zeta)
    t = np.arange(40000) / sample_rate_hz
    y = run(m, np.sin(W * t), sample_rate_hz, method)
    H = 1 / (w * w - W * W + 2j * zeta * w * W)
    xp = (H * np.exp(1j * W * t)).imag
    x0, v0 = H.imag, W * H.real
    if zeta == 1.0:
        lam = -w  # (A + B t) e^(lam t)
        A = -x0
        B = -v0 - lam * A
        xh = (A + B * t) * np.exp(lam * t)
    else:
        l1, l2 = roots(w, zeta)
        A2 = (-v0 + l1 * x0) / (l2 - l1)
        A1 = -x0 - A2
        xh = (A1 * np.exp(l1 * t) + A2 * np.exp(l2 * t)).real
    ref = (xp + xh) * m.s**2
    assert np.max(np.abs(y - ref)) <= 2e-5 * np.max(np.abs(ref))


def test_critical_damping_uses_robust_path_and_is_exact():
    """The path taken; its exactness at zeta = 1 is what test_step, test_impulse and
    test_sine_from_rest check (REGIMES holds 1.0)."""
    m = OneMode(1000.0, 1.0)
    sysm = ModalSystem.build(m, 44100, *DRIVE, *MIC)
    assert sysm.methods_used == ["dense"]  # defective eigenvalue -> matrix exponential


def test_periodic_steady_state_per_harmonic():
    """Periodic steady state equals the sum over harmonics of H(j w_q) U_q for a force that is
    a sum of harmonics of the loop frequency (interpolation error kept below 1e-5 by sample_rate_hz)."""
    sample_rate_hz, P = 2_000_000, 20000               # loop frequency 100 Hz
    m = OneMode(1234.0, 0.01)
    w = m.angular_frequencies_rad_s[0]
    t = np.arange(P) / sample_rate_hz
    harmonics = {3: 1.0, 12: 0.5 - 0.3j, 25: 0.2j}
    u = sum((a * np.exp(2j * np.pi * 100 * k * t)).real for k, a in harmonics.items())
    y = periodic_response(m, u, sample_rate_hz, *DRIVE, *MIC)
    ref = 0
    for k, a in harmonics.items():
        W = 2 * np.pi * 100 * k
        ref = ref + (m.s**2 * a / (w * w - W * W + 2j * 0.01 * w * W) * np.exp(1j * W * t)).real
    assert np.max(np.abs(y - ref)) <= 1e-5 * np.max(np.abs(ref))


@pytest.mark.parametrize("zeta", REGIMES)
def test_periodic_equals_late_time_domain_all_regimes(zeta):
    """Dense (critical) and complex-mode paths: the steady state is what the time-domain
    response settles to."""
    sample_rate_hz, P = 44100, 441
    m = OneMode(800.0, zeta)
    u = np.random.default_rng(3).normal(size=P)
    y_p = periodic_response(m, u, sample_rate_hz, *DRIVE, *MIC)
    n_per = 400 if zeta < 1 else 60
    y_t = modal_response(m, np.tile(u, n_per), sample_rate_hz, *DRIVE, *MIC)
    assert np.max(np.abs(y_t[-P:] - y_p)) <= 1e-9 * np.max(np.abs(y_p))
