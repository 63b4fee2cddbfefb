"""Every deprecated spelling still works for one release: it warns (a DeprecationWarning that
names the new spelling and points at the caller's line) and behaves exactly as the new
spelling; the new spelling does not warn."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import sensors


@pytest.mark.parametrize("name", ["spectral_features", "amplitude_spectrum"])
def test_fs_keyword_of_the_feature_functions(name):
    func = getattr(sensors, name)
    ex = sensors.Excitation.by_name("linear", sample_rate_hz=22050)
    with pytest.warns(DeprecationWarning, match=rf"{name}\(fs=\.\.\.\) is deprecated.*sample_rate_hz="):
        old = func(ex.signal, fs=22050)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        new = func(ex.signal, sample_rate_hz=22050)
    if name == "amplitude_spectrum":  # (frequencies, amplitude)
        old, new = np.concatenate(old), np.concatenate(new)
    np.testing.assert_array_equal(old, new)
    with pytest.raises(TypeError, match="both fs= and sample_rate_hz="):
        func(ex.signal, fs=22050, sample_rate_hz=22050)


def test_fs_keyword_of_segment_and_the_transformer():
    from sensors.signals.features import segment

    wave = np.arange(44100.0)
    with pytest.warns(DeprecationWarning, match=r"segment\(fs=\.\.\.\)"):
        old = segment(wave, fs=22050)
    np.testing.assert_array_equal(old, segment(wave, 22050))
    with pytest.warns(DeprecationWarning, match=r"SpectralFeatures.__init__\(fs=\.\.\.\)"):
        t = sensors.SpectralFeatures(fs=22050)
    assert t.get_params() == sensors.SpectralFeatures(sample_rate_hz=22050).get_params()
