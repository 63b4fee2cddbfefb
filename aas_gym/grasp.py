"""Grasping with the aas_gym Franka hand: Cartesian carriage, force-limited grasps, planar
antipodal grasps along an object's main axis.

The gripper actuator is a position servo on the tendon whose length is the opening between
the fingertip faces; its lower force limit is minus the grip force. Closing on an object, the
servo saturates, so at rest each fingertip presses the object with exactly the grip force
(the finger joints have no friction loss and move horizontally). The tests check the MuJoCo
contact forces against it within 5 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from aas_gym.contacts import ContactStream, row_force_sum_n
from sensors._infra.lru import CACHE_SIZES, LRU

DEFAULT_GRIP_FORCE_N = 40.0  # the paper's grasp force
MAX_GRIP_FORCE_N = 140.0     # Franka hand: 70 N continuous, 140 N peak
MAX_OPENING_M = 0.08
#: Servo target of "close and squeeze": 30 mm below closed, so the servo (kp 5000 N/m)
#: saturates at its force limit on any object down to a 0 mm wall for grip forces up to
#: 140 N (a target of 0 would press a 3 mm wall with only 15 N).
SQUEEZE_TARGET_M = -0.03
#: Lowest height of the pads' centre above the table (pads are 16 mm tall): grasps of flat
#: objects close the pads' lower part on them.
PAD_CLEARANCE_M = 0.009
TCP_JOINTS = ("hand_x", "hand_y", "hand_z", "hand_yaw")
#: Whether the scripted physics (placement, settle, release, grasp) skips the MuJoCo work whose
#: results nothing reads before the next ``mj_step`` recomputes them from the integration state
#: (``mj_forward`` after a teleport, before a settle or after a replayed release; the whole
#: forward where a grasp reads only poses: ``mj_kinematics``; a fingertip force sum computed
#: twice), and replays a reset's settle and first release as one run
#: (``aas_gym.canonical_settle.run_after_settle``).  The integration state, the observations
#: and the infos come out bit for bit the same (``tests/test_lean_script.py``); False runs
#: them as before (the reference).  Read at each call.
LEAN_SCRIPT = True
#: Whether ``planar_grasp``'s rest test after each chunk of steps computes the mic fingertip's
#: force and the hand's motion only when the actuator's force already passes (positive and
#: steady: the test's other terms are pure, so the outcome is the same), the motion from Python
#: floats (the same comparisons as ``np.max(np.abs(v)) > tol``, NaN included).  False: every
#: term every chunk (the reference; ``tests/test_episode_glue.py``).  Read at each call.
LAZY_GRASP_TESTS = True
#: Whether ``body_half_extents`` keeps its result per body and content of the model's geom
#: arrays it reads (one per object, not one per grasp); False recomputes it (the reference).
CACHED_EXTENTS = True
_EXTENTS: LRU = LRU(CACHE_SIZES["sim.body_extents"])
#: Whether ``Hand.teleport`` and ``Hand.command`` clip a Python-float opening in Python
#: (``np.clip`` on a scalar: ~8 us; the same value, -0.0 and NaN included) and ``teleport`` sets
#: the servo targets it has already clipped without ``command`` clipping them again (clipping is
#: idempotent).  False: ``np.clip`` and ``command`` (the reference; ``tests/test_episode_glue.py``).
#: Read at each call.
LEAN_TELEPORT = True


def model_id(model: mujoco.MjModel, kind, name: str, what: str) -> int:
    """The id of ``name`` (a ``mujoco.mjtObj`` ``kind``) in ``model``; ``HandError`` naming
    ``what`` the model should have been if it has none."""
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise HandError(f"model has no {kind.name[6:].lower()} {name!r}: not {what}")
    return i


class HandError(ValueError):
    """The model does not contain the aas_gym hand (or a part of it)."""


@dataclass(frozen=True)
class GraspResult:
    """Outcome of ``planar_grasp``.

    Attributes:
        success: both sensor fingertips touch the object with force.
        actuator_force_n, mic_force_n: summed normal forces of the two fingertips on the object.
        opening_m: final opening between the fingertip faces.
        grasp_position_m: commanded grasp point along the object's main axis (object frame x).
        settle_time_s: simulated time until the grasp came to rest (or the time limit).
        settled: whether the rest criterion was met before the time limit.
    """

    success: bool
    actuator_force_n: float
    mic_force_n: float
    opening_m: float
    grasp_position_m: float
    settle_time_s: float
    settled: bool


class Hand:
    """Indices of the aas_gym hand in a compiled model, and commands for it."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model

        def ident(kind, name):
            return model_id(model, kind, name, "an aas_gym hand scene (build one with aas_gym.scene.build_scene)")

        j = mujoco.mjtObj.mjOBJ_JOINT
        self.tcp_joint_ids = np.array([ident(j, n) for n in TCP_JOINTS])
        self.finger_joint_ids = np.array([ident(j, "finger_left"), ident(j, "finger_right")])
        self.tcp_qpos = model.jnt_qposadr[self.tcp_joint_ids]
        self.tcp_qvel = model.jnt_dofadr[self.tcp_joint_ids]
        self.finger_qpos = model.jnt_qposadr[self.finger_joint_ids]
        self.finger_qvel = model.jnt_dofadr[self.finger_joint_ids]
        a = mujoco.mjtObj.mjOBJ_ACTUATOR
        self.tcp_actuators = np.array([ident(a, n) for n in TCP_JOINTS])
        self.gripper_actuator = ident(a, "gripper")
        self.actuator_site = ident(mujoco.mjtObj.mjOBJ_SITE, "aas_actuator")
        self.mic_site = ident(mujoco.mjtObj.mjOBJ_SITE, "aas_mic")
        self.tcp_site = ident(mujoco.mjtObj.mjOBJ_SITE, "tcp")
        self.tcp_low = model.actuator_ctrlrange[self.tcp_actuators, 0].copy()
        self.tcp_high = model.actuator_ctrlrange[self.tcp_actuators, 1].copy()

    # --- grip force -------------------------------------------------------------------------
    def set_grip_force(self, force_n: float) -> None:
        """Grip force [N] each fingertip presses with when the gripper closes on an object."""
        force_n = float(force_n)
        if not (0.0 < force_n <= MAX_GRIP_FORCE_N):
            raise ValueError(f"grip force must be in (0, {MAX_GRIP_FORCE_N}] N, got {force_n}")
        self.model.actuator_forcerange[self.gripper_actuator, 0] = -force_n

    @property
    def grip_force_n(self) -> float:
        return float(-self.model.actuator_forcerange[self.gripper_actuator, 0])

    # --- state ------------------------------------------------------------------------------
    def tcp(self, data: mujoco.MjData) -> np.ndarray:
        """TCP x, y, z [m] and yaw [rad] (joint values of the carriage)."""
        return data.qpos[self.tcp_qpos].copy()

    def tcp_velocity(self, data: mujoco.MjData) -> np.ndarray:
        return data.qvel[self.tcp_qvel].copy()

    def opening_m(self, data: mujoco.MjData) -> float:
        """Opening between the fingertip faces [m]."""
        return float(np.sum(data.qpos[self.finger_qpos]))

    def finger_velocity(self, data: mujoco.MjData) -> np.ndarray:
        return data.qvel[self.finger_qvel].copy()

    # --- commands ---------------------------------------------------------------------------
    def command(self, data: mujoco.MjData, tcp=None, opening_m: float | None = None) -> None:
        """Set servo targets: ``tcp`` = (x, y, z, yaw), ``opening_m`` (0 = close and squeeze)."""
        if tcp is not None:
            data.ctrl[self.tcp_actuators] = np.clip(np.asarray(tcp, float), self.tcp_low, self.tcp_high)
        if opening_m is not None:
            opening_m = clip_opening_m(opening_m)
            data.ctrl[self.gripper_actuator] = SQUEEZE_TARGET_M if opening_m == 0.0 else opening_m

    def teleport(self, data: mujoco.MjData, tcp, opening_m: float, forward: bool = True) -> None:
        """Put the hand at ``tcp`` with the fingers at ``opening_m``, at rest, targets set there;
        ``forward=False`` leaves the derived quantities (poses, contacts) stale, for a caller
        whose next call is ``mj_step``."""
        tcp = np.clip(np.asarray(tcp, float), self.tcp_low, self.tcp_high)
        opening_m = clip_opening_m(opening_m)
        data.qpos[self.tcp_qpos] = tcp
        data.qvel[self.tcp_qvel] = 0.0
        data.qpos[self.finger_qpos] = opening_m / 2
        data.qvel[self.finger_qvel] = 0.0
        if LEAN_TELEPORT and type(self).command is Hand.command:    # command's clips would change nothing
            data.ctrl[self.tcp_actuators] = tcp
            data.ctrl[self.gripper_actuator] = SQUEEZE_TARGET_M if opening_m == 0.0 else opening_m
        else:
            self.command(data, tcp, opening_m)
        if forward:
            mujoco.mj_forward(self.model, data)


def clip_opening_m(opening_m) -> float:
    """``float(np.clip(opening_m, 0.0, MAX_OPENING_M))``; for a Python float (with
    :data:`LEAN_TELEPORT`) as ``min(max(x, 0.0), MAX_OPENING_M)``: NaN stays NaN and -0.0 stays
    -0.0, as ``np.clip`` keeps them."""
    if LEAN_TELEPORT and type(opening_m) is float:
        return min(max(opening_m, 0.0), MAX_OPENING_M)
    return float(np.clip(opening_m, 0.0, MAX_OPENING_M))


def grasp_pose(model: mujoco.MjModel, data: mujoco.MjData, body: str, position_m: float = 0.0,
               height_offset_m: float = 0.0, grasp=None) -> tuple[np.ndarray, float]:
    """TCP (x, y, z, yaw) of a planar antipodal grasp of ``body`` at ``position_m`` along its
    main axis (body x), fingers closing across the axis in the horizontal plane; and the
    object's extent along the closing direction [m].

    With ``grasp`` (an ``aas_gym.object_grasps.ObjectGrasp`` in the body frame), the fingers
    close along its axis (turned into the horizontal plane) around its centre, and the width
    is the distance between its contacts; the pads' centre stays at least
    :data:`PAD_CLEARANCE_M` above the table."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0:
        raise ValueError(f"model has no body named {body!r}")
    rot = data.xmat[bid].reshape(3, 3)
    if grasp is not None:
        centre = data.xpos[bid] + rot @ grasp.centre_m
        closing = rot @ grasp.axis
        yaw = math.atan2(-closing[0], closing[1])
        yaw = (yaw + math.pi / 2) % math.pi - math.pi / 2  # fingers swapped: the same grasp
        z = max(float(centre[2]), PAD_CLEARANCE_M) + height_offset_m
        return np.array([centre[0], centre[1], z, yaw]), float(grasp.width_m)
    axis = rot[:, 0]
    if math.hypot(axis[0], axis[1]) < 1e-6:
        raise ValueError(f"{body!r} stands upright: no planar grasp across its main axis")
    point = data.xpos[bid] + axis * position_m
    yaw = math.atan2(axis[1], axis[0])
    yaw = (yaw + math.pi / 2) % math.pi - math.pi / 2  # same grasp, fingers swapped: keep |yaw| <= pi/2
    closing = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    # Extent along the closing direction from the geoms' bounding boxes in the body frame.
    half = body_half_extents(model, bid)
    width = 2.0 * float(np.abs(rot.T @ closing) @ half)
    return np.array([point[0], point[1], point[2] + height_offset_m, yaw]), width


def body_half_extents(model: mujoco.MjModel, bid: int) -> np.ndarray:
    """Half sizes of the axis-aligned box around the body's colliding geoms (body frame)."""
    if not CACHED_EXTENTS:
        return _half_extents(model, bid)
    # keyed by everything _half_extents reads (a model edited in place gets its own entry)
    key = (int(bid), b"".join(getattr(model, f).tobytes() for f in _EXTENT_FIELDS))
    return _EXTENTS.get_or_build(key, lambda: _half_extents(model, bid)).copy()


_EXTENT_FIELDS = ("geom_bodyid", "geom_contype", "geom_conaffinity", "geom_aabb", "geom_quat", "geom_pos")


def _half_extents(model: mujoco.MjModel, bid: int) -> np.ndarray:
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    colliding = (model.geom_bodyid == bid) & ((model.geom_contype != 0) | (model.geom_conaffinity != 0))
    for g in np.flatnonzero(colliding):
        # geom_aabb: centre and half sizes in the geom frame; rotate into the body frame.
        c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        q = model.geom_quat[g]
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, q)
        r = r.reshape(3, 3)
        centre = model.geom_pos[g] + r @ c
        ext = np.abs(r) @ h
        lo, hi = np.minimum(lo, centre - ext), np.maximum(hi, centre + ext)
    if not np.all(np.isfinite(lo)):
        raise ValueError(f"body {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, bid)!r} has no colliding geom")
    return np.maximum(np.abs(lo), np.abs(hi))


def planar_grasp(model: mujoco.MjModel, data: mujoco.MjData, body: str, position_m: float = 0.0,
                 grip_force_n: float = DEFAULT_GRIP_FORCE_N, height_offset_m: float = 0.0,
                 lift_m: float = 0.0, clearance_m: float = 0.012, max_time_s: float = 1.0,
                 hand: Hand | None = None, stream: ContactStream | None = None, grasp=None) -> GraspResult:
    """Grasp ``body`` across its main axis at ``position_m`` (object frame x) and let it settle;
    or, with ``grasp`` (an ``aas_gym.object_grasps.ObjectGrasp``, any object), at that grasp,
    whose ``position_m`` along the object's grasp path is reported.

    The hand is placed open (object extent + 2 ``clearance_m``) around the grasp point, closes
    with ``grip_force_n`` and, if ``lift_m`` > 0, lifts; simulation runs until fingers and
    object are at rest and the fingertip forces are steady, at most ``max_time_s``.
    """
    hand = hand or Hand(model)
    hand.set_grip_force(grip_force_n)
    lean = LEAN_SCRIPT
    (mujoco.mj_kinematics if lean else mujoco.mj_forward)(model, data)  # poses of a fresh or edited state
    tcp, width = grasp_pose(model, data, body, position_m, height_offset_m, grasp)
    if grasp is not None:
        position_m = grasp.position_m
    if width + 2 * clearance_m > MAX_OPENING_M:
        if width >= MAX_OPENING_M:
            raise ValueError(f"{body!r} is {width * 1e3:.1f} mm wide across the grasp: more than the "
                             f"hand's {MAX_OPENING_M * 1e3:.0f} mm opening")
        clearance_m = (MAX_OPENING_M - width) / 2
    hand.teleport(data, tcp, width + 2 * clearance_m, forward=not lean)   # the next call steps
    stream = stream or ContactStream(model, [body])
    dt = model.opt.timestep
    chunk = max(1, int(round(0.01 / dt)))
    hand.command(data, opening_m=0.0)
    t, settled, lifted = 0.0, False, lift_m <= 0
    prev = forces = None
    lazy = LAZY_GRASP_TESTS and stream.elliptic          # fingertip_rows: the solver's rows
    while t < max_time_s:
        mujoco.mj_step(model, data, nstep=chunk)
        t += chunk * dt
        if lazy:
            efc, actuator_rows, mic_rows = stream.fingertip_rows(data, body)
            fa = row_force_sum_n(efc, actuator_rows)
            fm = None                                   # summed below when the test needs it
            steady = prev is not None and abs(fa - prev) < 1e-3 * grip_force_n
            prev = fa
            forces = (fa, fm)
            if not (fa > 0 and steady and not _hand_moving(hand, data)):
                continue
            fm = row_force_sum_n(efc, mic_rows)
            forces = (fa, fm)
            if not fm > 0:
                continue
        else:
            fa, fm = forces = stream.fingertip_forces_n(data, body)
            moving = np.max(np.abs(hand.finger_velocity(data))) > 1e-4 or np.max(np.abs(hand.tcp_velocity(data))) > 1e-3
            steady = prev is not None and abs(fa - prev) < 1e-3 * grip_force_n
            prev = fa
            if not (fa > 0 and fm > 0 and not moving and steady):
                continue
        if not lifted:
            hand.command(data, tcp=tcp + np.array([0, 0, lift_m, 0]))
            lifted = True
            prev = None
            continue
        settled = True
        break
    if forces is not None and forces[1] is None:        # the mic's sum of the state the loop left
        forces = (forces[0], row_force_sum_n(efc, mic_rows))
    # the loop's last sums are those of the state it left (no step since)
    fa, fm = forces if lean and forces is not None else stream.fingertip_forces_n(data, body)
    return GraspResult(success=bool(fa > 0 and fm > 0), actuator_force_n=fa, mic_force_n=fm,
                       opening_m=hand.opening_m(data), grasp_position_m=float(position_m),
                       settle_time_s=t, settled=settled)


def _hand_moving(hand, data: mujoco.MjData) -> bool:
    """``planar_grasp``'s motion test on Python floats: ``np.max(np.abs(v)) > tol`` is False
    for a NaN anywhere in ``v`` (``np.max`` propagates it), else whether any ``|v|`` exceeds it."""
    return exceeds(hand.finger_velocity(data).tolist(), 1e-4) or exceeds(hand.tcp_velocity(data).tolist(), 1e-3)


def exceeds(values: list, tol: float) -> bool:
    """``np.max(np.abs(values)) > tol`` for a short list of floats (False with a NaN)."""
    out = False
    for v in values:
        if v != v:
            return False
        if abs(v) > tol:
            out = True
    return out


def release(model: mujoco.MjModel, data: mujoco.MjData, hand: Hand | None = None,
            retreat_m: float = 0.1, duration_s: float = 0.2) -> None:
    """Open the gripper and move the hand up by ``retreat_m``."""
    hand = hand or Hand(model)
    tcp = hand.tcp(data)
    hand.command(data, tcp=tcp + np.array([0, 0, retreat_m, 0]), opening_m=MAX_OPENING_M)
    mujoco.mj_step(model, data, nstep=max(1, int(duration_s / model.opt.timestep)))
