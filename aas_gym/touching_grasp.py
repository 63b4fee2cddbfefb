"""The grasped object with the sensed objects it touches, as the acoustic sensor hears it.

With contact springs (``contact_model="spring_damper"``) a grasped object that rests on or
presses against another sensed object (a plinth, a neighbour in a multi-object scene) vibrates
together with it: :func:`touching_grasp` turns the MuJoCo contact stream into a
``sensors.modal.TouchingObjects`` (the partner's model and pose in the grasped object's frame,
the contacts between the two, the partner's own contacts with the table), and leaves the other
contacts (table, hand links, objects without a mesh model) as the grasped object's own
grounded springs and dampers.  With ``"damping"`` nothing changes (the paper's model).
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from aas_gym.contacts import ObjectContacts
from sensors import Contact
from sensors import ContactTolerance, GraspState
from sensors._infra.lru import CACHE_SIZES, LRU, IdentityKey
from sensors.modal import TouchingObjects, TouchingPartner
from sensors.modal.damping import MAX_SURFACE_DISTANCE_M
from sensors.modal.spring_modes import flexible_base

__all__ = ["TOUCHING_TOLERANCE", "TouchingMemo", "on_solid", "touching_grasp"]

#: When the contacts with a touching object count as unchanged, so that the coupled grasp
#: (one component mode synthesis, ~0.1-0.5 s) is reused: coarser than the stream's default
#: (a bar set on a plinth rocks and settles for a while, each physics step moving its contact
#: points by a fraction of a millimetre).  1 mm is a few percent of the shortest bending
#: wavelength in band (centimetres at 10 kHz for the project's objects); 10 % force is 3 % of
#: the Hertz stiffness (F^(1/3)), well under 1 % of a coupled frequency.
TOUCHING_TOLERANCE = ContactTolerance(force_rtol=0.1, force_atol_n=0.1, position_m=1e-3, normal_rad=0.05)


class TouchingMemo:
    """The coupled groups a sensor built recently: a new grasp whose touching contacts match one
    of them within ``tolerance`` (:data:`TOUCHING_TOLERANCE`) hears that group, so the
    synthesis caches (keyed by the model's identity) reuse its systems."""

    def __init__(self, tolerance: ContactTolerance = TOUCHING_TOLERANCE) -> None:
        self.tolerance = tolerance
        self._groups = LRU(CACHE_SIZES["sim.touching_groups"])

    def get_or_build(self, key, tables, build):
        """The group built for ``key`` (body, partners, models) whose contact ``tables`` match."""
        bucket = self._groups.get_or_build(key, list)
        for ref_tables, group in bucket:
            if all(self.tolerance.tables_match(a, b) for a, b in zip(tables, ref_tables)):
                return group
        group = build()
        bucket.insert(0, (tables, group))
        del bucket[8:]
        return group


def touching_grasp(sensor, body: str, contacts: Mapping[str, ObjectContacts], variation, others: list | None):
    """``(model, others)`` for the grasp of ``body``: its (``variation``-scaled) model, or a
    ``TouchingObjects`` of it and the sensed objects it touches, and the contacts that stay
    grounded on it (``others`` from ``ObjectContacts.sensor_grasp`` without the partners';
    ``None``: made here, only where no partner takes them, ``ObjectContacts.other_sensor_contacts``)."""
    model = sensor.scaled_model(body, variation)
    if others is None:
        def all_others():
            return contacts[body].other_sensor_contacts(sensor.min_force_n, sensor.object_materials())
    else:
        def all_others():
            return others
    if sensor.contact_model != "spring_damper":
        return model, on_solid(model, all_others())
    oc = contacts[body]
    objs = oc.select("object")
    partners, names, tables, models = [], [], [], []
    materials = sensor.object_materials()
    for pb in dict.fromkeys(objs.other_bodies.tolist()):
        if pb not in sensor.bodies or pb not in contacts:
            continue
        links = objs.select(objs.other_bodies == pb).to_sensor_contacts(sensor.min_force_n, materials)
        if not links:
            continue
        pmodel = sensor.scaled_model(pb, variation)
        if flexible_base(pmodel) is None:      # no mesh: it stays a grounded contact
            continue
        grounded = contacts[pb].select("environment").to_sensor_contacts(sensor.min_force_n)
        R, t = _pose_in(sensor.model, sensor.data, body, pb)
        partners.append(TouchingPartner(pmodel, R, t, tuple(links), tuple(grounded), name=pb))
        names.append(pb)
        models.append(pmodel)
        # the contact tables, with the partner's origin as one more point (its pose)
        pose = Contact(t, R[:, 2], 1.0, 0.0, 0.0, 0.0)
        tables += [GraspState(None, None, None, links).contact_table(),
                   GraspState(None, None, None, (pose, *grounded)).contact_table()]
    if not partners:
        return model, on_solid(model, all_others())
    rest = oc.select(~np.isin(oc.kinds, ("actuator", "mic")) & ~np.isin(oc.other_bodies, names))
    memo = getattr(sensor, "touching", None)
    build = lambda: TouchingObjects(model, partners)  # noqa: E731
    group = build() if memo is None else memo.get_or_build(
        (body, tuple(names), IdentityKey(model), tuple(IdentityKey(m) for m in models)), tables, build)
    return group, on_solid(model, rest.to_sensor_contacts(sensor.min_force_n, materials))


def on_solid(model, contacts) -> list:
    """``contacts`` without those of a collision piece where the solid is absent.

    CoACD's convex pieces stand up to a few millimetres proud of the solid they wrap
    (``benchmarks/collision_fidelity.py``: 1.1 mm on the mug, 3.5 mm on the bottle), so MuJoCo can
    let the hull touch the table where the real solid stands clear of it (the mug's handle):
    such a contact presses nothing real and lies beyond the sensor's surface tolerance
    (``MAX_SURFACE_DISTANCE_M``), where the synthesis refuses it. Every contact within the
    tolerance is kept unchanged (a model that offers distances only: a non-finite one too, which
    the synthesis names); the fingertips are not filtered here (an off-surface pad stays an error)."""
    contacts = list(contacts)
    distance = getattr(model, "surface_distance_m", None)
    if distance is None or not contacts:
        return contacts
    points = np.array([c.position_m for c in contacts], dtype=float)
    within = getattr(model, "within_surface_distance_m", None)
    if within is not None:             # bounds settle most points (sensors.mesh.locator.CENTROID_BOUNDS)
        return [c for c, keep in zip(contacts, within(points, MAX_SURFACE_DISTANCE_M)) if keep]
    d = np.abs(np.asarray(distance(points), dtype=float)).reshape(-1)
    return [c for c, di in zip(contacts, d) if not di > MAX_SURFACE_DISTANCE_M]


def _pose_in(model: mujoco.MjModel, data: mujoco.MjData, body: str, other: str):
    """Rotation and translation [m] of ``other``'s frame in ``body``'s frame."""
    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, other)
    Ra, Rb = data.xmat[a].reshape(3, 3), data.xmat[b].reshape(3, 3)
    return Ra.T @ Rb, Ra.T @ (data.xpos[b] - data.xpos[a])
