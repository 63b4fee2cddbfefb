"""Which robot holds the sensor: ``"floating_hand"`` (the Franka hand on a Cartesian carriage,
fast, the default) or ``"panda"`` (the Franka Panda arm with the same hand). One place maps a
name to its MJCF and to the controller the envs and scripted grasps drive."""

from __future__ import annotations

import mujoco

from aas_gym.assets import HAND_XML
from aas_gym.grasp import Hand

__all__ = ["DEFAULT_ROBOT", "ROBOT_NAMES", "check_robot", "robot_controller", "robot_spec"]

ROBOT_NAMES = ("floating_hand", "panda")
DEFAULT_ROBOT = "floating_hand"


def check_robot(robot) -> str:
    """``robot`` if it names a robot, else ``ValueError`` listing the names."""
    if not isinstance(robot, str) or robot not in ROBOT_NAMES:
        raise ValueError(f"robot must be one of {list(ROBOT_NAMES)}, got {robot!r}")
    return robot


def robot_spec(robot: str = DEFAULT_ROBOT) -> mujoco.MjSpec:
    """The robot's MJCF as an ``MjSpec`` (a scene adds table, objects and sensors to it)."""
    if check_robot(robot) == "panda":
        from aas_gym.panda import panda_spec

        return panda_spec()
    return mujoco.MjSpec.from_file(str(HAND_XML))


def robot_controller(model: mujoco.MjModel) -> Hand:
    """The controller of the robot in ``model``: ``aas_gym.panda_control.PandaArm`` where the
    model has the Panda's joints, else the floating hand's ``aas_gym.grasp.Hand``."""
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "panda_joint1") >= 0:
        from aas_gym.panda_control import PandaArm

        return PandaArm(model)
    return Hand(model)
