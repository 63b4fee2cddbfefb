"""``MujocoRobot``: the robot interface of ``real.RealGraspEnv`` implemented on the simulated
scene (the floating Franka hand), so the real env's logic runs end to end without a robot, on
simulated or real sound. It implements ``real.RobotInterface`` structurally and returns
``sensors.task.grasp.RobotState``; ``aas_gym`` does not import ``real``.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from aas_gym.envs.acoustic_grasp import AcousticGraspEnv
from sensors.task.grasp import RobotState


class MujocoRobot:
    """``real.RobotInterface`` on the aas_gym MuJoCo scene (the floating Franka hand).

    ``reset`` places the objects as ``aas_gym/AcousticGrasp-v0`` does; ``move`` advances the
    physics by ``duration_s``. ``sim_sensor`` is the scene's ``aas_gym.SimAcousticSensor``, so
    the same env runs on simulated or real sound.

    Args:
        objects, scene, **env_kwargs: as for ``aas_gym/AcousticGrasp-v0``.
    """

    def __init__(self, objects=("aluminium_bar",), *, scene: str = "single", **env_kwargs) -> None:
        self._env = AcousticGraspEnv(objects, scene=scene, sense_mode="never", **env_kwargs)
        self._env.reset(seed=0)
        self._gripper_force_n = self._env.grip_force_n

    @property
    def model(self):
        """The MuJoCo model of the current scene."""
        return self._env.model

    @property
    def data(self):
        """Its MjData."""
        return self._env.data

    @property
    def sim_sensor(self):
        """The scene's simulated acoustic sensor (``aas_gym.SimAcousticSensor``)."""
        return self._env.sensor

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """New episode: objects placed, hand home and open."""
        self._env.reset(seed=seed, options=options)

    def move(self, tcp, duration_s: float) -> None:
        self._env.hand.command(self.data, tcp=np.asarray(tcp, float))
        mujoco.mj_step(self.model, self.data, nstep=max(1, int(round(duration_s / self.model.opt.timestep))))

    def grasp(self, force_n: float) -> None:
        self._env.hand.set_grip_force(force_n)
        self._env.hand.command(self.data, opening_m=0.0)

    def open(self) -> None:
        self._env.hand.command(self.data, opening_m=0.08)

    def state(self) -> RobotState:
        hand, d, m = self._env.hand, self.data, self.model
        sensor = self._env.sensor
        target = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sensor.bodies[0])
        return RobotState(
            tcp=hand.tcp(d), tcp_velocity=hand.tcp_velocity(d), gripper_opening_m=hand.opening_m(d),
            gripper_speed_m_s=float(np.sum(hand.finger_velocity(d))),
            gripper_force_n=float(-d.actuator_force[hand.gripper_actuator]),
            object_pose=np.concatenate([d.xpos[target], d.xquat[target]]),
            grasped=sensor.grasped_body() == sensor.bodies[0])

    def close(self) -> None:
        self._env.close()
