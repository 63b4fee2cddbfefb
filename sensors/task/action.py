"""What an action of the grasp task means (``aas_gym/AcousticGrasp-v0`` and
``real.RealGraspEnv``): Box(6) in [-1, 1] = TCP delta x, y, z, yaw, gripper, sense.

Plain floats: the simulated env decodes an action every 0.05 s step next to physics that
costs a few hundred microseconds, and four numbers do not need numpy's call overhead.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

from .grasp import MAX_DELTA, check_action

__all__ = ["GraspAction", "decode_grasp_action", "next_tcp_target"]


class GraspAction(NamedTuple):
    """A decoded grasp-task action.

    Attributes:
        tcp_delta: TCP change x, y, z [m] and yaw [rad] this step: each entry clipped to
            [-1, 1] and scaled by ``MAX_DELTA`` (10 mm, 10 mm, 10 mm, 0.05 rad).
        open_gripper: entry 4 > 0 opens the gripper; otherwise it closes and squeezes with
            the grip force.
        sense: entry 5 > 0: the policy asks to record (cadence ``"action"``) or, streamed, to
            stop with what it heard.
    """

    tcp_delta: tuple[float, float, float, float]
    open_gripper: bool
    sense: bool


def decode_grasp_action(action: Any) -> GraspAction:
    """The :class:`GraspAction` of a Box(6) action; ``ValueError`` for NaN/inf or another
    shape (``max(-1, min(1, nan))`` is 1: a NaN would be a full-speed move)."""
    a = check_action(action, (6,)).tolist()
    dx, dy, dz, dyaw = MAX_DELTA
    clip = _clip_unit
    return GraspAction((clip(a[0]) * dx, clip(a[1]) * dy, clip(a[2]) * dz, clip(a[3]) * dyaw), a[4] > 0, a[5] > 0)


def next_tcp_target(target: Sequence[float], delta: Sequence[float], low: Sequence[float] | None = None,
                    high: Sequence[float] | None = None) -> list[float]:
    """The TCP set-point after a step: ``target + delta``, each entry kept within
    ``[low, high]`` when limits are given (the simulated carriage's range)."""
    out = [t + d for t, d in zip(target, delta)]
    if low is not None and high is not None:
        out = [min(max(v, lo), hi) for v, lo, hi in zip(out, low, high)]
    return out


def _clip_unit(v: float) -> float:
    return max(-1.0, min(1.0, v))
