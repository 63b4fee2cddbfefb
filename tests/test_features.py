"""Spectral features against exact tones and the bin definition."""

import numpy as np
import pytest

from sensors import SpectralFeatures, amplitude_spectrum, feature_frequencies_hz, smooth_spectrum, spectral_features

FS = 44100


def _tone(freq_hz, amplitude, seconds, sample_rate_hz=FS, phase=0.3):
    t = np.arange(int(round(seconds * sample_rate_hz))) / sample_rate_hz
    return amplitude * np.sin(2 * np.pi * freq_hz * t + phase)


def test_bin_frequencies_are_exact():
    f = feature_frequencies_hz()
    assert f.shape == (140,)
    np.testing.assert_array_equal(f, 3000.0 + 50.0 * np.arange(140))
    assert f[0] == 3000.0 and f[-1] == 9950.0


@pytest.mark.parametrize("freq_hz", [3000.0, 5050.0, 9950.0])
@pytest.mark.parametrize("period_s", [0.5, 0.317, 0.2])  # aligned and non-aligned window lengths
def test_pure_tone_lands_in_its_bin_with_its_amplitude(freq_hz, period_s):
    x = _tone(freq_hz, 0.37, 1.0)
    feats = spectral_features(x, FS, period_s=period_s)
    k = int(round((freq_hz - 3000) / 50))
    assert np.argmax(feats) == k
    # The exact DTFT of a windowed sine: A plus the leakage of its negative-frequency image.
    assert feats[k] == pytest.approx(0.37, rel=2e-3)


def test_feature_equals_direct_dtft_for_any_window_length():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(20000)
    feats = spectral_features(x, FS, period_s=0.2)  # 8820 samples: 5 Hz resolution, 50 Hz bins aligned
    odd = spectral_features(x, FS, period_s=0.2001, average=False)  # not aligned -> chirp-z
    n = round(0.2001 * FS)
    t = np.arange(n)
    for k in (0, 77, 139):
        f = 3000 + 50 * k
        direct = 2 * np.abs(np.exp(-2j * np.pi * f * t / FS) @ x[:n]) / n
        assert odd[0, k] == pytest.approx(direct, rel=1e-9)
    assert feats.shape == (140,)


def test_windows_start_at_the_offset_and_average():
    x = np.concatenate([np.zeros(1000), _tone(4000, 1.0, 1.0, phase=0.0)])
    per_window = spectral_features(x, FS, start_s=1000 / FS, average=False)
    assert per_window.shape == (2, 140)
    np.testing.assert_allclose(per_window[:, 20], 1.0, rtol=1e-9)
    np.testing.assert_allclose(spectral_features(x, FS, start_s=1000 / FS), per_window.mean(axis=0))


def test_full_spectrum_and_smoothing():
    x = _tone(6000, 0.5, 1.0)
    f, a = amplitude_spectrum(x, FS)
    assert f[1] == pytest.approx(2.0)
    assert a[np.argmin(np.abs(f - 6000))] == pytest.approx(0.5, rel=1e-9)
    smooth = smooth_spectrum(a)
    assert smooth.shape == a.shape and np.all(np.isfinite(smooth))


@pytest.mark.parametrize(
    "waveform, kwargs, word",
    [
        (np.array([]), {}, "empty"),
        (np.full(30000, np.nan), {}, "NaN"),
        (np.zeros(1000), {}, "too short"),
        (np.zeros(30000), {"sample_rate_hz": 8000}, "sample_rate_hz"),
        (np.zeros(30000), {"sample_rate_hz": -1}, "sample_rate_hz"),
        (np.zeros((2, 30000)), {}, "1-D"),
        (np.zeros(30000), {"start_s": -0.1}, "start_s"),
        (np.zeros(30000), {"period_s": 0}, "period_s"),
    ],
)
def test_bad_input_raises_naming_the_problem(waveform, kwargs, word):
    with pytest.raises(ValueError, match=word):
        spectral_features(waveform, **kwargs)


def test_bad_band_is_named():
    with pytest.raises(ValueError, match="f_max_hz"):
        spectral_features(np.zeros(30000), f_min_hz=3000, f_max_hz=25000)
    with pytest.raises(ValueError, match="step_hz"):
        feature_frequencies_hz(step_hz=0)


def test_transformer_in_a_pipeline_matches_the_function():
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline

    rng = np.random.default_rng(1)
    X = np.stack([_tone(3000 + 500 * (i % 2), 1.0, 0.5) + 0.01 * rng.standard_normal(22050) for i in range(8)])
    y = np.arange(8) % 2
    feats = SpectralFeatures().fit_transform(X)
    assert feats.shape == (8, 140)
    np.testing.assert_allclose(feats[3], spectral_features(X[3]))
    clf = make_pipeline(SpectralFeatures(), KNeighborsClassifier(n_neighbors=1)).fit(X, y)
    assert (clf.predict(X) == y).all()
    assert SpectralFeatures().fit(X).get_feature_names_out()[0] == "amp_3000hz"


def test_transformer_passes_sklearn_estimator_checks():
    from sklearn.utils.estimator_checks import check_estimator

    with pytest.warns(UserWarning, match="zero-padded"):
        results = check_estimator(SpectralFeatures(), on_fail=None)
    failed = [r["check_name"] for r in results if r["status"] == "failed"]
    assert failed == []


def test_feature_scales_read_a_known_tone():
    """A 1e-3 sine on a feature bin reads 1e-3 linear, 60 dB re 1e-6, and unit norm."""
    from sensors.signals.features import DB_FLOOR, DB_REFERENCE, scale_features

    sample_rate_hz = 44100
    t = np.arange(sample_rate_hz) / sample_rate_hz
    x = 1e-3 * np.sin(2 * np.pi * 5000.0 * t)
    lin = spectral_features(x, sample_rate_hz)
    k = int(np.argmax(lin))
    assert feature_frequencies_hz()[k] == 5000.0
    db = scale_features(lin, "db")
    assert abs(db[k] - 60.0) < 0.01
    assert abs(20 * np.log10(DB_FLOOR / DB_REFERENCE) - scale_features(np.zeros(3), "db")[0]) < 1e-12
    unit = scale_features(lin, "normalized")
    assert abs(np.linalg.norm(unit) - 1.0) < 1e-12 and unit[k] > 0.99
    assert np.all(scale_features(np.zeros(140), "normalized") == 0)
    with pytest.raises(ValueError, match="feature scale"):
        scale_features(lin, "log")


def test_transformer_and_env_config_scale_alike():
    from sensors import SpectralFeatures
    from sensors.signals.features import scale_features
    from sensors.task import AcousticConfig

    rng = np.random.default_rng(0)
    X = rng.standard_normal((3, 22050)) * 1e-4
    for scale in ("linear", "db", "normalized"):
        got = SpectralFeatures(scale=scale).fit_transform(X)
        linear = np.stack([spectral_features(r, 44100) for r in X])
        want = scale_features(linear, scale)
        np.testing.assert_allclose(got, want, rtol=1e-12)
        np.testing.assert_allclose(AcousticConfig(feature_scale=scale).scale_features(linear[0]), want[0], rtol=1e-6)
