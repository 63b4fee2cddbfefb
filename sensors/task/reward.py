"""The grasp task's reward (``aas_gym/AcousticGrasp-v0`` and ``real.RealGraspEnv``), term by term.

Each step's terms go to ``info["reward_terms"]`` under the fixed keys of
:data:`GRASP_REWARD_TERMS` (as Gymnasium's MuJoCo envs report theirs); the reward is their sum.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["GRASP_REWARD", "GRASP_REWARD_TERMS", "SUCCESS_REWARD", "grasp_reward_terms", "reward_total",
           "tcp_object_distance_m"]

#: The terms, in the order they are summed: ``reach`` minus the TCP-object distance [m],
#: ``grasp`` while both sensor fingertips press the object, ``success`` when the episode
#: ends with a recording of the grasped object.
GRASP_REWARD_TERMS = ("reach", "grasp", "success")
#: Reward per step while grasped.
GRASP_REWARD = 1.0
#: Reward for the step that succeeds (and ends the episode).
SUCCESS_REWARD = 10.0


def tcp_object_distance_m(tcp: Sequence[float], object_position: Sequence[float]) -> float:
    """Euclidean distance [m] between the TCP (x, y, z first) and the object's centre."""
    dx = float(tcp[0]) - float(object_position[0])
    dy = float(tcp[1]) - float(object_position[1])
    dz = float(tcp[2]) - float(object_position[2])
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def grasp_reward_terms(distance_m: float, grasped: bool, success: bool) -> dict[str, float]:
    """The step's reward terms (keys :data:`GRASP_REWARD_TERMS`, plain floats)."""
    return {"reach": -float(distance_m), "grasp": GRASP_REWARD if grasped else 0.0,
            "success": SUCCESS_REWARD if success else 0.0}


def reward_total(terms: dict[str, float]) -> float:
    """The reward: the sum of the terms in their order."""
    total = 0.0
    for value in terms.values():
        total += value
    return total
