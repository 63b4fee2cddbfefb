"""Settling a placed scene once per object, not once per placement.

The table top is the plane z = 0 under vertical gravity, and the hand waits at its home pose
far above: the objects' settle is the same motion wherever on the table and however turned
about z the placement put them (a rigid motion of the plane maps one run onto the other).  So
:func:`settle_placed` moves the placed objects by the inverse of the target's planar pose
(``Layout.target_xy_m``, ``target_yaw_rad``) to the canonical placement (target at the
origin, yaw 0), settles that through the scene's ``PhysicsMemo`` (one run per object and
layout of the others, replayed after), and moves the end state back.  The target's canonical
position comes out exact; its orientation, within rounding (1e-16) of the placement's own
at yaw 0 (:func:`canonical_quat`), is set to that, so every draw lands on the same bytes.
Nothing is rounded coarser: a rest pose off by more would put the table contacts a hair off
the bottom face, and their static correction would load nodes off that face (new unit-load
solves, ``sensors.modal.static_correction``).

Always the canonical run, hit or miss: a reset's state does not depend on what ran before.
A placement at the origin, unturned (``randomization=False``), settles as drawn, as before.

The first section after a reset that leaves the hand far from the objects (the release that
opens the hand at home before the first grasp: 30 steps, half a grasp's physics) is the same
motion wherever the placement is, too: :func:`run_after_settle` runs it after the canonical
settle, in the canonical frame, through the memo (once per object), and moves the end state
back, if the scene is still in the state the settle left (:class:`SettledPlacement`).

Used by ``GraspPosition-v0`` and ``ObjectRecognition-v0`` (``AasEnv._settle_canonical``).
Grasps from moved settles put contact points off mesh faces by about 1e-13 m (rounding), a
shape weight far below the unit-load reuse's negligible weight (``static_correction``), so
they load the same nodes as the direct settle's grasps.
The result equals the settle simulated where the objects were placed to the rounding of the
rigid motion (object poses within 1e-9 m and rad, features within 1e-6 after the grasp,
``tests/test_canonical_settle.py``), not bit for bit; :data:`CANONICAL_SETTLE` ``= False`` is
that reference (the direct settle, cached only for a repeated placement).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from aas_gym import grasp
from aas_gym.object_bodies import euler_to_quat, yaw_rest_quat
from aas_gym.physics_memo import EDITED_MODEL_FIELDS, PhysicsMemo
from aas_gym.scenario import Layout, settle
from sensors.objects.catalog import ObjectSpec

__all__ = ["CANONICAL_SETTLE", "SettledPlacement", "canonical_quat", "from_canonical", "run_after_settle", "settle_placed", "to_canonical"]

#: Whether :func:`settle_placed` settles the canonical placement and moves it (True, fast) or
#: settles the objects where they were placed (False: the reference; the first release then
#: runs where placed too).  Read at each call.
CANONICAL_SETTLE = True
# A turned-back orientation this close to the canonical one is it, up to rounding.
_SAME_QUAT = 1e-12
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class SettledPlacement:
    """A placement :func:`settle_placed` settled canonically: the canonical start state
    (``mj_getState`` integration state), the settle's duration [s], the objects' free joints,
    the planar motion back (``layout``), and the state the settle left and the model's edited
    fields then (to tell whether the scene is still there)."""

    start_state: np.ndarray
    settle_s: float
    free_joints: tuple
    layout: Layout
    settled_state: np.ndarray
    model_fields: bytes

    def is_current(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        """Whether ``data`` and ``model`` are as the settle left them (nothing ran since)."""
        state = np.empty(self.settled_state.size)
        mujoco.mj_getState(model, data, state, _STATE)
        return bool(np.array_equal(state, self.settled_state)) and _model_fields(model) == self.model_fields


def _model_fields(model: mujoco.MjModel) -> bytes:
    return b"".join(getattr(model, f).tobytes() for f in EDITED_MODEL_FIELDS)


def canonical_quat(target: ObjectSpec) -> np.ndarray:
    """The orientation (w, x, y, z) ``aas_gym.scenario.place_objects`` gives ``target`` at yaw 0:
    a prism lies along x, a surface object rests upright (``yaw_rest_quat``)."""
    return euler_to_quat(0.0) if target.is_prism else yaw_rest_quat(target.solid(), 0.0)


def settle_placed(memo: PhysicsMemo, model: mujoco.MjModel, data: mujoco.MjData,
                  free_joints: Sequence[tuple[int, int]], layout: Layout, settle_s: float,
                  target_quat: np.ndarray, forward: bool = True) -> SettledPlacement | None:
    """Let the placed scene in ``data`` settle for ``settle_s`` (as ``aas_gym.scenario.settle``),
    through ``memo``; the objects' free joints ``(qpos address, qvel address)``, target first,
    its planar pose from ``layout`` and its :func:`canonical_quat` ``target_quat``.  The module
    docstring says how and how exactly.  Returns the :class:`SettledPlacement` for
    :func:`run_after_settle`, or None with :data:`CANONICAL_SETTLE` False (the reference).
    ``forward=False``: the moved state's derived quantities left stale (a caller whose next
    physics is :func:`run_after_settle`)."""
    if not CANONICAL_SETTLE:                            # the reference
        memo.run(data, ("settle", settle_s), lambda: settle(model, data, settle_s))
        return None
    to_canonical(data, free_joints, layout, target_quat)
    start = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, start, _STATE)
    memo.run(data, ("settle", settle_s), lambda: settle(model, data, settle_s))
    from_canonical(model, data, free_joints, layout, forward=forward)
    settled = np.empty(start.size)
    mujoco.mj_getState(model, data, settled, _STATE)
    return SettledPlacement(start, float(settle_s), tuple(free_joints), layout, settled, _model_fields(model))


def run_after_settle(memo: PhysicsMemo, model: mujoco.MjModel, data: mujoco.MjData, placement: SettledPlacement,
                     args: Hashable, section: Callable[[], object], forward: bool = True):
    """Run ``section`` (deterministic, with the hand far from every object: a rigid motion of
    the table plane maps its run onto itself) from the state ``placement``'s settle left in
    ``data``, as the same run from the canonical settle, moved: through ``memo`` under ``args``
    (a tuple), once per object.  Returns ``section``'s result (kept with the run).  ``forward=False``
    (with ``aas_gym.grasp.LEAN_SCRIPT``) leaves the moved state's derived quantities stale,
    for a caller whose next call steps or recomputes them."""
    mujoco.mj_setState(model, data, placement.start_state, _STATE)
    settle_args = ("settle", placement.settle_s)

    def settle_run():
        memo.run(data, settle_args, lambda: settle(model, data, placement.settle_s))

    if not grasp.LEAN_SCRIPT:                           # the reference: two replays, then a forward
        settle_run()
        result = memo.run(data, args, section)
        from_canonical(model, data, placement.free_joints, placement.layout)
        return result

    def settle_then_section():
        settle_run()
        return section()

    # settle and section kept as one run (keyed by the section's arguments, then the settle's):
    # one replay from the start state
    result = memo.run(data, (*args, settle_args), settle_then_section)
    from_canonical(model, data, placement.free_joints, placement.layout, forward=forward)
    return result


def to_canonical(data: mujoco.MjData, free_joints, layout: Layout, target_quat: np.ndarray) -> None:
    """Move the placed objects to the canonical placement (target at the origin, yaw 0), the
    target's orientation set to ``target_quat`` where it is that up to rounding."""
    x, y = layout.target_xy_m
    yaw = float(layout.target_yaw_rad)
    if x == y == yaw == 0.0:                            # already canonical: as drawn
        return
    _move_free_bodies(data, free_joints, -yaw, (x, y), inverse=True)
    a = free_joints[0][0]
    quat = data.qpos[a + 3:a + 7]
    if min(np.abs(quat - target_quat).max(), np.abs(quat + target_quat).max()) < _SAME_QUAT:
        quat[:] = target_quat                           # (q and -q: one rotation); else a run of its own


def from_canonical(model: mujoco.MjModel, data: mujoco.MjData, free_joints, layout: Layout,
                   forward: bool = True) -> None:
    """Move a canonical end state back to the placement (poses, contacts and forces of the
    moved state recomputed, unless ``forward`` is False); as it is for a placement that was
    canonical."""
    x, y = layout.target_xy_m
    yaw = float(layout.target_yaw_rad)
    if x == y == yaw == 0.0:
        return
    _move_free_bodies(data, free_joints, yaw, (x, y), inverse=False)
    if forward:
        mujoco.mj_forward(model, data)


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
        data.qpos[a:a + 3] = (rot @ (p - shift) if inverse else rot @ p + shift) + 0.0   # no -0.0
        mujoco.mju_mulQuat(quat, turn, data.qpos[a + 3:a + 7].copy())
        data.qpos[a + 3:a + 7] = quat
        data.qvel[v:v + 3] = rot @ data.qvel[v:v + 3]
        data.qacc_warmstart[v:v + 3] = rot @ data.qacc_warmstart[v:v + 3]
