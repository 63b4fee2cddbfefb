"""The grasp task's contract, shared by the simulated envs and the real rig (no MuJoCo here)."""

from .grasp import AcousticConfig, RobotState, check_action, check_grip_force, proprio_spaces

__all__ = ["AcousticConfig", "RobotState", "check_action", "check_grip_force", "proprio_spaces"]
