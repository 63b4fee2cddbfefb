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
from sensors.modal import TouchingObjects, TouchingPartner
from sensors.modal.spring_modes import flexible_base

__all__ = ["touching_grasp"]


def touching_grasp(sensor, body: str, contacts: Mapping[str, ObjectContacts], variation, others: list):
    """``(model, others)`` for the grasp of ``body``: its (``variation``-scaled) model, or a
    ``TouchingObjects`` of it and the sensed objects it touches, and the contacts that stay
    grounded on it (``others`` from ``ObjectContacts.sensor_grasp`` without the partners')."""
    model = sensor.scaled_model(body, variation)
    if sensor.contact_model != "spring_damper":
        return model, others
    oc = contacts[body]
    objs = oc.select("object")
    partners, names = [], []
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
        partners.append(TouchingPartner(pmodel, R, t, tuple(links), tuple(grounded)))
        names.append(pb)
    if not partners:
        return model, others
    rest = oc.select(~np.isin(oc.kinds, ("actuator", "mic")) & ~np.isin(oc.other_bodies, names))
    return TouchingObjects(model, partners), rest.to_sensor_contacts(sensor.min_force_n, materials)


def _pose_in(model: mujoco.MjModel, data: mujoco.MjData, body: str, other: str):
    """Rotation and translation [m] of ``other``'s frame in ``body``'s frame."""
    a = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, other)
    Ra, Rb = data.xmat[a].reshape(3, 3), data.xmat[b].reshape(3, 3)
    return Ra.T @ Rb, Ra.T @ (data.xpos[b] - data.xpos[a])
