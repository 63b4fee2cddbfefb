"""The replaceable fingertip pads of the aas_gym hand, and the bodies carrying the sensor."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

__all__ = ["FINGERTIP_BODIES", "FingertipSpec", "replace_fingertips"]

#: Fingertip bodies carrying the actuator and microphone sites in the aas_gym hand.
FINGERTIP_BODIES = {"actuator": "left_fingertip", "mic": "right_fingertip"}


@dataclass(frozen=True)
class FingertipSpec:
    """A replaceable fingertip: pad half sizes along the object axis and vertical, contact
    parameters. The pad's contact face stays on the finger's joint origin so the gripper
    tendon length remains the opening between the faces."""

    half_width_m: float = 0.010
    half_height_m: float = 0.008
    friction: tuple[float, float, float] = (1.0, 0.01, 0.0005)
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    rgba: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 1.0)


def replace_fingertips(spec: mujoco.MjSpec, fingertip: FingertipSpec) -> None:
    """Swap both fingertip pads of a hand spec for ``fingertip``."""
    for side in ("left", "right"):
        geom = spec.geom(f"{side}_fingertip")
        if geom is None:
            raise ValueError(f"spec has no geom '{side}_fingertip' (not an aas_gym hand?)")
        thickness = geom.size[1]
        geom.size = [fingertip.half_width_m, thickness, fingertip.half_height_m]
        geom.friction = fingertip.friction
        geom.solref = fingertip.solref
        geom.solimp = fingertip.solimp
        geom.rgba = fingertip.rgba
        geom.material = ""
