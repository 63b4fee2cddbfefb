"""The active acoustic sensor: excitations, features, FEM modal analysis and modal synthesis.

This package imports neither MuJoCo nor PyAudio: simulation (``aas_gym``) and the real rig
(``real``) both build on it. The whole workflow, from a solid to the paper's 140 features::

    import sensors

    bar = sensors.ModalModel.bar(0.2, 0.025, 0.025, "aluminium")    # FEM modes, cached on disk
    bar.frequencies_hz[:3]                                          # its first elastic modes
    h = 0.0125                                                      # the fingers press the +-y faces
    actuator = sensors.Contact([0.04, h, 0.0], [0, 1, 0], force_n=40.0, friction=0.8)
    mic = sensors.Contact([0.04, -h, 0.0], [0, -1, 0], force_n=40.0, friction=0.8)
    sweep = sensors.Excitation.linear_sweep()                       # 20 Hz -> 10 kHz in 0.5 s
    obs = sensors.simulate_recording(bar, sweep, 1.0, actuator, mic, noise_std=1e-4, rng=0)
    obs.features().shape                                            # (140,): 3-9.95 kHz in 50 Hz steps

The same ``AcousticObservation`` comes from the real rig (``real.RealAcousticSensor``), so what
is trained on it moves between the two unchanged.

The subpackages are the stages of that pipeline, each importing only earlier ones:
``signals`` (excitations, features, observations, leak) < ``materials`` < ``mesh`` < ``fem``
< ``modal`` (modal models, contacts, damping) < ``synthesis`` (modal response, drive,
recording, streaming) < ``objects`` (the catalog) < ``fluid`` (liquids in containers) <
``calibration`` < ``task`` (the grasp task shared by sim and real); ``_infra`` holds the
infrastructure (atomic files, cache, LRU). docs/ARCHITECTURE.md says where each idea lives.

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
from .synthesis.contact_modes import contact_modes
from .synthesis.fingertip import FingertipModel
from .signals.leak import LeakRecording, align_leak, load_leak, save_leak
from .synthesis.caches import SynthesisCache
from .synthesis.grasp_state import ContactTolerance, GraspState
from .synthesis.recording import simulate_recording
from .synthesis.stream import AcousticStream
from .synthesis.passive import ContactLoads, PassiveSound
from .materials.solids import Material, MATERIALS, get_material
from .modal.basis import MaterialView, ModalBasis, with_material
from .modal.model import ModalModel
from .mesh.tets import MeshError
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
