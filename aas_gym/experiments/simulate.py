"""One dataset task: build the scene, grasp, record every excitation, return the rows.

Scripted grasps follow the paper: planar antipodal grasps across the object's main axis,
sampled along the object's extent (its "segmentation": the part of the axis where both
fingertip pads fit on the object), closing on the two parallel faces with the grip force (the
faces' normals are opposite, so the grasp has force closure for any friction > 0).

Multi-object scenes add one or two other objects lying across the target, so that the target
carries their weight at random places: contacts that damp some modes and not others.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import mujoco
import numpy as np

from aas_gym.experiments.config import DatasetConfig, Task
from aas_gym.grasp import planar_grasp
from aas_gym.scene import Placement, build_scene, get_object
from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation

# Keep the fingertip pads (20 mm wide) on the object and away from its ends.
_END_MARGIN_M = 0.02
# Crossing objects rest this far from the target's centre, at least.
_CROSSING_MIN_OFFSET_M = 0.045


@lru_cache(maxsize=16)
def _single_scene(object_name: str) -> mujoco.MjModel:
    return build_scene([object_name])


def _multi_scene(task: Task, config: DatasetConfig, rng: np.random.Generator
                 ) -> tuple[mujoco.MjModel, list[float]]:
    """Target at the origin, 1-2 other objects lying across it on either side of the centre."""
    target = get_object(task.object_name)
    others = [o for o in config.objects if o != task.object_name] or [task.object_name]
    n_others = int(rng.integers(1, 3))
    names = [task.object_name]
    placements = [Placement(0.0, 0.0)]
    offsets = []
    half = target.length_m / 2
    for k in range(n_others):
        other = get_object(others[int(rng.integers(len(others)))])
        side = 1.0 if k == 0 else -1.0
        x = side * rng.uniform(_CROSSING_MIN_OFFSET_M, half - 0.015)
        placements.append(crossing_placement(target, other, x, rng.uniform(-0.3, 0.3)))
        names.append(other.label)
        offsets.append(x)
    return build_scene(names, placements=placements), offsets


def crossing_placement(target, other, x_m: float, skew_rad: float = 0.0) -> Placement:
    """``other`` lying across ``target`` (which rests on the table at the origin), 1 mm above
    contact, ``x_m`` from the target's centre, turned ``skew_rad`` from perpendicular."""
    top_m = 2 * target.half_extents_m[2] + other.half_extents_m[2] + 0.001
    return Placement(x_m, 0.0, z_m=top_m, yaw_rad=math.pi / 2 + skew_rad)


def _grasp_position(task: Task, config: DatasetConfig, rng: np.random.Generator, avoid: list[float]) -> float:
    if task.position_m is not None:
        return float(task.position_m)
    half = get_object(task.object_name).length_m / 2 - _END_MARGIN_M
    if not avoid:
        return float(rng.uniform(-half, half))
    # Between the crossing objects, clear of them by the pad half-width plus a margin.
    lo = min([x for x in avoid if x < 0], default=-half - 0.02) + 0.025
    hi = max([x for x in avoid if x > 0], default=half + 0.02) - 0.025
    return float(rng.uniform(max(lo, -half), min(hi, half)))


def run_task(task: Task, config: DatasetConfig) -> list[dict[str, Any]]:
    """Simulate ``task`` and return one row per excitation."""
    rng = task.rng(config.seed)
    if task.scene == "multi":
        model, avoid = _multi_scene(task, config, rng)
    else:
        model, avoid = _single_scene(task.object_name), []
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    spec = get_object(task.object_name)
    body = spec.label
    position_m = _grasp_position(task, config, rng, avoid)
    # Re-grasping is never exact: the pads land a little off the commanded point along the axis
    # and in height, as on the robot (the label stays the commanded position).
    jitter_m = float(rng.uniform(-config.grasp_jitter_m, config.grasp_jitter_m))
    height_offset_m = float(rng.uniform(-0.002, 0.002))
    grasp = planar_grasp(model, data, body, position_m + jitter_m, grip_force_n=config.grip_force_n,
                         height_offset_m=height_offset_m)
    if not grasp.success:
        raise RuntimeError(f"task {task.task_id}: the scripted grasp did not hold the object ({grasp})")
    sensor = SimAcousticSensor(model, data, noise_std=config.noise_std, rng=rng)
    rows = []
    for name in config.excitations:
        obs = sensor.sense(Excitation.by_name(name), config.duration_s)
        meta = obs.metadata
        row = {
            "task_id": task.task_id, "scene": task.scene, "object": spec.label, "material": spec.material,
            "shape": spec.shape, "excitation": name, "grasp_index": task.grasp_index,
            "position_m": position_m, "grip_force_n": float(grasp.actuator_force_n),
            "n_other_contacts": len(meta.get("other_contacts", [])),
            "other_contact_force_n": float(sum(c["force_n"] for c in meta.get("other_contacts", []))),
            "features": obs.features().astype(np.float32),
        }
        if config.store_waveforms:
            row["waveform"] = obs.waveform
        rows.append(row)
    return rows
