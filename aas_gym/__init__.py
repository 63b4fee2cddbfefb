"""MuJoCo scenes, contact datastream, simulated acoustic sensor and Gymnasium environments.

``import aas_gym`` registers ``aas_gym/AcousticGrasp-v0``, ``aas_gym/GraspPosition-v0``,
``aas_gym/ObjectRecognition-v0``, ``aas_gym/ContactFormation-v0`` and ``aas_gym/FillLevel-v0``
with Gymnasium. Heavy modules load on first use.
Headless Linux: without a display, ``MUJOCO_GL`` defaults to ``egl`` (set it yourself, e.g.
to ``osmesa``, before importing mujoco to choose otherwise).
"""

from __future__ import annotations

import os
import sys


def has_display() -> bool:
    """Whether a window can be opened (macOS/Windows always; Linux needs X11 or Wayland)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


if "MUJOCO_GL" not in os.environ and not has_display():
    os.environ["MUJOCO_GL"] = "egl"

import gymnasium as _gym

_ENVS = {
    "aas_gym/AcousticGrasp-v0": ("aas_gym.envs.acoustic_grasp:AcousticGraspEnv", 200),
    "aas_gym/GraspPosition-v0": ("aas_gym.envs.grasp_position:GraspPositionEnv", 1),
    "aas_gym/ObjectRecognition-v0": ("aas_gym.envs.object_recognition:ObjectRecognitionEnv", 10),
    "aas_gym/ContactFormation-v0": ("aas_gym.envs.contact_formation:ContactFormationEnv", 200),
    "aas_gym/FillLevel-v0": ("aas_gym.envs.fill_level:FillLevelEnv", 1),
}
for _id, (_entry, _steps) in _ENVS.items():
    if _id not in _gym.registry:
        _gym.register(id=_id, entry_point=_entry, max_episode_steps=_steps)

# Public API, imported lazily (PEP 562) so that `import aas_gym` stays cheap.
_LAZY = {
    "SimAcousticSensor": "aas_gym.sim_sensor",
    "NoGraspError": "aas_gym.sim_sensor",
    "SensorSitesError": "aas_gym.sim_sensor",
    "ContactStream": "aas_gym.contacts",
    "ObjectContacts": "aas_gym.contacts",
    "object_contacts": "aas_gym.contacts",
    "ObjectSpec": "sensors.objects.catalog",
    "FingertipSpec": "aas_gym.fingertips",
    "Placement": "aas_gym.object_bodies",
    "build_scene": "aas_gym.scene",
    "build_scene_spec": "aas_gym.scene",
    "get_object": "sensors.objects.catalog",
    "default_objects": "aas_gym.scene",
    "DEFAULT_OBJECT_NAMES": "aas_gym.object_names",
    "Hand": "aas_gym.grasp",
    "planar_grasp": "aas_gym.grasp",
    "release": "aas_gym.grasp",
    "DomainRandomization": "aas_gym.scenario",
    "MujocoRobot": "aas_gym.robot",
    "PandaArm": "aas_gym.panda_control",
    "UnreachableError": "aas_gym.panda_control",
    "SimAcousticStream": "aas_gym.sim_stream",
    "build_object": "aas_gym.object_build",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'aas_gym' has no attribute {name!r}")
