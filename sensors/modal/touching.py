"""A grasped object touching other objects: the modes the microphone hears are the assembly's.

When the grasped object rests on, or presses against, another object (a plinth, a neighbour in
a multi-object scene), both vibrate together: the contact is a spring and a damper between two
free bodies, not a grounded spring.  :class:`TouchingObjects` is the grasped object's model
together with the objects it touches (:class:`TouchingPartner`: their models, poses, the
contacts between them and their own contacts with the ground); with
``contact_model="spring_damper"`` the synthesis builds its system on :class:`CoupledGraspModes`,
the component mode synthesis of all of them (:mod:`sensors.modal.coupled_bodies`):

- the grasped object's contacts (fingertip pads, the table) are grounded springs on it, as in
  :mod:`sensors.modal.spring_modes`;
- each contact with a partner is a link (Hertz/Mindlin stiffness of the two materials), and a
  damper gamma_0 f W on the relative velocity of the two points (the grasped object's contact
  damping gamma_0, as for a grounded contact: an infinitely massive partner gives the old model);
- each partner's contacts with the ground (the table: a massive support) are grounded springs
  and dampers (the partner's gamma) on the partner.

Damping of the coupled modes: the contact dampers exactly (a low-rank factor), the material
(Rayleigh) damping of each body as the diagonal of sum_b V_b^T (alpha_b I + beta_b K_b) V_b
(each coupled mode damped by its energy share in each body; the coupling of modes through the
two bodies' different Rayleigh constants, second order in the share, is left out).

The microphone and the drive are on the grasped object: :class:`CoupledGraspModes` is a
``ModalBasis`` in its frame (mode shapes of the assembly's modes at its points), and carries
the grasped object's coordinates for the state transfer across contact changes
(:func:`sensors.modal.spring_modes.modal_transfer`: the partners' share of the energy is
dropped at a switch, so no switch adds energy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from .contact import Contact
from .contact_stiffness import contact_stiffnesses_n_per_m
from .damping import within_surface_distance_m
from . import coupled_basis
from .coupled_bodies import BodyLink, CoupledBodies
from .spring_modes import contact_springs

__all__ = ["CoupledGraspModes", "TouchingObjects", "TouchingPartner", "coupled_grasp_modes"]

_CACHE: LRU = LRU(CACHE_SIZES["modal.coupled_grasps"])


def _weight_root(normal: np.ndarray, friction: float) -> np.ndarray:
    """W^(1/2) = sqrt(mu) (I - n n^T) + n n^T (the contact damping's weight, see damping.py)."""
    nn = np.outer(normal, normal)
    return np.sqrt(friction) * (np.eye(3) - nn) + nn


@dataclass(frozen=True, eq=False)
class TouchingPartner:
    """An object the grasped object touches.

    ``model``: its modal model (its own frame, a ``ModalModel`` or a ``MaterialView`` of one);
    ``rotation`` (3, 3) and ``translation_m`` (3,): its frame -> the grasped object's frame;
    ``contacts``: the contacts between the two (``sensors.Contact`` in the GRASPED object's
    frame, its outward normal, ``counter_material`` the partner's material); ``grounded``: the
    partner's contacts with the ground or table (its own frame, outward normal); ``name``: the
    partner's body name, as ``sensors.synthesis.passive.ContactLoads.bodies`` names the body
    exerting a load (a load from it acts on both bodies, :mod:`sensors.synthesis.partner_loads`).
    """

    model: Any
    rotation: np.ndarray
    translation_m: np.ndarray
    contacts: tuple = ()
    grounded: tuple = ()
    name: str | None = None

    def __post_init__(self) -> None:
        R = np.array(self.rotation, float).reshape(3, 3)
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
            raise ValueError("TouchingPartner.rotation must be a rotation matrix")
        t = np.array(self.translation_m, float).reshape(3)
        for c in (*self.contacts, *self.grounded):
            if not isinstance(c, Contact):
                raise TypeError(f"contacts must be sensors.Contact, got {type(c).__name__}")
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "translation_m", t)
        object.__setattr__(self, "contacts", tuple(self.contacts))
        object.__setattr__(self, "grounded", tuple(self.grounded))


class TouchingObjects:
    """The grasped object's ``model`` touching ``partners`` (:class:`TouchingPartner`).

    A ``ModalBasis`` of the grasped object alone (its free modes, material, shapes, surface),
    so that everything that checks a grasp against the object works unchanged; the synthesis
    with ``contact_model="spring_damper"`` hears the assembly (:func:`coupled_grasp_modes`).
    ``max_coordinates``: the coupled size bound (``sensors.modal.coupled_bodies``).
    """

    def __init__(self, model, partners, max_coordinates: int | None = None) -> None:
        self.model = model
        self.partners = tuple(partners)
        for p in self.partners:
            if not isinstance(p, TouchingPartner):
                raise TypeError(f"partners must be TouchingPartner, got {type(p).__name__}")
        self.max_coordinates = max_coordinates

    @property
    def grasped_model(self):
        """The grasped object's own model (the modes a state of this group is given in)."""
        return self.model

    @property
    def material(self):
        return self.model.material

    @property
    def angular_frequencies_rad_s(self) -> np.ndarray:
        return self.model.angular_frequencies_rad_s

    @property
    def frequencies_hz(self) -> np.ndarray:
        return np.asarray(self.model.angular_frequencies_rad_s) / (2 * np.pi)

    @property
    def mass_kg(self) -> float:
        return float(self.model.mass_kg)

    @property
    def n_modes(self) -> int:
        return len(self.model.angular_frequencies_rad_s)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        return self.model.mode_shapes_at(points_m)

    def surface_distance_m(self, points_m) -> np.ndarray:
        return self.model.surface_distance_m(points_m)

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        return within_surface_distance_m(self.model, points_m, limit_m)

    def __repr__(self) -> str:
        return f"TouchingObjects({self.model!r} touching {len(self.partners)} object(s))"


class CoupledGraspModes:
    """The modes of a :class:`TouchingObjects` held by the grasped object's ``contacts`` (a
    ``ModalBasis`` in the grasped object's frame; see the module docstring).

    ``assembly``: the :class:`sensors.modal.coupled_bodies.CoupledBodies` (body 0 the grasped
    object, then the partners); ``rayleigh_damping_per_s`` (r,) and ``coupling_damping_factor``
    (k, r) are the damping :func:`sensors.modal.damping.modal_damping_parts` uses in place of
    the material's Rayleigh damping and in addition to the grasped object's contact damping.
    """

    def __init__(self, group: TouchingObjects, contacts) -> None:
        model = group.model
        self.group = group
        self.base = model
        self.material = model.material
        links = [BodyLink(0, None, tuple(p), tuple(n), kn, kt) for p, n, kn, kt in contact_springs(model, contacts)]
        bodies = [(model, np.eye(3), np.zeros(3))]
        dampers = []        # (link, gamma [s/m], force [N], friction)
        for i, partner in enumerate(group.partners, start=1):
            bodies.append((partner.model, partner.rotation, partner.translation_m))
            for c in partner.contacts:
                if c.force_n <= 0:
                    continue
                kn, kt = contact_stiffnesses_n_per_m(c, model.material)
                ln = BodyLink(0, i, tuple(c.position_m), tuple(c.normal), kn, kt)
                links.append(ln)
                dampers.append((ln, float(model.material.gamma), c.force_n, c.friction))
            R, t = partner.rotation, partner.translation_m
            for c in partner.grounded:
                if c.force_n <= 0:
                    continue
                kn, kt = contact_stiffnesses_n_per_m(c, partner.model.material)
                ln = BodyLink(i, None, tuple(R @ c.position_m + t), tuple(R @ c.normal), kn, kt)
                links.append(ln)
                dampers.append((ln, float(partner.model.material.gamma), c.force_n, c.friction))
        self.assembly = A = CoupledBodies(bodies, links, group.max_coordinates)
        self.angular_frequencies_rad_s = A.angular_frequencies_rad_s
        self.frequencies_hz = A.frequencies_hz
        # material damping: each mode's energy share in each body
        d = np.zeros(A.V.shape[1])
        for b, ((m, _, _), part) in enumerate(zip(A.bodies, A.parts)):
            Vb = A.V[A.rows(b)]
            d += float(m.material.alpha) * np.sum(Vb * Vb, axis=0)
            d += float(m.material.beta) * np.einsum("ir,ij,jr->r", Vb, part.free_stiffness, Vb)
        self.rayleigh_damping_per_s = d
        rows = [np.sqrt(g * f) * _weight_root(np.asarray(ln.normal) / np.linalg.norm(ln.normal), mu)
                @ A.link_difference(ln) @ A.V for ln, g, f, mu in dampers]
        self.coupling_damping_factor = np.vstack(rows) if rows else np.zeros((0, A.V.shape[1]))
        # the grasped object's coordinates, as a SpringModes holds them (modal_transfer)
        part0 = A.parts[0]
        self.split, self.attachment, self.geometry = part0.split, part0.attachment, part0.geometry
        self.V = A.V[A.rows(0)]

    def partner_transfer(self, from_modes) -> np.ndarray:
        """The partners' part of ``modal_transfer(from_modes, self)``: for coupled modes of the
        same group the partners' Ritz bases are the same (built from the same links), so their
        coordinates carry over (T_p = V_p,to^T V_p,from); zero otherwise (their energy share is
        dropped, never added)."""
        A = self.assembly
        out = np.zeros((A.V.shape[1], len(from_modes.angular_frequencies_rad_s)))
        if isinstance(from_modes, CoupledGraspModes) and from_modes.group is self.group:
            B = from_modes.assembly
            for b in range(1, len(A.bodies)):
                out += A.V[A.rows(b)].T @ B.V[B.rows(b)]
        return out

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Mass-normalised (over the assembly) coupled mode shapes at points of the grasped
        object (its frame): (n, 3, r)."""
        return self.assembly.mode_shapes_at(0, points_m)

    def surface_distance_m(self, points_m) -> np.ndarray:
        return self.base.surface_distance_m(points_m)

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        return within_surface_distance_m(self.base, points_m, limit_m)

    @property
    def n_modes(self) -> int:
        return int(self.angular_frequencies_rad_s.size)

    @property
    def mass_kg(self) -> float:
        return float(self.base.mass_kg)

    def __repr__(self) -> str:
        return f"CoupledGraspModes({self.group!r}, {self.n_modes} modes)"


def coupled_grasp_modes(group: TouchingObjects, contacts) -> CoupledGraspModes:
    """The coupled modes of ``group`` under the grasped object's ``contacts`` (cached per
    group and contact set)."""
    contacts = list(contacts)
    key = (IdentityKey(group), tuple(contacts), coupled_basis.flags())     # a flag's A/B in one process
    return _CACHE.get_or_build(key, lambda: CoupledGraspModes(group, contacts))
