"""The Franka Panda arm with the aas_gym Franka hand, as an ``MjSpec`` built at run time.

``assets/panda_arm.xml`` holds the arm (links 0-7, Franka's kinematics, joint and torque limits,
identified masses and inertias, see its header); its meshes are the Panda's, loaded from the
installed ``gymnasium-robotics`` package (never copied here). The hand is the one of
``assets/franka_hand.xml`` (the same fingers, tendon, 0-0.08 m opening, force-limited gripper,
sensor housings and the ``aas_actuator`` / ``aas_mic`` sites), taken off its floating carriage,
mounted on the flange and dressed with the Franka hand and finger meshes.
"""

from __future__ import annotations

import copy
import importlib.util
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco

from aas_gym.assets import ASSETS_DIR, HAND_XML
from aas_gym.stage import look_at

__all__ = ["PANDA_ARM_XML", "PANDA_JOINTS", "PandaAssetsError", "franka_mesh_dir", "panda_spec"]

#: The arm's MJCF (meshes relative to :func:`franka_mesh_dir`).
PANDA_ARM_XML = ASSETS_DIR / "panda_arm.xml"
#: The arm's joints, base to flange (each driven by a position servo of the same name).
PANDA_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
# Where gymnasium-robotics keeps the Panda's STL meshes inside its package.
_MESHES_IN_PACKAGE = ("envs", "assets", "kitchen_franka", "franka_assets", "meshes")
# Hand parts made of primitives that the meshes replace in pictures (they still collide).
_HAND_PRIMITIVE_VISUALS = ("hand_flange", "hand_body", "hand_rail", "left_link", "right_link")
# The Franka finger mesh's inner face sits on the finger joint axis; our finger frame is the
# fingertip pad's contact face, 12 mm inside the finger link (pad 3 mm + housing 7 mm + pad gap).
_FINGER_MESH_OFFSET_M = 0.012


class PandaAssetsError(ModuleNotFoundError):
    """The Panda's meshes are not installed (the ``gymnasium-robotics`` package is missing)."""


def franka_mesh_dir() -> Path:
    """The folder of the Panda's meshes (``visual/``, ``collision/``) in the installed
    ``gymnasium-robotics`` package, found without importing it."""
    found = importlib.util.find_spec("gymnasium_robotics")
    if found is None or found.origin is None:
        raise PandaAssetsError("robot='panda' needs the Franka meshes of the gymnasium-robotics package: "
                               "pip install gymnasium-robotics", name="gymnasium_robotics")
    folder = Path(found.origin).parent.joinpath(*_MESHES_IN_PACKAGE)
    if not (folder / "visual" / "link0.stl").is_file():
        raise PandaAssetsError(f"gymnasium-robotics is installed but has no Panda meshes in {folder}",
                               name="gymnasium_robotics")
    return folder


def _merge_hand(arm: ET.Element, hand: ET.Element) -> None:
    """Move the hand body of ``franka_hand.xml`` (and its defaults, materials, contact
    exclusions, tendon, coupling and gripper actuator) onto the arm's flange."""
    body = hand.find(".//body[@name='hand']")
    flange = arm.find(".//site[@name='panda_flange']")
    link7 = arm.find(".//body[@name='panda_link7']")
    body.set("pos", flange.get("pos"))
    body.set("quat", flange.get("quat"))
    # The TCP site in the carriage's convention: z up while the hand points down, x along yaw.
    ET.SubElement(body, "site", name="tcp", pos="0 0 0.1034", quat="0 1 0 0", size="0.004",
                  rgba="1 0 0 0.5", group="3")
    for geom in body.iter("geom"):
        if geom.get("name") in _HAND_PRIMITIVE_VISUALS:
            geom.set("group", "3")
    ET.SubElement(body, "geom", type="mesh", mesh="hand_visual", contype="0", conaffinity="0", group="1",
                  mass="0", material="panda_white")
    for side in ("left", "right"):
        finger = body.find(f"body[@name='{side}_finger']")
        # The finger mesh's pad faces -y: turn it to face the grasp centre (the finger frame's -y).
        ET.SubElement(finger, "geom", type="mesh", mesh="finger_visual", pos=f"0 {_FINGER_MESH_OFFSET_M} 0",
                      contype="0", conaffinity="0", group="1", mass="0", material="hand_dark")
    link7.append(body)
    for section in ("default", "asset", "contact", "tendon", "equality"):
        src = hand.find(section)
        if src is None:
            continue
        dst = arm.find(section)
        if dst is None:
            dst = ET.SubElement(arm, section)
        dst.extend(copy.deepcopy(list(src)))
    gripper = hand.find("actuator/position[@name='gripper']")
    arm.find("actuator").append(copy.deepcopy(gripper))


def panda_spec(base_pos_m=(-0.42, 0.0, 0.0)) -> mujoco.MjSpec:
    """The Panda with the aas_gym hand, its base (link 0) at ``base_pos_m`` on the table."""
    arm = ET.parse(PANDA_ARM_XML).getroot()
    _merge_hand(arm, ET.parse(HAND_XML).getroot())
    arm.find(".//body[@name='panda_link0']").set("pos", " ".join(f"{v:g}" for v in base_pos_m))
    arm.find("compiler").set("meshdir", str(franka_mesh_dir()))
    arm.set("model", "panda_aas")
    spec = mujoco.MjSpec.from_string(ET.tostring(arm, encoding="unicode"))
    # A view of the whole arm and the table in front of it.
    eye = [0.55, -0.95, 0.62]
    spec.worldbody.add_camera(name="panda_view", pos=eye, xyaxes=look_at(eye, [-0.12, 0.0, 0.18]))
    return spec
