"""The grasp-and-sense task contract shared by the simulated envs (``aas_gym``) and the real
env (``real``): one place for the constants, the observation layout and the robot's state,
so a policy sees the same spaces on both sides (the acoustic entries: ``acoustic.py``; the
rules of an episode: ``action.py``, ``reward.py``, ``cadence.py``).

Nothing here knows about MuJoCo or PyAudio; gymnasium is imported only by the helpers that
build spaces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .checks import check_number

#: Where an episode starts: TCP x, y, z [m], yaw [rad].
HOME_TCP = (0.0, 0.0, 0.3, 0.0)
#: Largest TCP change per env step for action 1: 10 mm, 10 mm, 10 mm, 0.05 rad.
MAX_DELTA = (0.01, 0.01, 0.01, 0.05)
#: Grip forces an env accepts [N]: the Franka hand's continuous force is 70 N, its peak 140 N.
MAX_GRIP_FORCE_N = 140.0
#: Fully open gripper: distance between the fingertip faces [m].
MAX_OPENING_M = 0.08

#: Named slices of the proprioceptive state vector, in the order envs assemble it.
#: ``gripper`` is opening [m], opening speed [m/s], motor force [N]; ``object`` is the
#: target's position [m] and quaternion (w, x, y, z).
STATE_LAYOUT: dict[str, slice] = {
    "tcp": slice(0, 4),
    "tcp_velocity": slice(4, 8),
    "gripper": slice(8, 11),
    "object": slice(11, 18),
}
STATE_SIZE = 18


@dataclass(frozen=True)
class RobotState:
    """What the env observes of the robot.

    Attributes:
        tcp: x, y, z [m], yaw [rad] of the tool centre point in the task frame.
        tcp_velocity: their rates [m/s, rad/s].
        gripper_opening_m: distance between the fingertip faces.
        gripper_speed_m_s: its rate.
        gripper_force_n: force the gripper motor applies (the grip force when squeezing).
        object_pose: target object position [m] and quaternion (w, x, y, z) in the task frame,
            from whatever tracks it (motion capture, vision, a fixture); zeros if unknown.
        grasped: both sensor fingertips press the object.
    """

    tcp: np.ndarray
    tcp_velocity: np.ndarray
    gripper_opening_m: float
    gripper_speed_m_s: float
    gripper_force_n: float
    object_pose: np.ndarray
    grasped: bool


def check_grip_force(grip_force_n: float) -> float:
    """``grip_force_n`` as a float; ``TypeError`` for a bool or a string, ``ValueError`` if it
    is outside (0, 140] N."""
    return check_number("grip_force_n", grip_force_n, 0.0, MAX_GRIP_FORCE_N, low_open=True, unit="N")


def check_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as a float64 array of ``shape``; ``ValueError`` for another shape or for
    NaN / infinite entries (``max(-1, min(1, nan))`` is 1: a NaN would be a full-speed move)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numeric with shape {shape}, got {type(action).__name__}") from None
    if a.shape != tuple(shape):
        if a.size == math.prod(shape) and a.squeeze().shape == tuple(s for s in shape if s != 1):
            a = a.reshape(shape)
        else:
            raise ValueError(f"action must have shape {tuple(shape)}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action has NaN or infinite entries: {a.tolist()}")
    return a


def proprio_spaces(with_object: bool = True) -> dict:
    """Observation-space entries of the proprioceptive state (see ``STATE_LAYOUT``)."""
    from gymnasium import spaces

    out = {}
    for name, sl in STATE_LAYOUT.items():
        if name == "object" and not with_object:
            continue
        out[name] = spaces.Box(-np.inf, np.inf, (sl.stop - sl.start,), np.float32)
    return out
