"""The modes a recording can show: the model under that recording's contacts, with the same
contact model as the simulation it calibrates.

With ``contact_model="spring_damper"`` (the synthesis' default) every contact is a spring as
well as a damper: the fingertip pads hold the object with the pad springs of the
``sensors.FingertipModel`` (``FingertipModel.pad``), other contacts with their Hertz/Mindlin
stiffness.  The object then rings in its coupled modes (:mod:`sensors.modal.spring_modes`),
whose frequencies no longer scale with sqrt(E) alone (the springs do not follow E) and whose
shapes carry the contact damping.  With ``"damping"`` (the paper's model) the contacts only
damp the free modes, which scale exactly with sqrt(E).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..materials.solids import Material
from ..modal.basis import with_material
from ..modal.contact import Contact
from ..modal.spring_modes import spring_modes
from ..synthesis.fingertip import FingertipModel
from ..synthesis.modal_system import CONTACT_MODELS
from .recordings import RecordingSetup

__all__ = ["DEFAULT_CONTACT_MODEL", "recording_contact_model", "recording_contacts", "recording_pads",
           "recording_modes", "scaled_frequencies_hz"]

#: The contact model a recording without one in its metadata (the rig's) is calibrated with:
#: the synthesis' default.
DEFAULT_CONTACT_MODEL = "spring_damper"


def recording_contact_model(setups: Sequence[RecordingSetup], contact_model: str | None = None) -> str:
    """``contact_model`` if given; else the one the recordings' metadata names (the simulator
    writes it; all recordings must agree); else :data:`DEFAULT_CONTACT_MODEL`."""
    if contact_model is not None:
        if contact_model not in CONTACT_MODELS:
            raise ValueError(f"contact_model must be one of {CONTACT_MODELS}, got {contact_model!r}")
        return contact_model
    named = {(s.observation.metadata or {}).get("contact_model") for s in setups} - {None}
    if len(named) > 1:
        raise ValueError(f"the recordings were made with different contact models {sorted(named)}: "
                         "calibrate them separately or pass contact_model=")
    return named.pop() if named else DEFAULT_CONTACT_MODEL


def recording_pads(setup: RecordingSetup) -> FingertipModel:
    """The fingertip pads a recording was made with: the pad springs of its metadata's
    ``fingertip`` (the simulator writes them) or the default ``FingertipModel``'s (the rig's
    printed pads, as the simulator assumes)."""
    tip = (setup.observation.metadata or {}).get("fingertip") or {}
    changes = {k: float(tip[k]) for k in ("contact_stiffness_n_m", "contact_tangential_stiffness_n_m") if k in tip}
    return FingertipModel().with_(**changes)


def recording_contacts(setup: RecordingSetup) -> list[Contact]:
    """Every contact of a recording as the synthesis sees it with springs: the two fingertip
    contacts with the pads' springs (where they give none), then the others."""
    pads = recording_pads(setup)
    return [pads.pad(setup.actuator), pads.pad(setup.mic), *setup.others]


def recording_modes(model, setups: Sequence[RecordingSetup], material: Material, contact_model: str) -> list:
    """Per recording, the modal basis its sound is made of when the object is of
    ``material``: ``model`` in that material (``"damping"``; one basis for all) or that model
    held by the recording's contact springs (``"spring_damper"``; :func:`spring_modes`)."""
    view = with_material(model, material)
    if contact_model == "damping":
        return [view] * len(setups)
    return [spring_modes(view, recording_contacts(s)) for s in setups]


def scaled_frequencies_hz(modes, scale: float) -> np.ndarray:
    """The frequencies [Hz] of ``modes`` divided by ``scale``: what the E fit (which scales a
    model's frequencies by s = sqrt(E / E_base)) should see as the modes at the base E."""
    return np.asarray(modes.angular_frequencies_rad_s, float) / (2 * np.pi) / scale
