"""A recording with the contacts it was made in, and the model modes it can show."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..modal.contact import Contact
from ..signals.observation import AcousticObservation


@dataclass
class RecordingSetup:
    """A recording and the contacts it was made with (object frame).

    ``actuator`` and ``mic`` are the two fingertip contacts; ``others`` any further contacts
    (table, other objects). All of them damp the object.
    """

    observation: AcousticObservation
    actuator: Contact
    mic: Contact
    others: tuple[Contact, ...] = ()

    @property
    def contacts(self) -> list[Contact]:
        """Every contact on the object in this recording."""
        return [self.actuator, self.mic, *self.others]

    @classmethod
    def from_observation(cls, observation: AcousticObservation, actuator: Contact | None = None,
                         mic: Contact | None = None, others: Sequence[Contact] | None = None) -> RecordingSetup:
        """Contacts from the arguments, else from ``metadata["contacts"]`` as the simulator
        (and the rig, when it knows the grasp) writes them."""
        meta = (observation.metadata or {}).get("contacts") or {}

        def from_meta(key):
            d = meta.get(key)
            return None if d is None else Contact.from_dict(d)

        actuator = actuator if actuator is not None else from_meta("actuator")
        mic = mic if mic is not None else from_meta("mic")
        if others is None:
            others = [Contact.from_dict(d) for d in meta.get("other", [])]
        if actuator is None or mic is None:
            raise ValueError("the recording has no contacts in its metadata; pass actuator and mic contacts")
        return cls(observation, actuator, mic, tuple(others))


def mode_clusters(frequencies_hz: np.ndarray, rtol: float = 2e-3) -> list[np.ndarray]:
    """Groups of consecutive modes within ``rtol`` of each other in frequency.

    Symmetric objects have near-repeated pairs whose basis is arbitrary; only sums over a
    cluster (trace of a damping block, total observability) are meaningful.
    """
    f = np.asarray(frequencies_hz, float)
    order = np.argsort(f)
    groups: list[list[int]] = []
    for i in order:
        if groups and f[i] <= f[groups[-1][-1]] * (1 + rtol):
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    return [np.asarray(g) for g in groups]


def observability(model, actuator: Contact, mic: Contact) -> np.ndarray:
    """Relative displacement response of each mode from the actuator to the microphone,
    ``|(n_a . U_a)(n_m . U_m)| / w^2`` (the static modal flexibility; 0 = at a node)."""
    U = np.asarray(model.mode_shapes_at(np.array([actuator.position_m, mic.position_m])), float)
    b = np.asarray(actuator.normal) @ U[0]
    o = np.asarray(mic.normal) @ U[1]
    w = np.asarray(model.angular_frequencies_rad_s, float)
    return np.abs(b * o) / w**2
