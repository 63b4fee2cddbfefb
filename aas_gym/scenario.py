"""One place that says what "a scene of this kind with this randomization" is, used by the
Gymnasium envs and by dataset generation alike (so the report's numbers come from the
scenes users are pointed to).

A scenario is drawn from a numpy Generator in a fixed order:
1. objects: the target alone (``"single"``) or with one or two others (``"multi"``), drawn
   from a pool without the target;
2. placement: the target lies on the table, its centre uniformly within +- ``placement_m``
   and its yaw within +- ``yaw_rad``; each other object leans across one end of the target
   (crossing point 72-88 mm from the centre on a 200 mm object, crossing angle 60-120 deg),
   its bottom face on the target's top and its far end on the table: its analytic rest
   pose, so settling only removes small overlaps. These are random contacts that damp some
   modes and not others (the paper's multi-object scenes);
3. the grasp position along the target's main axis, between the crossing objects and clear
   of them and of the ends, then the re-grasp error (jitter along the axis and in height).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from aas_gym import grasp
from aas_gym.object_bodies import euler_to_quat, yaw_rest_quat
from aas_gym.object_grasps import END_MARGIN_M, grasp_set, rest_height_m, rest_rotation
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from sensors._infra.lru import CACHE_SIZES, LRU, IdentityKey
from sensors.objects.catalog import ObjectSpec, get_object
from sensors.task import check_number

SCENE_KINDS = ("single", "multi")
#: A surface target's top edge must reach this far from its centre for a bar to lean on it.
MIN_LEAN_REACH_M = 0.025
# Pads stay this far from a crossing object's contact line.
CROSSING_CLEARANCE_M = 0.025


@dataclass(frozen=True)
class DomainRandomization:
    """Domain-randomization knobs; every draw uses the caller's Generator (an env's
    ``np_random``, seeded by ``reset(seed=...)``; a dataset task's own stream). Set a knob to 0
    to switch it off (``DomainRandomization.off()``).

    Attributes:
        grip_force_rel: grip force drawn uniformly in ``F (1 +- grip_force_rel)``.
        position_noise_m: std of the grasp point's error along the object axis.
        placement_m: object centre drawn uniformly in ``+- placement_m`` on the table (x, y).
        yaw_rad: object yaw drawn uniformly in ``+- yaw_rad``.
        damping_rel: Rayleigh and contact damping (alpha, beta, gamma) scaled by
            ``1 +- damping_rel`` per episode.
        modulus_rel, density_rel: Young's modulus and density scaled by ``1 +- x`` per
            episode (modal frequencies move by sqrt(E / rho)).
        sensor_noise_std: std of additive microphone noise (units of the waveform).
        leak_scale: leak recording scaled uniformly in this range (if a leak is given).
    """

    grip_force_rel: float = 0.05
    position_noise_m: float = 0.0005
    placement_m: float = 0.02
    yaw_rad: float = 0.3
    damping_rel: float = 0.05
    modulus_rel: float = 0.02
    density_rel: float = 0.01
    sensor_noise_std: float = 0.0
    leak_scale: tuple[float, float] = (1.0, 1.0)

    @classmethod
    def off(cls) -> "DomainRandomization":
        """No randomization at all (every reset gives the same scene)."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (1.0, 1.0))

    @classmethod
    def coerce(cls, value) -> "DomainRandomization":
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, dict):
            unknown = set(value) - set(asdict(cls()))
            if unknown:
                raise ValueError(f"unknown randomization knobs {sorted(unknown)}; known: {sorted(asdict(cls()))}")
            return cls(**value)
        if value is False:
            return cls.off()
        raise TypeError(f"randomization must be a DomainRandomization, a dict, None or False, got {value!r}")

    def checked(self) -> "DomainRandomization":
        """``self`` if every knob is a finite number >= 0 (relative ones below 1: a scale of
        ``1 - 1`` would zero a modulus or a grip force) and ``leak_scale`` a pair 0 <= low <= high;
        else ``TypeError``/``ValueError`` naming the knob."""
        for name in ("grip_force_rel", "position_noise_m", "placement_m", "yaw_rad", "damping_rel", "modulus_rel",
                     "density_rel", "sensor_noise_std"):
            value = check_number(f"randomization.{name}", getattr(self, name), 0.0)
            if name.endswith("_rel") and value >= 1.0:
                raise ValueError(f"randomization.{name} must be below 1 (a relative spread), got {value!r}")
        scale = self.leak_scale
        if isinstance(scale, (str, bytes)) or not hasattr(scale, "__len__") or len(scale) != 2:
            raise TypeError(f"randomization.leak_scale must be a pair (low, high), got {scale!r}")
        lo, hi = (check_number("randomization.leak_scale", v, 0.0) for v in scale)
        if lo > hi:
            raise ValueError(f"randomization.leak_scale must have low <= high, got {scale!r}")
        return self


def default_distractors(pool: Sequence[ObjectSpec]) -> list[ObjectSpec]:
    """The objects that may lean on a target: the bars of ``pool`` (a leaning tube or rod
    rolls away before it settles), else its prisms, else the paper's bars."""
    bars = [o for o in pool if o.shape == "bar"]
    return bars or [o for o in pool if o.is_prism] or [get_object(n) for n in DEFAULT_OBJECT_NAMES
                                                         if n.endswith("_bar")]


def choose_objects(rng: np.random.Generator, target: ObjectSpec, pool: Sequence[ObjectSpec], kind: str,
                   max_others: int = 2) -> tuple[ObjectSpec, ...]:
    """Target first, then for ``"multi"`` 1 to ``max_others`` others drawn from ``pool``
    without the target (one per target end)."""
    if kind not in SCENE_KINDS:
        raise ValueError(f"scene must be one of {SCENE_KINDS}, got {kind!r}")
    if kind == "single":
        return (target,)
    others = [o for o in pool if o != target] or list(pool)
    k = 1 if max_others <= 1 else int(rng.integers(1, max_others + 1))
    picks = rng.choice(len(others), size=min(k, len(others)), replace=False)
    return (target,) + tuple(others[int(i)] for i in sorted(picks))


@dataclass(frozen=True)
class Layout:
    """Where a drawn scene put things: the target's centre (x, y) [m] and yaw [rad], and
    where each other object crosses the target, in the target's frame along its axis [m]."""

    target_xy_m: tuple[float, float]
    target_yaw_rad: float
    crossings_m: tuple[float, ...]
    #: Where the others rest on a surface (non-prism) target, as points in its frame [m].
    contacts_m: tuple = ()


def place_objects(model: mujoco.MjModel, data: mujoco.MjData, objects: Sequence[ObjectSpec],
                  free_joints: Sequence[tuple[int, int]], rng: np.random.Generator,
                  randomization: DomainRandomization, *, far_end_only: bool = False) -> Layout:
    """Pose the objects (target first) through their free joints ``(qpos address, qvel
    address)`` as the module docstring says; ``far_end_only`` keeps the others at the
    target's -x end (tasks that grasp on the +x half). Does not step the physics."""
    r = randomization
    target = objects[0]
    xy = rng.uniform(-r.placement_m, r.placement_m, 2) if r.placement_m > 0 else np.zeros(2)
    yaw = float(rng.uniform(-r.yaw_rad, r.yaw_rad)) if r.yaw_rad > 0 else 0.0
    if not target.is_prism:
        return _place_on_surface_target(data, objects, free_joints, rng, xy, yaw)
    _set_free_pose(data, free_joints[0], [xy[0], xy[1], target.half_extents_m[2]], euler_to_quat(yaw))
    axis = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    across = np.array([-axis[1], axis[0], 0.0])
    top = 2 * target.half_extents_m[2]
    ends = [-1.0] if far_end_only else ([-1.0, 1.0] if rng.random() < 0.5 else [1.0, -1.0])
    crossings = []
    for i, obj in enumerate(objects[1:], start=1):
        end = ends[(i - 1) % len(ends)]
        # Crossing point near one end of the target, clear of the grasp region.
        u = end * rng.uniform(0.072, 0.088) * target.length_m / 0.2
        angle = rng.uniform(math.radians(60), math.radians(120)) * (1 if rng.random() < 0.5 else -1)
        direction = math.cos(angle) * axis + math.sin(angle) * across
        _lean(data, free_joints[i], obj, rng, np.array([xy[0], xy[1]]) + axis[:2] * u, direction, top)
        crossings.append(float(u))
    return Layout((float(xy[0]), float(xy[1])), yaw, tuple(crossings))


def _lean(data, joint, obj: ObjectSpec, rng: np.random.Generator, contact_xy, direction, top: float) -> None:
    """Pose a bar leaning on an edge at height ``top`` above ``contact_xy``, running down
    along the horizontal unit ``direction`` to the table: its analytic rest pose."""
    dyaw = math.atan2(direction[1], direction[0])
    # Centre beyond the edge: bottom face on the edge, far end on the table.
    side = rng.uniform(0.03, 0.06) * obj.length_m / 0.2
    half_len, half_h = obj.length_m / 2, obj.half_extents_m[2]
    pitch = math.atan2(top, half_len + side)
    bottom = top * half_len / (half_len + side)
    centre = np.array([contact_xy[0], contact_xy[1], 0.0]) + direction * (side + half_h * math.sin(pitch))
    centre[2] = bottom + half_h * math.cos(pitch) + 0.0003
    _set_free_pose(data, joint, centre, euler_to_quat(dyaw, pitch))


def _place_on_surface_target(data, objects, free_joints, rng, xy, yaw) -> Layout:
    """A surface target resting upright, turned by ``yaw``; each other object leans on its
    top edge from a random side (two from opposite sides). A top narrower than
    :data:`MIN_LEAN_REACH_M` from the centre (a bottle's neck) leaves no room for the fingers
    beside a bar lying on it: there the bar lies on the table, its end against the base."""
    solid = objects[0].solid()
    height = _rest_height_m(solid)
    _set_free_pose(data, free_joints[0], [xy[0], xy[1], height], yaw_rest_quat(solid, yaw))
    if len(objects) == 1:                 # nothing leans on it: its rim is not needed
        rng.uniform(0, 2 * math.pi)       # the side the others would lean from: the stream stays the same
        return Layout((float(xy[0]), float(xy[1])), yaw, (), ())
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ rest_rotation(solid)
    origin = np.array([xy[0], xy[1], height])
    world = np.asarray(solid.surface.vertices) @ rot.T + origin
    top = float(world[:, 2].max())
    rim = world[world[:, 2] >= top - 0.003]
    phi = float(rng.uniform(0, 2 * math.pi))
    contacts = []
    for i, obj in enumerate(objects[1:], start=1):
        angle = phi + math.pi * (i - 1)
        d = np.array([math.cos(angle), math.sin(angle), 0.0])
        reach = float(((rim[:, :2] - origin[:2]) @ d[:2]).max())
        if reach >= MIN_LEAN_REACH_M:
            edge = origin[:2] + reach * d[:2]
            _lean(data, free_joints[i], obj, rng, edge, d, top)
            contacts.append(rot.T @ (np.array([edge[0], edge[1], top]) - origin))
            continue
        base = world[world[:, 2] <= world[:, 2].min() + obj.half_extents_m[2] * 2]
        edge = origin[:2] + float(((base[:, :2] - origin[:2]) @ d[:2]).max()) * d[:2]
        centre = np.array([edge[0], edge[1], obj.half_extents_m[2]]) + d * (obj.length_m / 2 + 0.0005)
        _set_free_pose(data, free_joints[i], centre, euler_to_quat(float(angle)))
        contacts.append(rot.T @ (np.array([edge[0], edge[1], obj.half_extents_m[2]]) - origin))
    return Layout((float(xy[0]), float(xy[1])), yaw, (), tuple(contacts))


_REST_HEIGHTS: LRU = LRU(CACHE_SIZES["objects.rest_heights"])


def _rest_height_m(solid) -> float:
    """``rest_height_m(solid)``, computed once per solid (a pass over its surface vertices)."""
    return _REST_HEIGHTS.get_or_build(IdentityKey(solid), lambda: rest_height_m(solid))


def place_beside(data: mujoco.MjData, objects: Sequence[ObjectSpec], free_joints: Sequence[tuple[int, int]],
                 rng: np.random.Generator, randomization: DomainRandomization, spacing_m: float = 0.08) -> Layout:
    """The target and one other object lying flat and parallel on the table, ``spacing_m``
    apart along y (target at -y): the other is a plinth the hand can set the target on
    (``aas_gym/ContactFormation-v0``). Centres move by up to ``placement_m`` along x and 5 mm
    along y, yaws by up to ``yaw_rad`` / 3 (kept small: the hand carries the target across
    without turning). Does not step the physics."""
    if len(objects) != 2:
        raise ValueError(f"place_beside places a target and one other object, got {len(objects)} objects")
    r = randomization
    yaws = []
    for i, (obj, joint) in enumerate(zip(objects, free_joints)):
        x = float(rng.uniform(-r.placement_m, r.placement_m)) if r.placement_m > 0 else 0.0
        y = (i - 0.5) * spacing_m + (float(rng.uniform(-0.005, 0.005)) if r.placement_m > 0 else 0.0)
        yaw = float(rng.uniform(-r.yaw_rad, r.yaw_rad)) / 3 if r.yaw_rad > 0 else 0.0
        _set_free_pose(data, joint, [x, y, obj.half_extents_m[2]], euler_to_quat(yaw))
        yaws.append(yaw)
        if i == 0:
            target_xy = (x, y)
    return Layout(target_xy, yaws[0], ())


#: Whether ``settle(..., until_rest=True)`` stops once the free bodies are at rest (True) or
#: always runs the whole duration (False: the reference, and the default).  Not exact: the
#: poses stay within 1e-9 m of the whole settle's, but FillLevel-v0's features move by up to
#: 5e-5 relative (7.5e-4 on a seed where the whole settle, 10 ms longer, moves them by 42 %),
#: so it stays off until the project decides what a FillLevel-v0 episode simulates
#: (``tests/test_settle_until_rest.py``; 2.6x fewer MuJoCo steps per episode).  Read at each call.
SETTLE_UNTIL_REST = False
#: Free bodies slower than this [m/s and rad/s] are at rest: had they kept that speed for a
#: whole 0.4 s settle they would have moved by at most 0.4 nm.  A resting container reaches it
#: after 0.08-0.12 s and then only trembles (1e-11-1e-9 m/s, a limit cycle of the soft contacts).
REST_SPEED = 1e-9
#: The least settle [s] before the rest test (the first steps start from zero velocity).
MIN_SETTLE_S = 0.05
_REST_CHECK_STEPS = 5


def settle_steps(model: mujoco.MjModel, duration_s: float) -> int:
    """The steps of a whole settle of ``duration_s``."""
    return max(1, int(duration_s / model.opt.timestep))


@dataclass(frozen=True)
class SceneState:
    """The integration state of a scene at one moment, to tell whether anything ran since."""

    state: bytes

    @classmethod
    def of(cls, model: mujoco.MjModel, data: mujoco.MjData) -> "SceneState":
        kind = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(model, kind))
        mujoco.mj_getState(model, data, state, kind)
        return cls(state.tobytes())

    def is_current(self, model: mujoco.MjModel, data: mujoco.MjData) -> bool:
        return SceneState.of(model, data).state == self.state


def settle(model: mujoco.MjModel, data: mujoco.MjData, duration_s: float = 0.4, until_rest: bool = False) -> int:
    """Let the placed scene come to rest: ``duration_s`` of physics or, with ``until_rest`` (and
    :data:`SETTLE_UNTIL_REST`), until no free body moves faster than :data:`REST_SPEED` (tested
    every few steps after :data:`MIN_SETTLE_S`), at most ``duration_s``.  Returns the steps run.

    At rest the steps left only tremble: the state after them differs from the early one by
    about 1e-11 m in poses, as much as settling 10 ms longer changes the full settle
    (``tests/test_settle_until_rest.py``)."""
    if not grasp.LEAN_SCRIPT:            # the reference; a step recomputes what this forward derives
        mujoco.mj_forward(model, data)
    n = settle_steps(model, duration_s)
    if not (until_rest and SETTLE_UNTIL_REST):
        mujoco.mj_step(model, data, nstep=n)
        return n
    free = [int(model.jnt_dofadr[j]) for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    dofs = np.concatenate([np.arange(a, a + 6) for a in free]) if free else np.zeros(0, int)
    least = int(math.ceil(MIN_SETTLE_S / model.opt.timestep))
    done = 0
    while done < n:
        k = min(_REST_CHECK_STEPS, n - done)
        mujoco.mj_step(model, data, nstep=k)
        done += k
        if done >= least and np.abs(data.qvel[dofs]).max(initial=0.0) < REST_SPEED:
            break
    return done


def grasp_position(rng: np.random.Generator, target: ObjectSpec, layout: Layout) -> float:
    """A grasp position along the target's axis [m]: uniform over the part where both pads
    fit, between the crossing objects and clear of them. For a surface target, the position
    along its grasp path of the grasp nearest a uniform draw over the path, among the grasps
    clear of the others' contacts (``target_grasp`` gives that grasp)."""
    if not target.is_prism:
        lo, hi = grasp_set(target).span_m
        return target_grasp(target, float(rng.uniform(lo, hi)), layout).position_m
    half = target.length_m / 2 - END_MARGIN_M
    lo = max([x for x in layout.crossings_m if x < 0], default=-half - 1.0) + CROSSING_CLEARANCE_M
    hi = min([x for x in layout.crossings_m if x > 0], default=half + 1.0) - CROSSING_CLEARANCE_M
    return float(rng.uniform(max(lo, -half), min(hi, half)))


def target_grasp(target: ObjectSpec, position_m: float, layout: Layout | None = None, shift_m: float = 0.0,
                 min_width_m: float = 0.0):
    """The grasp of a surface target nearest ``position_m`` along its grasp path (clear of
    ``layout``'s contacts by :data:`CROSSING_CLEARANCE_M`, at least ``min_width_m`` wide), its
    centre moved ``shift_m`` along the path (the re-grasp error); None for a prism (grasped
    across its axis at the position)."""
    if target.is_prism:
        return None
    grasps = grasp_set(target)
    avoid = layout.contacts_m if layout is not None else ()
    g = grasps.nearest(position_m, avoid, CROSSING_CLEARANCE_M, min_width_m=min_width_m)
    if shift_m:
        g = type(g)(g.centre_m + shift_m * grasps.path_direction, g.axis, g.width_m, g.position_m + shift_m)
    return g


def position_along_path(target: ObjectSpec, point_m) -> float:
    """Position [m] of an object-frame point along a surface target's grasp path."""
    grasps = grasp_set(target)
    return float((np.asarray(point_m, float) - grasps.path_start_m) @ grasps.path_direction)


def _set_free_pose(data: mujoco.MjData, joint: tuple[int, int], pos, quat) -> None:
    a, v = joint
    data.qpos[a:a + 3] = pos
    data.qpos[a + 3:a + 7] = quat
    data.qvel[v:v + 6] = 0.0
