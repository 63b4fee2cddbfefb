"""Settling a placed scene once per object, not once per placement.

The table top is the plane z = 0 under vertical gravity, and the hand waits at its home pose
far above: the objects' settle is the same motion wherever on the table and however turned
about z the placement put them (a rigid motion of the plane maps one run onto the other).  So
:func:`settle_placed` moves the placed objects by the inverse of the target's planar pose
(``Layout.target_xy_m``, ``target_yaw_rad``) to the canonical placement (target at the
origin, yaw 0; its poses rounded to :data:`CANONICAL_DECIMALS` so that every draw of a
placement lands on the same bytes), settles that through the scene's ``PhysicsMemo`` (one
run per object and layout of the others, replayed after), and moves the end state back.

Always the canonical run, hit or miss: a reset's state does not depend on what ran before.
A placement at the origin, unturned (``randomization=False``), settles as drawn, as before.
It equals the settle simulated where the objects were placed to the rounding of the rigid
motion (object poses within 1e-9 m and rad, ``tests/test_canonical_settle.py``), not bit for
bit; :data:`CANONICAL_SETTLE` ``= False`` is that reference (the direct settle, cached only
for a repeated placement).  Randomized placements (the envs' default) then settle once per
target in a single-object scene instead of every reset.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from aas_gym.physics_memo import PhysicsMemo
from aas_gym.scenario import Layout, settle

__all__ = ["CANONICAL_DECIMALS", "CANONICAL_SETTLE", "settle_placed"]

#: Whether :func:`settle_placed` settles the canonical placement and moves it (True, fast) or
#: settles the objects where they were placed (False: the reference).  Read at each call.
CANONICAL_SETTLE = True
#: The canonical poses [m, quaternion] are rounded to this many decimals (1e-12 m): the
#: inverse rigid motion leaves rounding in the last bits that would make each placement a
#: new key of the physics cache.
CANONICAL_DECIMALS = 12


def settle_placed(memo: PhysicsMemo, model: mujoco.MjModel, data: mujoco.MjData,
                  free_joints: Sequence[tuple[int, int]], layout: Layout, settle_s: float) -> None:
    """Let the placed scene in ``data`` settle for ``settle_s`` (as ``aas_gym.scenario.settle``),
    through ``memo``; the objects' free joints ``(qpos address, qvel address)``, the target's
    planar pose from ``layout``.  The module docstring says how and how exactly."""
    x, y = layout.target_xy_m
    yaw = float(layout.target_yaw_rad)
    if not CANONICAL_SETTLE or x == y == yaw == 0.0:     # the reference, or already canonical
        memo.run(data, ("settle", settle_s), lambda: settle(model, data, settle_s))
        return
    _move_free_bodies(data, free_joints, -yaw, (x, y), inverse=True)
    for a, v in free_joints:            # the canonical placement: the same bytes for every draw
        data.qpos[a:a + 7] = np.round(data.qpos[a:a + 7], CANONICAL_DECIMALS) + 0.0
        data.qvel[v:v + 6] = np.round(data.qvel[v:v + 6], CANONICAL_DECIMALS) + 0.0
        data.qacc_warmstart[v:v + 6] = np.round(data.qacc_warmstart[v:v + 6], CANONICAL_DECIMALS) + 0.0
    memo.run(data, ("settle", settle_s), lambda: settle(model, data, settle_s))
    _move_free_bodies(data, free_joints, yaw, (x, y), inverse=False)
    mujoco.mj_forward(model, data)      # poses, contacts and forces of the moved state


def _move_free_bodies(data: mujoco.MjData, free_joints, yaw_rad: float, shift_xy, inverse: bool) -> None:
    """Turn every free body by ``yaw_rad`` about world z and shift it by ``shift_xy``: after the
    turn (``inverse=False``), or ``-shift_xy`` before it (``inverse=True``).  A free joint's
    linear velocity (and warm-start acceleration) is in the world frame and turns; its angular
    part is in the body frame and stays."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    turn = np.array([math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)])
    shift = np.array([shift_xy[0], shift_xy[1], 0.0])
    quat = np.empty(4)
    for a, v in free_joints:
        p = data.qpos[a:a + 3]
        data.qpos[a:a + 3] = rot @ (p - shift) if inverse else rot @ p + shift
        mujoco.mju_mulQuat(quat, turn, data.qpos[a + 3:a + 7].copy())
        data.qpos[a + 3:a + 7] = quat
        data.qvel[v:v + 3] = rot @ data.qvel[v:v + 3]
        data.qacc_warmstart[v:v + 3] = rot @ data.qacc_warmstart[v:v + 3]
