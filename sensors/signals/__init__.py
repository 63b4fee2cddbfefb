"""Stage 1, signals: what is played and what is heard, independent of how it was produced.

Excitations, the paper's spectral features, the observation type shared by simulation and the
rig, and the recorded gripper leak. The scikit-learn transformer (``signals.transformers``) is
not imported here: it pulls in scikit-learn.
"""

from .excitation import Excitation
from .features import (amplitude_spectrum, feature_frequencies_hz, scale_features, segment, smooth_spectrum,
                       spectral_features, validate_waveform)
from .leak import LeakRecording, align_leak, aligned_leak_cycle, load_leak, save_leak
from .observation import AcousticObservation, AcousticSensor

__all__ = ["Excitation", "amplitude_spectrum", "feature_frequencies_hz", "scale_features", "segment",
           "smooth_spectrum", "spectral_features", "validate_waveform", "LeakRecording", "align_leak",
           "aligned_leak_cycle", "load_leak",
           "save_leak", "AcousticObservation", "AcousticSensor"]
