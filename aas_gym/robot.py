"""``MujocoRobot``: the robot interface of ``real.RealGraspEnv`` implemented on a MuJoCo scene
(the floating Franka hand), so the real env's logic runs end to end without a robot, on
simulated or real sound. It drives the scene directly (no Gymnasium env inside: the task's
rules are the real env's own), implements ``real.RobotInterface`` structurally and returns
``sensors.task.RobotState``; ``aas_gym`` does not import ``real``.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from aas_gym.grasp import DEFAULT_GRIP_FORCE_N, Hand
from aas_gym.scenario import DomainRandomization, place_objects, settle
from aas_gym.scene import build_scene, get_object
from aas_gym.sim_sensor import SimAcousticSensor
from sensors.task import HOME_TCP, MAX_OPENING_M, RobotState, check_grip_force


class MujocoRobot:
    """``real.RobotInterface`` on an aas_gym MuJoCo scene (the floating Franka hand).

    The scene holds ``objects``, the first the target; ``reset`` places them as the envs do
    (``aas_gym.scenario.place_objects``: the target on the table, any others leaning across
    its ends), lets them settle and puts the hand home, open. ``move`` advances the physics by
    ``duration_s``. ``sim_sensor`` is the scene's ``aas_gym.SimAcousticSensor``, so the same
    real env runs on simulated or real sound.

    Args:
        objects: the scene's objects (names or ``ObjectSpec``), target first.
        randomization: placement randomization (``DomainRandomization``, a dict of its
            knobs, ``None`` for its defaults or ``False`` for none).
        grip_force_n: the grip force each episode starts with, until ``grasp`` sets one [N].
        leak, fingertip: the simulated sensor's (``SimAcousticSensor``).
    """

    def __init__(self, objects=("aluminium_bar",), *, randomization=None,
                 grip_force_n: float = DEFAULT_GRIP_FORCE_N, leak=None, fingertip=None) -> None:
        self.objects = tuple(get_object(o) for o in objects)
        if not self.objects:
            raise ValueError("objects must name at least one object")
        self.randomization = DomainRandomization.coerce(randomization)
        self.model = build_scene(list(self.objects))
        self.data = mujoco.MjData(self.model)
        self.hand = Hand(self.model)
        self.grip_force_n = check_grip_force(grip_force_n)
        self.sim_sensor = SimAcousticSensor(self.model, self.data, on_no_grasp="silence", leak=leak,
                                            fingertip=fingertip)
        bodies = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.sim_sensor.bodies]
        self._target = bodies[0]
        self._free_joints = [(int(self.model.jnt_qposadr[self.model.body_jntadr[b]]),
                              int(self.model.jnt_dofadr[self.model.body_jntadr[b]])) for b in bodies]
        self._rng = np.random.default_rng()
        self.reset(seed=0)

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """New episode: objects placed (drawn from ``seed``, else the robot's own stream),
        hand home and open. ``options`` is accepted for ``real.RobotInterface`` and unused."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        self.hand.set_grip_force(self.grip_force_n)
        self.hand.teleport(d, HOME_TCP, MAX_OPENING_M)
        place_objects(m, d, self.objects, self._free_joints, self._rng, self.randomization)
        settle(m, d)
        self.hand.teleport(d, HOME_TCP, MAX_OPENING_M)

    def move(self, tcp, duration_s: float) -> None:
        self.hand.command(self.data, tcp=np.asarray(tcp, float))
        mujoco.mj_step(self.model, self.data, nstep=max(1, int(round(duration_s / self.model.opt.timestep))))

    def grasp(self, force_n: float) -> None:
        self.hand.set_grip_force(force_n)
        self.hand.command(self.data, opening_m=0.0)

    def open(self) -> None:
        self.hand.command(self.data, opening_m=MAX_OPENING_M)

    def state(self) -> RobotState:
        hand, d = self.hand, self.data
        sensor, target = self.sim_sensor, self._target
        return RobotState(
            tcp=hand.tcp(d), tcp_velocity=hand.tcp_velocity(d), gripper_opening_m=hand.opening_m(d),
            gripper_speed_m_s=float(np.sum(hand.finger_velocity(d))),
            gripper_force_n=float(-d.actuator_force[hand.gripper_actuator]),
            object_pose=np.concatenate([d.xpos[target], d.xquat[target]]),
            grasped=sensor.grasped_body() == sensor.bodies[0])

    def close(self) -> None:
        """Nothing to release (no renderer, no devices); kept for symmetry with real drivers."""
