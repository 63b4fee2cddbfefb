"""Stage 6, synthesis: contacts and an excitation -> the microphone signal. The exact LTI
discretisation and the modal system, the lumped fingertip drive, the microphone, and the one
recording chain: a stream across contact changes, of which a batch recording is one span."""

from .caches import SynthesisCache, SystemCache
from .contact_modes import contact_modes
from .feature_recording import FeatureObservation, simulate_features
from .fingertip import FingertipModel
from .grasp_state import ContactTolerance, GraspState
from .microphone import MIC_GAIN_PER_M, mic_gain
from .modal_system import ModalSystem, modal_response, modal_state_matrix, periodic_response
from .passive import ContactLoads, PassiveSound
from .recording import simulate_recording
from .stream import AcousticStream

__all__ = ["contact_modes", "FingertipModel", "ModalSystem", "modal_response", "modal_state_matrix", "periodic_response",
           "SynthesisCache", "simulate_recording", "simulate_features", "FeatureObservation",
           "AcousticStream", "ContactTolerance", "GraspState",
           "SystemCache", "MIC_GAIN_PER_M", "mic_gain", "ContactLoads", "PassiveSound"]
