"""Excitations against their analytic definitions."""

import numpy as np
import pytest
from scipy.signal import resample_poly

from sensors import Excitation


def _zero_crossing_frequency_hz(x, sample_rate_hz):
    """Frequency from the time between every other zero crossing (one full cycle),
    crossings located by linear interpolation between samples."""
    i = np.flatnonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))
    t = (i + x[i] / (x[i] - x[i + 1])) / sample_rate_hz
    return 0.5 * (t[2:] + t[:-2]), 1.0 / (t[2:] - t[:-2])


@pytest.mark.parametrize("kind", ["linear_sweep", "exponential_sweep"])
def test_sweep_instantaneous_frequency_follows_the_analytic_law(kind):
    exc = getattr(Excitation, kind)()
    assert (exc.f0_hz, exc.f1_hz, exc.duration_s, exc.sample_rate_hz) == (20.0, 10_000.0, 0.5, 44100)
    # Band-limited upsampling makes linear interpolation of the crossings accurate even
    # at 10 kHz, where one cycle has only 4.4 samples.
    up = 16
    x = resample_poly(exc.signal[: exc.active_samples], up, 1)
    t, measured = _zero_crossing_frequency_hz(x, exc.sample_rate_hz * up)
    inside = (t > 0.005) & (t < 0.495)  # away from the resampling filter's edge transients
    t, measured = t[inside], measured[inside]
    expected = 20.0 + 9980.0 * t / 0.5 if kind == "linear_sweep" else 20.0 * 500.0 ** (t / 0.5)
    np.testing.assert_allclose(exc.instantaneous_frequency_hz(t), expected, rtol=1e-12)
    np.testing.assert_allclose(measured, expected, rtol=0.01)
    assert measured.size > 1000


def test_sweep_amplitude_and_period():
    exc = Excitation.exponential_sweep(amplitude=0.5, period_s=0.75)
    assert exc.signal.shape == (round(0.75 * 44100),)
    assert np.max(np.abs(exc.signal)) <= 0.5 + 1e-12
    assert np.max(np.abs(exc.signal)) > 0.49
    assert np.all(exc.signal[exc.active_samples:] == 0)


def test_impulse_energy_and_duration():
    exc = Excitation.impulse()
    assert exc.duration_s == 0.01 and exc.period_s == 0.5 and exc.shape == "click"
    assert exc.active_samples == 441
    x = Excitation.impulse(shape="rect").signal
    nonzero = np.flatnonzero(x)
    assert nonzero[0] == 0 and nonzero[-1] == 440  # 0.01 s at 44.1 kHz = 441 samples
    assert np.sum(x**2) / exc.sample_rate_hz == pytest.approx(0.01)  # energy of a unit pulse of 0.01 s
    click = Excitation.impulse(amplitude=0.8)
    assert np.flatnonzero(click.signal).tolist() == [0]
    assert np.sum(click.signal**2) == pytest.approx(0.64)
    # A click's spectrum is flat: every feature bin reads the same amplitude.
    from sensors import spectral_features

    feats = spectral_features(click.loop(1.0), click.sample_rate_hz)
    np.testing.assert_allclose(feats, 2 * 0.8 / click.period_samples, rtol=1e-9)


def test_loop_repeats_the_period():
    exc = Excitation.linear_sweep()
    x = exc.loop(1.3)
    assert x.size == round(1.3 * 44100)
    np.testing.assert_array_equal(x[:22050], exc.signal)
    np.testing.assert_array_equal(x[22050:44100], exc.signal)
    np.testing.assert_array_equal(x[44100:], exc.signal[: x.size - 44100])


def test_round_trip_and_names():
    exc = Excitation.linear_sweep(100, 8000, 0.4, period_s=0.5, fade_s=0.01)
    assert Excitation.from_dict(exc.to_dict()) == exc
    assert Excitation.by_name("exponential").kind == "exponential"
    assert Excitation.by_name("linear_sweep").kind == "linear"  # the long form is still understood
    # a file written before the names were unified ("fs", "linear_sweep") still loads, the same
    old = dict(exc.to_dict(), kind="linear_sweep")
    old["fs"] = old.pop("sample_rate_hz")
    assert Excitation.from_dict(old) == exc


@pytest.mark.parametrize(
    "factory, kwargs, word",
    [
        (Excitation.linear_sweep, {"f1_hz": 30_000.0}, "f1_hz"),
        (Excitation.linear_sweep, {"f0_hz": 5000.0, "f1_hz": 4000.0}, "f0_hz"),
        (Excitation.exponential_sweep, {"f0_hz": 0.0}, "f0_hz"),
        (Excitation.linear_sweep, {"duration_s": -1.0}, "duration_s"),
        (Excitation.linear_sweep, {"duration_s": 0.6}, "period_s"),
        (Excitation.impulse, {"duration_s": float("nan")}, "duration_s"),
        (Excitation.impulse, {"sample_rate_hz": 0}, "sample_rate_hz"),
        (Excitation.impulse, {"shape": "triangle"}, "shape"),
        (Excitation.linear_sweep, {"fade_s": 0.3}, "fade_s"),
    ],
)
def test_bad_parameters_are_named(factory, kwargs, word):
    with pytest.raises(ValueError, match=word):
        factory(**kwargs)
