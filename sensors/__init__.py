"""The active acoustic sensor: excitations, features, FEM modal analysis and modal synthesis.

This package imports neither MuJoCo nor PyAudio: simulation (``aas_gym``) and the real rig
(``real``) both build on it.
"""

from .excitation import Excitation
from .features import amplitude_spectrum, feature_frequencies_hz, smooth_spectrum, spectral_features
from .observation import AcousticObservation, AcousticSensor
from .transformers import SpectralFeatures
from .contact import Contact
from .damping import modal_damping_matrix
from .synthesis import ModalSystem, modal_response, periodic_response
from .fingertip import FingertipModel
from .leak import LeakRecording, align_leak, load_leak, save_leak
from .recording import simulate_recording
from .modal_estimation import ModalEstimate, estimate_modes, estimate_modes_from_observation, transfer_function
from .materials import Material, MATERIALS, get_material
from .modal_model import ModalModel
from .calibration import CalibrationResult, RecordingSetup, calibrate, load_material, save_material
