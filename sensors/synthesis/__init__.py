"""Stage 6, synthesis: contacts and an excitation -> the microphone signal. The exact modal
response, the lumped fingertip drive, batch recordings and streaming across contact changes."""

from .fingertip import FingertipModel
from .modal_system import ModalSystem, modal_response, modal_state_matrix, periodic_response
from .recording import SynthesisCache, simulate_recording
from .stream import AcousticStream, ContactTolerance, GraspState, SystemCache

__all__ = ["FingertipModel", "ModalSystem", "modal_response", "modal_state_matrix", "periodic_response",
           "SynthesisCache", "simulate_recording", "AcousticStream", "ContactTolerance", "GraspState",
           "SystemCache"]
