"""MuJoCo contact sensors a scene carries for its objects, computed in C during the step.

* Touch: per object and sensor fingertip, the number of contacts: a grasp test envs can check
  every step without walking the contact list in Python.
* Signature (streaming scenes only): per object and partner body, the contact count, net force
  and force-weighted point, then the count of all the object's contacts; a streaming microphone
  reads them to see in a few microseconds whether the contacts changed (``aas_gym.sim_stream``).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco

from aas_gym.fingertips import FINGERTIP_BODIES

__all__ = ["touch_sensor_name", "add_touch_sensors", "SIGNATURE_WIDTH", "signature_partners",
           "signature_sensor_name", "add_contact_signature_sensors"]


def touch_sensor_name(body: str, side: str) -> str:
    """Name of the contact sensor between ``body`` and the ``side`` ("actuator"/"mic") tip."""
    return f"{body}_touch_{side}"


def add_touch_sensors(spec: mujoco.MjSpec, body: str) -> None:
    """Two MuJoCo contact sensors (number of contacts of ``body`` with each sensor fingertip):
    a grasp test computed in C during the step, so environments can check it every step
    without walking the contact list in Python."""
    for side, tip in FINGERTIP_BODIES.items():
        spec.add_sensor(name=touch_sensor_name(body, side), type=mujoco.mjtSensor.mjSENS_CONTACT,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=tip,
                        reftype=mujoco.mjtObj.mjOBJ_BODY, refname=body,
                        intprm=[1, 0, 1])  # data "found" (contact count), no reduction, 1 slot


#: Data of one signature sensor: contact count, net force (3), force-weighted point (3).
SIGNATURE_WIDTH = 7


def signature_partners(bodies: Sequence[str], body: str, table: bool = True) -> list[str]:
    """The partner bodies whose contacts with ``body`` its signature sensors sum up, in order:
    actuator fingertip, microphone fingertip, the table (if any), the other objects."""
    return ([FINGERTIP_BODIES["actuator"], FINGERTIP_BODIES["mic"]] + (["table"] if table else [])
            + [b for b in bodies if b != body])


def signature_sensor_name(body: str, partner: str) -> str:
    """Name of the signature sensor of ``body``'s contacts with ``partner`` (``"*"``: any)."""
    return f"{body}_signature_{partner}"


def add_contact_signature_sensors(spec: mujoco.MjSpec, bodies: Sequence[str], table: bool = True) -> None:
    """Per object and partner body (:func:`signature_partners`), one MuJoCo contact sensor
    with the contact count, the net contact force and its force-weighted point (world
    frame), then one count of all the object's contacts. Computed in C during the step, they
    let a streaming microphone see in a few microseconds whether the contacts changed since it
    last read the contact list (``aas_gym.sim_stream``)."""
    found, force, pos, netforce = 1, 2, 16, 3
    for body in bodies:
        for partner in signature_partners(bodies, body, table):
            spec.add_sensor(name=signature_sensor_name(body, partner), type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body,
                            reftype=mujoco.mjtObj.mjOBJ_BODY, refname=partner,
                            intprm=[found | force | pos, netforce, 1])
        spec.add_sensor(name=signature_sensor_name(body, "*"), type=mujoco.mjtSensor.mjSENS_CONTACT,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body, intprm=[found, 0, 1])
