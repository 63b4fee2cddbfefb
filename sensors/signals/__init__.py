"""Stage 1, signals: what is played and what is heard, independent of how it was produced.

Excitations, the paper's spectral features, the observation type shared by simulation and the
rig, and the recorded gripper leak. The scikit-learn transformer (``signals.transformers``) is
not imported here: it pulls in scikit-learn.
"""

from .corruption import (BackgroundNoise, Clipping, CorruptionPipeline, DCOffset, DroppedBuffers, GainDrift,
                         Latency)
from .excitation import Excitation
from .features import (amplitude_spectrum, feature_frequencies_hz, scale_features, segment, smooth_spectrum,
                       spectral_features, validate_waveform)
from .leak import LeakRecording, align_leak, aligned_leak_cycle, load_leak, save_leak
from .noise_library import NOISE_KINDS, load_noise_folder, noise_segment, synthesize_noise
from .observation import AcousticObservation, AcousticSensor
from .stream_corruption import NOISE_BLOCK_S, CorruptedStream, StreamCorruptor
from .spectrogram import mel_filterbank, mel_frequencies_hz, mel_spectrogram, spectrogram, spectrogram_frequencies_hz

__all__ = ["Excitation", "amplitude_spectrum", "feature_frequencies_hz", "scale_features", "segment",
           "smooth_spectrum", "spectral_features", "validate_waveform", "LeakRecording", "align_leak",
           "aligned_leak_cycle", "load_leak",
           "save_leak", "AcousticObservation", "AcousticSensor", "BackgroundNoise", "Clipping", "CorruptionPipeline",
           "DCOffset", "DroppedBuffers", "GainDrift", "Latency", "NOISE_KINDS", "load_noise_folder", "noise_segment",
           "synthesize_noise", "mel_filterbank", "mel_frequencies_hz", "mel_spectrogram", "spectrogram",
           "spectrogram_frequencies_hz", "NOISE_BLOCK_S", "CorruptedStream", "StreamCorruptor"]
