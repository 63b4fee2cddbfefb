"""The contact state of an object during one span of a recording, and when two count as equal.

A :class:`GraspState` says what touches the object (both sensor fingertips, the table, other
objects) while it is constant, e.g. during one physics step; a batch recording
(``sensors.simulate_recording``) is one such span.  Discretising the system of a contact set
costs far more than synthesizing a physics step with it, and MuJoCo's contact forces and
points jitter a little at every step: a :class:`ContactTolerance` says when a contact set
counts as unchanged, so that ``sensors.synthesis.caches.SystemCache`` reuses a system.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Hashable

import numpy as np

from ..modal.contact import Contact

__all__ = ["ContactTolerance", "GraspState"]


@dataclass(frozen=True, eq=False)
class GraspState:
    """What touches the object during one span of a stream (object frame, see ``Contact``).

    Parameters
    ----------
    model : the object's modal model (anything ``ModalSystem.build`` accepts).
    actuator, mic : the actuator and microphone fingertip contacts, or ``None`` where that
        fingertip does not touch the object.
    others : further contacts (table, other objects); they damp the object.
    object_key : which object this is; its modal state is carried under this key.  Default:
        the identity of ``model``.
    loads : the forces every touching body exerts on the object
        (``sensors.synthesis.passive.ContactLoads``), for a stream with passive sound; they do
        not change the system (``others`` damp it), only excite it.
    """

    model: Any
    actuator: Contact | None = None
    mic: Contact | None = None
    others: tuple[Contact, ...] = ()
    object_key: Hashable | None = None
    loads: Any = None

    def __post_init__(self) -> None:
        others = tuple(self.others)
        for c in (self.actuator, self.mic, *others):
            if c is not None and not isinstance(c, Contact):
                raise TypeError(f"contacts must be sensors.Contact, got {type(c).__name__}")
        object.__setattr__(self, "others", others)
        if self.object_key is None:
            object.__setattr__(self, "object_key", ("model", id(self.model)))
        object.__setattr__(self, "_table", None)

    def contact_table(self) -> np.ndarray:
        """Rows [position_m (3), normal (3), force_n, friction, normal and tangential
        stiffness (-1: derived), radius_m, counter material code] of the actuator, mic (NaN
        rows where absent) and other contacts with a positive force; computed once."""
        if self._table is None:
            rows = [_row(self.actuator), _row(self.mic)]
            rows += [_row(c) for c in self.others if c.force_n > 0]
            object.__setattr__(self, "_table", np.array(rows))
        return self._table

    @property
    def closed(self) -> bool:
        """Both fingertips press on the object: the microphone hears it."""
        return (self.actuator is not None and self.mic is not None
                and self.actuator.force_n > 0 and self.mic.force_n > 0)

    def damping_contacts(self) -> list[Contact]:
        """Every contact that damps the object (fingertips that touch, then the others)."""
        return [c for c in (self.actuator, self.mic) if c is not None] + list(self.others)


def _row(c: Contact | None) -> np.ndarray:
    if c is None:
        return np.full(12, np.nan)
    kn, kt = c.normal_stiffness_n_per_m, c.tangential_stiffness_n_per_m
    # the material as a number: equal names give equal codes within a process (tables are not stored)
    code = float(hash(c.counter_material) % 2**31)
    return np.concatenate([c.position_m, c.normal, [c.force_n, c.friction, -1.0 if kn is None else kn,
                                                    -1.0 if kt is None else kt, c.radius_m, code]])


@dataclass(frozen=True)
class ContactTolerance:
    """When two contact sets count as the same system.

    Two contacts match when their positions differ by at most ``position_m``, their normals
    by at most ``normal_rad``, their frictions by at most 1e-9, their forces by at most
    ``force_rtol * f_ref + force_atol_n``, and their given stiffnesses, radii and counter
    materials are the same (to 1e-9 relative).  A derived (Hertz) stiffness grows as
    F^(1/3): within the force tolerance it is within a third of ``force_rtol``.  Sets match when the roles (actuator, mic) match
    and the other contacts match one to one (any order).

    Effect on accuracy: contact damping is linear in each contact's force, so a matched set
    has each contact's damping contribution within ``force_rtol`` (plus ``force_atol_n``
    times its per-newton damping) of the true one; the damping of a mode that is dominated by
    contact damping (contact-damped decay rates) is off by at most that fraction.  Positions
    enter through the mode shapes: the shift is a small fraction of the shortest bending
    wavelength in band (centimetres for the project's objects at 10 kHz), so the drive and
    microphone gains and the contact damping change by O(k dx) ~ 1e-2 or less at the
    defaults.  Normals enter through n n^T: a relative change of O(angle).  The defaults
    (2 %, 0.05 N, 0.2 mm, 0.02 rad) are above the per-step jitter of MuJoCo's forces in a
    steady grasp and well below the changes the issue asks to hear (lifting off a table,
    pressing on it, a fingertip leaving).
    """

    force_rtol: float = 0.02
    force_atol_n: float = 0.05
    position_m: float = 2e-4
    normal_rad: float = 0.02

    def __post_init__(self) -> None:
        for k in ("force_rtol", "force_atol_n", "position_m", "normal_rad"):
            v = getattr(self, k)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"ContactTolerance.{k} must be finite and >= 0, got {v!r}")

    @classmethod
    def exact(cls) -> "ContactTolerance":
        """Reuse a system only for identical contact sets."""
        return cls(0.0, 0.0, 0.0, 0.0)

    # matching ----------------------------------------------------------------------------
    def rows_match(self, a: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Per row of two contact tables (see ``GraspState.contact_table``): do they match?
        Absent contacts (NaN rows) match only absent ones."""
        absent_a, absent_r = np.isnan(a[:, 0]), np.isnan(ref[:, 0])
        with np.errstate(invalid="ignore"):
            ok = np.abs(a[:, :3] - ref[:, :3]).max(axis=1) <= self.position_m
            # |n - n_ref| = 2 sin(angle / 2) for unit vectors
            dn = np.sqrt(((a[:, 3:6] - ref[:, 3:6]) ** 2).sum(axis=1))
            ok &= dn <= 2 * np.sin(self.normal_rad / 2) + 1e-15
            ok &= np.abs(a[:, 6] - ref[:, 6]) <= self.force_rtol * ref[:, 6] + self.force_atol_n
            ok &= np.abs(a[:, 7] - ref[:, 7]) <= 1e-9
            ok &= np.all(np.abs(a[:, 8:] - ref[:, 8:]) <= 1e-9 * np.abs(ref[:, 8:]) + 1e-12, axis=1)
        return np.where(absent_a | absent_r, absent_a & absent_r, ok)

    def tables_match(self, a: np.ndarray, ref: np.ndarray) -> bool:
        """Same roles (actuator, mic rows 0 and 1) and a one-to-one match of the other
        contacts in any order (tried in the given order first; greedy otherwise)."""
        if a.shape != ref.shape:
            return False
        ok = self.rows_match(a, ref)
        if ok.all():
            return True
        if not ok[:2].all():
            return False
        free = list(range(2, len(ref)))
        for i in range(2, len(a)):
            hit = self.rows_match(np.repeat(a[i:i + 1], len(free), axis=0), ref[free])
            if not hit.any():
                return False
            del free[int(np.argmax(hit))]
        return True
