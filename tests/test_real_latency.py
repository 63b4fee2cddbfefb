"""Latency and synchronization analysis of the rig (no audio device needed)."""

import numpy as np
import pytest

import sensors
from real import find_latency, period_lags
from real.rig import RigRecording, partial_paths, recover_partial


@pytest.mark.parametrize("name", ["impulse", "linear", "exponential"])
@pytest.mark.parametrize("latency", [0, 1, 5000, 30000])
def test_latency_of_a_delayed_loop_is_exact(name, latency):
    ex = sensors.Excitation.by_name(name)
    x = np.concatenate([np.zeros(latency), 0.3 * ex.loop(1.6)])
    assert find_latency(x, ex) == latency
    lags = period_lags(x, ex, latency)
    assert len(lags) == 3 and set(lags) == {latency}


def test_polarity_and_noise_do_not_matter():
    ex = sensors.Excitation.by_name("linear")
    rng = np.random.default_rng(0)
    x = np.concatenate([np.zeros(1234), -0.1 * ex.loop(1.0)]) + 0.02 * rng.standard_normal(1234 + 44100)
    assert find_latency(x, ex) == 1234


def test_noise_alone_has_no_latency():
    ex = sensors.Excitation.by_name("exponential")
    rng = np.random.default_rng(1)
    assert find_latency(rng.standard_normal(88200), ex) is None
    assert find_latency(np.zeros(88200), ex) is None
    assert find_latency(np.ones(100), ex) is None  # shorter than a period


def test_a_damaged_first_period_is_skipped():
    """A device that loses part of its first output buffer: align to the next period."""
    ex = sensors.Excitation.by_name("linear")
    x = np.concatenate([np.zeros(3000), ex.loop(1.5)])
    x[3000:3000 + 4000] = 0.0
    assert find_latency(x, ex) == 3000 + ex.period_samples


def test_inserted_samples_show_as_drift():
    ex = sensors.Excitation.by_name("linear")
    y = ex.loop(1.5)
    x = np.concatenate([np.zeros(500), y[:30000], y[29998:]])  # two samples repeated
    lags = period_lags(x, ex, find_latency(x, ex))
    assert lags.max() - lags.min() == 2


def test_a_lost_and_repeated_block_keeps_the_lags_but_not_the_periods():
    """A block lost and one repeated within one period: alignment holds, the period differs."""
    from real.latency import period_mismatch

    ex = sensors.Excitation.by_name("linear")
    P = ex.period_samples
    y = 0.3 * ex.loop(2.0)
    x = np.concatenate([np.zeros(500), y[:P + 5000], y[P + 6024:P + 7048], y[P + 6024:]])  # 1024 lost, 1024 repeated
    lags = period_lags(x, ex, find_latency(x, ex))
    assert set(lags.tolist()) == {500}
    mismatch = period_mismatch(x, P, lags)
    assert mismatch[0] > 0.1 and mismatch[1] > 0.1 and mismatch.size == 3
    clean = np.concatenate([np.zeros(500), y]) + 1e-3 * np.random.default_rng(0).standard_normal(500 + y.size)
    assert period_mismatch(clean, P, period_lags(clean, ex, 500)).max() < 0.02


def test_recover_partial_without_raw_files_returns_none(tmp_path):
    assert recover_partial(tmp_path / "nothing.npz") is None
    raw, js, npz = partial_paths(tmp_path / "take.npz")
    assert (raw.name, js.name, npz.name) == ("take.partial.f32", "take.partial.json", "take.partial.npz")


def test_rig_recording_observation_layout():
    from real.rig import AudioDevice

    ex = sensors.Excitation.by_name("impulse")
    dev = AudioDevice(0, "card", "ALSA", 2, 2, 44100.0)
    mic = np.concatenate([np.zeros(700), ex.loop(1.2)]).astype(np.float32)
    rec = RigRecording(input=mic[:, None], mic_channel=0, sample_rate_hz=44100, excitation=ex, duration_s=1.0,
                       latency_samples=700, period_lags_samples=[700, 700], events=[], input_device=dev,
                       output_device=dev, stream_mode="separate", reported_latency_s={}, started_at="t")
    obs = rec.to_observation()
    assert obs.waveform.size == 44100 and obs.start_time_s == 0.0 and obs.metadata["source"] == "real"
    np.testing.assert_array_equal(obs.waveform, ex.loop(1.0).astype(np.float32))
    raw = rec.to_observation(trim=False)
    assert raw.waveform.size == mic.size and raw.start_time_s == pytest.approx(700 / 44100)
    np.testing.assert_allclose(raw.features(), obs.features(), rtol=1e-6, atol=1e-12)
