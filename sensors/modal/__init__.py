"""Stage 5, modal models: an object's modes (built once and cached), material views, contacts
and the contact-dependent modal damping."""

from .basis import MaterialView, ModalBasis, with_material
from .contact import Contact
from .damping import OffSurfaceError, modal_damping_matrix
from .model import ModalModel

__all__ = ["MaterialView", "ModalBasis", "with_material", "Contact", "OffSurfaceError", "modal_damping_matrix",
           "ModalModel"]
