"""Scene composition: the Franka hand, a table and objects of the catalog, as one MuJoCo model.

The parts: objects come from :mod:`sensors.objects` (``get_object("aluminium_bar")``, ``"mug"``,
``"part.stl:steel"``) and become bodies in :mod:`aas_gym.object_bodies`; the table, lights and
cameras are :mod:`aas_gym.stage`; the fingertip pads :mod:`aas_gym.fingertips`; the contact
sensors :mod:`aas_gym.contact_sensors`. ``python -m aas_gym.scene`` regenerates ``assets/``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import mujoco

from aas_gym.assets import OBJECTS_DIR, SCENES_DIR
from aas_gym.contact_sensors import add_contact_signature_sensors, add_touch_sensors
from aas_gym.fingertips import FingertipSpec, replace_fingertips
from aas_gym.object_bodies import Placement, add_object
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from aas_gym.robots import DEFAULT_ROBOT, robot_spec
from aas_gym.stage import add_lights_and_cameras, add_table
from sensors.objects.catalog import ObjectSpec, get_object, known_material_names

__all__ = ["build_scene", "build_scene_spec", "default_objects", "unique_body_names", "write_asset_files"]


def default_objects() -> list[ObjectSpec]:
    """The paper's seven objects."""
    return [get_object(n) for n in DEFAULT_OBJECT_NAMES]


def unique_body_names(objects: Sequence[ObjectSpec]) -> list[str]:
    """Body names from labels, suffixed ``_1``, ``_2`` ... for repeated objects."""
    names, seen = [], {}
    for obj in objects:
        k = seen.get(obj.label, 0)
        names.append(obj.label if k == 0 else f"{obj.label}_{k}")
        seen[obj.label] = k + 1
    return names


def build_scene_spec(objects: Iterable[str | ObjectSpec] = ("aluminium_bar",),
                     placements: Sequence[Placement] | None = None,
                     fingertip: FingertipSpec | None = None,
                     table: bool = True, contact_signature: bool = False,
                     robot: str = DEFAULT_ROBOT) -> mujoco.MjSpec:
    """Compose the robot (``aas_gym.robots``: ``"floating_hand"`` or ``"panda"``), table and
    objects into an ``MjSpec`` (compile it with ``.compile()``).

    Without ``placements`` objects lie on the table side by side along y, 80 mm apart.
    ``contact_signature`` adds the sensors a streaming microphone watches every physics step
    (:func:`aas_gym.contact_sensors.add_contact_signature_sensors`); scenes without streaming do not pay for them.
    """
    objs = [get_object(o) for o in objects]
    if placements is None:
        placements = [Placement(0.0, 0.08 * (i - (len(objs) - 1) / 2)) for i in range(len(objs))]
    if len(placements) != len(objs):
        raise ValueError(f"{len(objs)} objects but {len(placements)} placements")
    spec = robot_spec(robot)
    spec.modelname = "aas_scene"
    if fingertip is not None:
        replace_fingertips(spec, fingertip)
    add_lights_and_cameras(spec)
    if table:
        add_table(spec)
    for obj, name, place in zip(objs, unique_body_names(objs), placements):
        add_object(spec, obj, name, place)
        add_touch_sensors(spec, name)
    if contact_signature:
        add_contact_signature_sensors(spec, unique_body_names(objs), table=table)
    return spec


def build_scene(objects: Iterable[str | ObjectSpec] = ("aluminium_bar",), **kwargs) -> mujoco.MjModel:
    """Compiled model of ``build_scene_spec(objects, **kwargs)``."""
    return build_scene_spec(objects, **kwargs).compile()


def write_asset_files(objects_dir: Path = OBJECTS_DIR, scenes_dir: Path = SCENES_DIR) -> list[Path]:
    """Write the generated MJCF files shipped in ``assets/``: a bar and a tube of every
    material (``objects/<label>.xml``: the object alone, with its description), a
    single-object, a multi-object and an all-default-objects scene with the hand.
    Regenerate (``python -m aas_gym.scene``) after changing a scene module."""
    objects_dir.mkdir(parents=True, exist_ok=True)
    scenes_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for obj in [get_object(f"{m}_{shape}") for m in known_material_names() for shape in ("bar", "tube")]:
        spec = mujoco.MjSpec()
        spec.modelname = obj.label
        add_object(spec, obj, obj.label)
        path = objects_dir / f"{obj.label}.xml"
        path.write_text(spec.to_xml())
        written.append(path)
    scenes = {
        "single_object.xml": build_scene_spec(["aluminium_bar"]),
        "multi_object.xml": build_scene_spec(
            ["aluminium_bar", "wood_bar", "aluminium_tube"],
            placements=[Placement(0.0, 0.0), Placement(-0.06, 0.09, None, math.pi / 2 - 0.3),
                        Placement(0.0, -0.06)]),
        "all_objects.xml": build_scene_spec(DEFAULT_OBJECT_NAMES),
    }
    for name, spec in scenes.items():
        path = scenes_dir / name
        path.write_text(spec.to_xml())
        written.append(path)
    return written


if __name__ == "__main__":
    for p in write_asset_files():
        print(p)
