"""Modal estimation against exact sums of damped sinusoids.

The recordings are built independently of the estimator's circular-convolution view: each
mode is a two-pole recursive filter (exact for ``A exp(-sigma t) cos(2 pi f t + phi)``) run
from rest over the looping excitation, then white noise at a given SNR is added.
"""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from sensors import AcousticObservation, Excitation
from sensors.calibration.estimation import esprit, estimate_modes, estimate_modes_from_observation, transfer_function

FS = 44100


def mode_filter_response(x, f_hz, sigma, amp, phase, sample_rate_hz=FS):
    """Response of ``sum_m amp_m exp(-sigma_m t) cos(2 pi f_m t + phase_m)`` to input x."""
    y = np.zeros(len(x))
    for f, s, a, ph in zip(f_hz, sigma, amp, phase):
        z = np.exp((-s + 2j * np.pi * f) / sample_rate_hz)
        c = a * np.exp(1j * ph)
        y += lfilter([c.real, -(c * np.conj(z)).real], [1.0, -2 * z.real, abs(z) ** 2], x)
    return y


def recording(exc, modes, periods=3, snr_db=None, seed=0):
    f, s, a, ph = modes
    y = mode_filter_response(exc.loop(periods * exc.period_s), f, s, a, ph)
    if snr_db is not None:
        rng = np.random.default_rng(seed)
        y = y + rng.standard_normal(y.size) * np.sqrt(np.mean(y**2)) * 10 ** (-snr_db / 20)
    return y


def rayleigh_modes(f_hz, alpha=4.0, beta=3e-7, seed=1):
    rng = np.random.default_rng(seed)
    f = np.asarray(f_hz, float)
    return f, 0.5 * (alpha + beta * (2 * np.pi * f) ** 2), rng.uniform(0.6, 1.4, f.size), rng.uniform(0, 2 * np.pi, f.size)


def match(est, f_true):
    idx = np.array([np.argmin(np.abs(est.frequencies_hz - f)) for f in f_true])
    return idx


def test_esprit_recovers_exact_poles():
    z_true = np.exp(np.array([-0.01 + 0.3j, -0.002 + 0.31j, -0.05 - 1.2j]))
    n = np.arange(200)
    x = (np.array([1.0, 0.7j, 0.3])[None, :] * z_true[None, :] ** n[:, None]).sum(axis=1)
    z = esprit(x, 3)
    for zt in z_true:
        assert np.min(np.abs(z - zt)) < 1e-9


@pytest.mark.parametrize("kind", ["impulse", "linear"])
def test_modes_with_a_close_pair_at_30_db(kind):
    # 3000 / 3020 Hz: 20 Hz apart with half-power bandwidths of ~18 Hz
    modes = rayleigh_modes([520.0, 1400.0, 3000.0, 3020.0, 4410.0, 6100.0, 7777.0])
    exc = Excitation.by_name(kind)
    est = estimate_modes_from_observation(
        AcousticObservation(recording(exc, modes, snr_db=30.0), FS, exc), f_max_hz=9000.0)
    f, sigma, amp, _ = modes
    i = match(est, f)
    assert len(set(i)) == f.size, "every true mode found once"
    np.testing.assert_allclose(est.frequencies_hz[i], f, atol=1.0)
    isolated = np.abs(f - 3010) > 50
    np.testing.assert_allclose(est.decay_rates_per_s[i][isolated], sigma[isolated], rtol=0.03)
    np.testing.assert_allclose(est.decay_rates_per_s[i][~isolated], sigma[~isolated], rtol=0.10)
    np.testing.assert_allclose(np.abs(est.amplitudes[i][isolated]), amp[isolated], rtol=0.05)
    # the Fisher standard deviations are honest: errors within 4 of them
    assert np.all(np.abs(est.decay_rates_per_s[i] - sigma) < 4 * est.decay_rate_std_per_s[i] + 1e-3 * sigma)
    # nothing spurious of any weight
    extra = np.setdiff1d(np.arange(len(est)), i)
    assert np.all(np.abs(est.amplitudes[extra]) < 0.05 * amp.min())
    assert all(b.fit_ok for b in est.bands)


def test_noise_free_estimates_are_exact_including_a_2_hz_pair():
    modes = rayleigh_modes([800.0, 2500.0, 2502.0, 5000.0], alpha=2.0, beta=1e-7)
    exc = Excitation.impulse()
    tf = transfer_function(recording(exc, modes), exc)
    est = estimate_modes(tf, f_max_hz=8000.0)
    f, sigma, amp, _ = modes
    i = match(est, f)
    np.testing.assert_allclose(est.frequencies_hz[i], f, atol=1e-3)
    np.testing.assert_allclose(est.decay_rates_per_s[i], sigma, rtol=1e-3)
    # amplitudes are those of the steady state: only modes that have died out within a
    # period are free of the start-from-rest transient that the first periods carry
    settled = sigma * exc.period_s > 3.5
    assert settled.sum() >= 2
    np.testing.assert_allclose(np.abs(est.amplitudes[i][settled]), amp[settled], rtol=1e-2)


def test_heavily_damped_modes_use_wider_sub_bands():
    # wood-like: Q of about 6 to 15, half-power bandwidths of 100 to 500 Hz
    modes = rayleigh_modes([700.0, 1900.0, 3600.0], alpha=60.0, beta=4e-6)
    exc = Excitation.linear_sweep()
    est = estimate_modes_from_observation(AcousticObservation(recording(exc, modes, snr_db=40.0), FS, exc))
    f, sigma, _, _ = modes
    i = match(est, f)
    np.testing.assert_allclose(est.frequencies_hz[i], f, rtol=0.01)
    np.testing.assert_allclose(est.decay_rates_per_s[i], sigma, rtol=0.05)


def test_fit_check_flags_what_is_not_modal():
    modes = rayleigh_modes([1000.0, 2000.0])
    exc = Excitation.impulse()
    y = recording(exc, modes, periods=6, snr_db=40.0)
    # a chirp burst repeated in every period (so the period-to-period spread does not see
    # it) is no sum of decaying modes
    t = np.arange(int(0.05 * FS)) / FS
    burst = 0.05 * np.sin(2 * np.pi * (1200.0 * t + 3000.0 * t**2)) * np.hanning(t.size)
    start = int(0.2 * FS)
    for p in range(6):
        y[p * exc.period_samples + start:p * exc.period_samples + start + t.size] += burst
    est = estimate_modes(transfer_function(y, exc), f_max_hz=2400.0)
    flagged = [b for b in est.bands if not b.fit_ok]
    assert flagged and all(b.f_lo_hz < 1500.0 and b.f_hi_hz > 1200.0 for b in flagged)
    clean = [b for b in est.bands if b.f_hi_hz < 1100.0 or b.f_lo_hz > 1600.0]
    assert clean and all(b.fit_ok for b in clean)


def test_start_offset_and_skip_periods():
    modes = rayleigh_modes([1500.0])
    exc = Excitation.impulse()
    y = recording(exc, modes, periods=3)
    delay = 1234
    obs = AcousticObservation(np.concatenate([np.zeros(delay), y]), FS, exc, start_time_s=delay / FS)
    est = estimate_modes_from_observation(obs, f_max_hz=3000.0, skip_periods=0)
    assert len(est) == 1
    assert est.frequencies_hz[0] == pytest.approx(1500.0, abs=1e-3)
    with pytest.raises(ValueError):
        transfer_function(y, exc, skip_periods=3)
    with pytest.raises(ValueError):
        estimate_modes(transfer_function(y, exc), band_hz=50.0)


def test_many_modes_across_the_band():
    # 24 modes, 150 to 9000 Hz, some within 40 Hz of each other: every sub-band fit is small
    rng = np.random.default_rng(5)
    f = np.sort(np.concatenate([np.linspace(150, 9000, 20), [2240.0, 4460.0, 6660.0, 8040.0]]))
    modes = rayleigh_modes(f, alpha=3.0, beta=1.5e-7, seed=7)
    modes = (modes[0], modes[1], rng.uniform(0.5, 1.5, f.size), modes[3])
    exc = Excitation.linear_sweep()
    est = estimate_modes_from_observation(AcousticObservation(recording(exc, modes, snr_db=40.0), FS, exc),
                                          f_max_hz=9500.0)
    i = match(est, f)
    assert len(set(i)) == f.size
    # within 5 % of each mode's half-power bandwidth sigma / pi (the 6660 / 6671 Hz pair overlaps
    # four times over), and within 4 stated standard deviations
    assert np.all(np.abs(est.frequencies_hz[i] - f) < 0.05 * modes[1] / np.pi + 0.05)
    assert np.all(np.abs(est.frequencies_hz[i] - f) < 4 * est.frequency_std_hz[i] + 0.05)
    gap = np.minimum(np.diff(f, prepend=-np.inf), np.diff(f, append=np.inf))
    overlapping = gap < modes[1] / np.pi
    assert overlapping.sum() == 4  # 6660 / 6671 and 8040 / 8068 Hz
    np.testing.assert_allclose(est.decay_rates_per_s[i][~overlapping], modes[1][~overlapping], rtol=0.05)
    np.testing.assert_allclose(est.decay_rates_per_s[i][overlapping], modes[1][overlapping], rtol=0.10)


def test_leak_is_removed_at_its_delay():
    exc = Excitation.linear_sweep()
    y = recording(exc, rayleigh_modes([900.0, 2500.0, 6000.0]), periods=4)
    # the leak: the excitation through a damped gripper mode, steady state, delayed by 37
    leak = recording(exc, ([4100.0], [300.0], [0.3], [0.0]), periods=5)[exc.period_samples:]
    delay = 37
    with_leak = y + np.roll(leak[:y.size], delay)
    clean = transfer_function(y, exc)
    band = (clean.frequencies_hz > 100) & (clean.frequencies_hz < 9800)

    def err(tf):
        return np.linalg.norm((tf.response - clean.response)[band]) / np.linalg.norm(clean.response[band])

    assert err(transfer_function(with_leak, exc)) > 0.01
    assert err(transfer_function(with_leak, exc, leak=leak, leak_delay_samples=delay)) < 1e-6
    assert err(transfer_function(with_leak, exc, leak=leak, leak_delay_samples=delay + 1)) > 1e-3


def test_silence_and_pure_noise_give_no_modes():
    exc = Excitation.impulse()
    for w in (np.zeros(2 * FS), np.random.default_rng(0).standard_normal(2 * FS)):
        assert len(estimate_modes_from_observation(AcousticObservation(w, FS, exc))) == 0


def test_stated_standard_deviations_match_the_scatter():
    # 16 noise draws of the same two modes: the Fisher standard deviations predict the spread
    exc = Excitation.impulse()
    modes = rayleigh_modes([1000.0, 1030.0], alpha=20.0, beta=1e-6)
    clean = recording(exc, modes, periods=3)
    rng = np.random.default_rng(3)
    noise = 0.03 * np.sqrt(np.mean(clean**2))
    f_est, s_est, f_sd, s_sd = [], [], [], []
    for _ in range(16):
        est = estimate_modes(transfer_function(clean + noise * rng.standard_normal(clean.size), exc),
                             f_min_hz=900.0, f_max_hz=1150.0)
        i = match(est, modes[0])
        f_est.append(est.frequencies_hz[i])
        s_est.append(est.decay_rates_per_s[i])
        f_sd.append(est.frequency_std_hz[i])
        s_sd.append(est.decay_rate_std_per_s[i])
    ratio_f = np.std(f_est, axis=0) / np.mean(f_sd, axis=0)
    ratio_s = np.std(s_est, axis=0) / np.mean(s_sd, axis=0)
    # 16 draws estimate a standard deviation to about +-18 %; allow for that and a little more
    assert np.all((ratio_f > 0.5) & (ratio_f < 1.6)), ratio_f
    assert np.all((ratio_s > 0.5) & (ratio_s < 1.6)), ratio_s


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(0.9, 0.999), st.floats(-3.0, 3.0), st.floats(0.3, 3.0)), min_size=1, max_size=5))
def test_esprit_property_noise_free(poles):
    angles = np.array([p[1] for p in poles])
    assume(np.all(np.diff(np.sort(angles)) > 0.05))
    z_true = np.array([r * np.exp(1j * a) for r, a, _ in poles])
    amps = np.array([p[2] for p in poles])
    n = np.arange(160)
    x = (amps[None, :] * z_true[None, :] ** n[:, None]).sum(axis=1)
    z = esprit(x, len(poles))
    for zt in z_true:
        assert np.min(np.abs(z - zt)) < 1e-7
