"""Stage 5, modal models: an object's modes (built once and cached), material views, contacts,
the contact-dependent modal damping, and the modes with contact springs (one body held by
grounded springs, or bodies joined by them)."""

from .basis import MaterialView, ModalBasis, with_material
from .contact import Contact
from .damping import OffSurfaceError, modal_damping_matrix
from .coupled_bodies import BodyLink, CoupledBodies, coupled_bodies
from .model import ModalModel
from .spring_modes import SpringModes, spring_modes
from .touching import CoupledGraspModes, TouchingObjects, TouchingPartner, coupled_grasp_modes

__all__ = ["MaterialView", "ModalBasis", "with_material", "Contact", "OffSurfaceError", "modal_damping_matrix",
           "ModalModel", "BodyLink", "CoupledBodies", "coupled_bodies", "SpringModes", "spring_modes",
           "CoupledGraspModes", "TouchingObjects", "TouchingPartner", "coupled_grasp_modes"]
