"""The active acoustic sensor: excitations, features, FEM modal analysis and modal synthesis.

This package imports neither MuJoCo nor PyAudio: simulation (``aas_gym``) and the real rig
(``real``) both build on it.

Modal estimation, calibration and the scikit-learn transformer are exported lazily (PEP 562):
they pull in scikit-learn and scipy.optimize, which ``import sensors`` should not pay for.
"""

from .excitation import Excitation
from .features import amplitude_spectrum, feature_frequencies_hz, scale_features, smooth_spectrum, spectral_features
from .observation import AcousticObservation, AcousticSensor
from .contact import Contact
from .damping import modal_damping_matrix
from .synthesis import ModalSystem, modal_response, modal_state_matrix, periodic_response
from .fingertip import FingertipModel
from .leak import LeakRecording, align_leak, load_leak, save_leak
from .recording import SynthesisCache, simulate_recording
from .materials import Material, MATERIALS, get_material
from .modal_basis import MaterialView, ModalBasis, with_material
from .modal_model import ModalModel
from .meshing import MeshError
from .eigen import EigenSolveError
from .npz import FileFormatError

_LAZY = {
    "SpectralFeatures": "sensors.transformers",
    "ModalEstimate": "sensors.modal_estimation",
    "estimate_modes": "sensors.modal_estimation",
    "estimate_modes_from_observation": "sensors.modal_estimation",
    "transfer_function": "sensors.modal_estimation",
    "CalibrationResult": "sensors.calibration",
    "RecordingSetup": "sensors.calibration",
    "calibrate": "sensors.calibration",
    "load_material": "sensors.calibration",
    "save_material": "sensors.calibration",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'sensors' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
