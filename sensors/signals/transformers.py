"""A scikit-learn transformer from raw waveforms to the paper's spectral features."""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from .._infra.deprecation import renamed_keywords
from .features import (DEFAULT_F_MAX_HZ, DEFAULT_F_MIN_HZ, DEFAULT_STEP_HZ, FEATURE_SCALES, feature_frequencies_hz,
                       scale_features, spectral_features)


class SpectralFeatures(TransformerMixin, BaseEstimator):
    """Rows of raw waveforms -> rows of spectral features (140 by default).

    Put it first in a ``Pipeline`` before KNN, SVM or MLP so the classifier is trained on
    raw recordings, simulated or real. All rows must have the same length, aligned so that
    an excitation period starts at ``start_s``. Rows shorter than one window are zero-padded
    to one window (the spectrum of a short snippet) with a warning, since a pipeline may see
    such data; :func:`sensors.spectral_features` itself refuses them.

    Args:
        sample_rate_hz: sample rate of the waveforms in Hz.
        period_s: excitation period = window length, seconds.
        start_s: offset of the first period in each waveform, seconds.
        f_min_hz, f_max_hz, step_hz: feature band and spacing.
        scale: ``"linear"`` amplitude, ``"db"`` or ``"normalized"`` (see
            :func:`sensors.signals.features.scale_features`); the envs' ``feature_scale`` option is the
            same, so features from a pipeline and from an env agree.
    """

    @renamed_keywords({"fs": "sample_rate_hz"})
    def __init__(self, sample_rate_hz=44100, period_s=0.5, start_s=0.0, f_min_hz=DEFAULT_F_MIN_HZ,
                 f_max_hz=DEFAULT_F_MAX_HZ, step_hz=DEFAULT_STEP_HZ, scale="linear"):
        self.sample_rate_hz = sample_rate_hz
        self.period_s = period_s
        self.start_s = start_s
        self.f_min_hz = f_min_hz
        self.f_max_hz = f_max_hz
        self.step_hz = step_hz
        self.scale = scale

    def fit(self, X, y=None):
        """Check the waveforms; nothing is learned."""
        if self.scale not in FEATURE_SCALES:
            raise ValueError(f"scale must be one of {FEATURE_SCALES}, got {self.scale!r}")
        X = validate_data(self, X, dtype=np.float64)
        self._pad_width(X.shape[1])
        self.feature_frequencies_hz_ = feature_frequencies_hz(self.f_min_hz, self.f_max_hz, self.step_hz)
        return self

    def _pad_width(self, n_samples: int) -> int:
        needed = int(round(self.start_s * self.sample_rate_hz)) + int(round(self.period_s * self.sample_rate_hz))
        if n_samples >= needed:
            return 0
        warnings.warn(
            f"waveforms of {n_samples} samples are shorter than one window of {needed} samples "
            f"(start_s={self.start_s} s + period_s={self.period_s} s at sample_rate_hz={self.sample_rate_hz} Hz); zero-padded",
            UserWarning, stacklevel=3,
        )
        return needed - n_samples

    def transform(self, X):
        """Features of each row, shape ``(n_waveforms, n_features)``."""
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        pad = self._pad_width(X.shape[1])
        if pad:
            X = np.pad(X, ((0, 0), (0, pad)))
        out = np.stack([
            spectral_features(row, self.sample_rate_hz, period_s=self.period_s, start_s=self.start_s,
                              f_min_hz=self.f_min_hz, f_max_hz=self.f_max_hz, step_hz=self.step_hz)
            for row in X
        ])
        return scale_features(out, self.scale)

    def get_feature_names_out(self, input_features=None):
        """Feature names ``amp_3000hz`` ... (frequency in Hz)."""
        check_is_fitted(self)
        return np.array([f"amp_{f:g}hz" for f in self.feature_frequencies_hz_], dtype=object)
