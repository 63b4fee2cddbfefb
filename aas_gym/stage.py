"""What surrounds the hand in every scene: the table (top at z = 0), the floor, lights and cameras."""

from __future__ import annotations

import mujoco
import numpy as np

from aas_gym.object_bodies import OBJECT_SOLIMP, OBJECT_SOLREF

__all__ = ["TABLE_HALF_SIZE_M", "add_table", "add_lights_and_cameras", "look_at"]

TABLE_HALF_SIZE_M = (0.45, 0.45, 0.02)


def add_table(spec: mujoco.MjSpec) -> None:
    """A wooden table whose top surface is the world plane z = 0, with a floor below."""
    hx, hy, hz = TABLE_HALF_SIZE_M
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.1],
                            pos=[0, 0, -0.75], rgba=[0.35, 0.37, 0.4, 1], contype=0, conaffinity=0)
    table = spec.worldbody.add_body(name="table", pos=[0, 0, -hz])
    table.add_geom(name="table_top", type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, hz],
                   rgba=[0.55, 0.42, 0.3, 1], friction=[0.5, 0.005, 0.0001],
                   solref=OBJECT_SOLREF, solimp=OBJECT_SOLIMP)
    leg_h = (0.75 - 2 * hz) / 2
    for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        table.add_geom(name=f"table_leg{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, leg_h],
                       pos=[sx * (hx - 0.03), sy * (hy - 0.03), -hz - leg_h], rgba=[0.45, 0.33, 0.22, 1],
                       contype=0, conaffinity=0, group=1)


def add_lights_and_cameras(spec: mujoco.MjSpec) -> None:
    """Light, cameras and a sky colour for pictures."""
    spec.visual.global_.offwidth = 640
    spec.visual.global_.offheight = 480
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.55, 0.65, 0.8], rgb2=[0.1, 0.1, 0.15], width=256, height=256)
    spec.worldbody.add_light(name="key", pos=[0.3, -0.4, 1.2], dir=[-0.25, 0.35, -1], diffuse=[0.8, 0.8, 0.8])
    spec.worldbody.add_light(name="fill", pos=[-0.5, 0.5, 1.0], dir=[0.4, -0.4, -1], diffuse=[0.3, 0.3, 0.3])
    spec.worldbody.add_camera(name="overview", pos=[0.5, -0.5, 0.5], xyaxes=look_at([0.5, -0.5, 0.5], [0, 0, 0.1]))
    # The hand at its home pose (TCP 0.3 m above the table) and the table below it: a reach.
    spec.worldbody.add_camera(name="workspace", pos=[0.55, -0.55, 0.3],
                              xyaxes=look_at([0.55, -0.55, 0.3], [0, 0, 0.19]))
    # Low side view: sees the fingertips and the object under the hand body.
    spec.worldbody.add_camera(name="closeup", pos=[0.2, -0.24, 0.08],
                              xyaxes=look_at([0.2, -0.24, 0.08], [0, 0, 0.035]))


def look_at(pos, target) -> list[float]:
    """MuJoCo camera ``xyaxes`` looking from ``pos`` at ``target`` with world z up."""
    back = np.asarray(pos, float) - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return [*right, *up]
