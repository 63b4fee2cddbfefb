"""AcousticObservation: validation, features, atomic persistence."""

import os

import numpy as np
import pytest

from sensors import AcousticObservation, AcousticSensor, Excitation, spectral_features


def _obs(**kw):
    exc = Excitation.linear_sweep()
    rng = np.random.default_rng(0)
    args = dict(waveform=rng.standard_normal(44100 + 300), sample_rate_hz=44100, excitation=exc,
                start_time_s=300 / 44100, metadata={"source": "test"})
    args.update(kw)
    return AcousticObservation(**args)


def test_features_use_the_excitation_period_and_start():
    obs = _obs()
    assert obs.waveform.dtype == np.float32
    np.testing.assert_allclose(obs.features(), spectral_features(obs.waveform, 44100, start_s=300 / 44100))
    assert obs.features().shape == (140,)
    assert obs.features(average=False).shape == (2, 140)


def test_save_load_round_trip_and_atomicity(tmp_path):
    obs = _obs()
    path = obs.save(tmp_path / "rec")
    assert path.name == "rec.npz"
    assert [p.name for p in tmp_path.iterdir()] == ["rec.npz"]  # no temporary file left
    back = AcousticObservation.load(path)
    np.testing.assert_array_equal(back.waveform, obs.waveform)
    assert back.excitation == obs.excitation and back.metadata == {"source": "test"}
    assert back.start_time_s == obs.start_time_s


def test_failed_save_leaves_no_file(tmp_path):
    obs = _obs(metadata={"not json": object()})
    with pytest.raises(TypeError):
        obs.save(tmp_path / "bad.npz")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize(
    "kw, word",
    [
        ({"waveform": np.array([])}, "waveform"),
        ({"waveform": np.array([1.0, np.nan])}, "NaN"),
        ({"sample_rate_hz": 48000}, "sample_rate_hz"),
        ({"start_time_s": -1.0}, "start_time_s"),
    ],
)
def test_bad_observations_are_rejected(kw, word):
    with pytest.raises(ValueError, match=word):
        _obs(**kw)


def test_protocol_is_structural():
    class Echo:
        def sense(self, excitation, duration_s):
            return AcousticObservation(excitation.loop(duration_s), excitation.sample_rate_hz, excitation)

    assert isinstance(Echo(), AcousticSensor)
    obs = Echo().sense(Excitation.impulse(), 1.0)
    assert obs.features().shape == (140,)
