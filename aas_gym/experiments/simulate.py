"""One dataset task: draw the scene, grasp, record every excitation, return the rows.

The scene comes from ``aas_gym.scenario``, the same module the Gymnasium envs draw theirs
from: the target on the table, in multi-object scenes one or two other objects leaning
across its ends (random contacts that damp some modes and not others). Scripted grasps
follow the paper: planar antipodal grasps across the object's main axis, on its
"segmentation" (where both fingertip pads fit, between the crossing objects), closing on the
two parallel faces with the grip force (opposite normals: force closure for any friction > 0).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from aas_gym.experiments.config import DatasetConfig, Task
from aas_gym.grasp import planar_grasp
from aas_gym.robots import DEFAULT_ROBOT, robot_controller
from aas_gym.scenario import (DomainRandomization, choose_objects, default_distractors, grasp_position, target_grasp,
                              place_objects, settle)
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation
from sensors.modal.damping import OffSurfaceError
from sensors.objects.catalog import get_object
from sensors.task.grasp import HOME_TCP, MAX_OPENING_M
from sensors._infra.lru import CACHE_SIZES, LRU

# Datasets vary the grasp (jitter, position, contacts), not the table pose: the target lies at
# the origin, axis along x, as in the paper's recordings.
DATASET_PLACEMENT = DomainRandomization.off()
#: Scene draws tried per task on a surface target before the task fails.
GRASP_ATTEMPTS = 4


#: Compiled scenes by their objects, per process (``SCENES.clear()`` ends their lifetime).
SCENES = LRU(CACHE_SIZES["dataset.scenes"])


def compiled_scene(objects: tuple, robot: str = DEFAULT_ROBOT) -> mujoco.MjModel:
    """The compiled scene of these objects (``ObjectSpec`` or names) held by ``robot``, built
    once per process (:data:`SCENES`); poses are set per task."""
    return SCENES.get_or_build((robot, *objects), lambda: build_scene(list(objects), robot=robot))


def run_task(task: Task, config: DatasetConfig) -> list[dict[str, Any]]:
    """Simulate ``task`` and return one row per excitation."""
    rng = task.rng(config.seed)
    spec = get_object(task.object_name)
    kind = "multi" if task.scene == "multi" else "single"
    objects = choose_objects(rng, spec, default_distractors([get_object(o) for o in config.objects]), kind)
    model = compiled_scene(tuple(objects), config.robot)
    data = mujoco.MjData(model)
    hand = robot_controller(model)
    hand.set_grip_force(config.grip_force_n)
    hand.teleport(data, HOME_TCP, MAX_OPENING_M)
    sensor = SimAcousticSensor(model, data, noise_std=config.noise_std, rng=rng, contact_model=config.contact_model,
                               bandlimited=config.drive == "bandlimited")
    joints = []
    for name in sensor.bodies:  # the scene's object bodies, in the order of ``objects``
        jnt = model.body_jntadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)]
        joints.append((int(model.jnt_qposadr[jnt]), int(model.jnt_dofadr[jnt])))
    body = sensor.bodies[0]
    # A surface target may offer a grasp that a leaning object blocks once the scene has
    # settled: such a draw is placed and grasped again (prisms never needed it: one attempt).
    attempts = 1 if spec.is_prism or task.position_m is not None else GRASP_ATTEMPTS
    for attempt in range(attempts):
        if attempt:
            mujoco.mj_resetData(model, data)
            hand.teleport(data, HOME_TCP, MAX_OPENING_M)
        layout = place_objects(model, data, objects, joints, rng, DATASET_PLACEMENT)
        settle(model, data)
        position_m = float(task.position_m) if task.position_m is not None else grasp_position(rng, spec, layout)
        # Re-grasping is never exact: the pads land a little off the commanded point along the
        # axis and in height, as on the robot (the label stays the commanded position).
        jitter_m = float(rng.uniform(-config.grasp_jitter_m, config.grasp_jitter_m))
        height_offset_m = float(rng.uniform(-0.002, 0.002))
        grasp = planar_grasp(model, data, body, position_m + jitter_m, grip_force_n=config.grip_force_n,
                             height_offset_m=height_offset_m, hand=hand,
                             grasp=target_grasp(spec, position_m, layout, shift_m=jitter_m))
        if not grasp.success:
            continue
        try:
            # A pad can rest on a collision piece where it over-covers the solid (a box's rim
            # corner): the contact is then off the modal surface, a grasp that failed.
            observations = [sensor.sense(Excitation.by_name(name), config.duration_s) for name in config.excitations]
            break
        except OffSurfaceError as exc:
            if attempt == attempts - 1:
                raise OffSurfaceError(f"task {task.task_id}: {exc}") from exc
    if not grasp.success:
        raise RuntimeError(f"task {task.task_id}: the scripted grasp did not hold the object in {attempts} "
                           f"attempts ({grasp})")
    rows = []
    for name, obs in zip(config.excitations, observations):
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
