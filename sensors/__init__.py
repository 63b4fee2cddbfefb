"""The active acoustic sensor: excitations, features, FEM modal analysis and modal synthesis.

This package imports neither MuJoCo nor PyAudio: simulation (``aas_gym``) and the real rig
(``real``) both build on it.

Modal estimation, calibration, the scikit-learn transformer, the object catalog (``get_object``,
``ObjectSpec``) and ``filled`` (a container holding a liquid) are exported lazily (PEP 562): they
pull in scikit-learn, scipy.optimize, trimesh and the sparse solvers, which ``import sensors``
should not pay for.
"""

from .signals.excitation import Excitation
from .signals.features import amplitude_spectrum, feature_frequencies_hz, scale_features, smooth_spectrum, spectral_features
from .signals.observation import AcousticObservation, AcousticSensor
from .modal.contact import Contact
from .modal.damping import modal_damping_matrix
from .synthesis.modal_system import ModalSystem, modal_response, modal_state_matrix, periodic_response
from .synthesis.fingertip import FingertipModel
from .signals.leak import LeakRecording, align_leak, load_leak, save_leak
from .synthesis.recording import SynthesisCache, simulate_recording
from .materials.solids import Material, MATERIALS, get_material
from .modal.basis import MaterialView, ModalBasis, with_material
from .modal.model import ModalModel
from .mesh.meshing import MeshError
from .fem.eigen import EigenSolveError
from ._infra.npz import FileFormatError

_LAZY = {
    "SpectralFeatures": "sensors.signals.transformers",
    "ModalEstimate": "sensors.calibration.estimation",
    "estimate_modes": "sensors.calibration.estimation",
    "estimate_modes_from_observation": "sensors.calibration.estimation",
    "transfer_function": "sensors.calibration.estimation",
    "CalibrationResult": "sensors.calibration",
    "RecordingSetup": "sensors.calibration",
    "calibrate": "sensors.calibration",
    "load_material": "sensors.calibration",
    "save_material": "sensors.calibration",
    "filled": "sensors.fluid",
    "ObjectSpec": "sensors.objects",
    "get_object": "sensors.objects",
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
