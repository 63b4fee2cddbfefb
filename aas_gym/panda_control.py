"""``PandaArm``: Cartesian (operational-space) control of the Panda with the aas_gym hand.

The arm's joints are driven by stiff position servos (computed in C every physics step, gravity
compensated). A Cartesian TCP command (x, y, z [m], yaw [rad], hand pointing down: the floating
hand's action) becomes joint targets through damped-least-squares inverse kinematics, solved
once per command within the joint limits and checked for self-collision. A TCP the arm cannot
reach that way raises :class:`UnreachableError`: nothing is clipped silently. Joint-space
control is :meth:`PandaArm.command_joints`.

``PandaArm`` has the interface of :class:`aas_gym.grasp.Hand` (``tcp``, ``tcp_velocity``,
``command``, ``teleport``, grip force, fingers), so the scripted grasps and the envs drive
either robot.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from aas_gym.grasp import MAX_OPENING_M, Hand, model_id
from aas_gym.panda import PANDA_JOINTS

__all__ = ["IK_POSITION_TOL_M", "IK_YAW_TOL_RAD", "PANDA_TCP_HIGH", "PANDA_TCP_LOW", "PANDA_REST_Q", "PandaArm",
           "UnreachableError"]

#: The Cartesian box of TCP commands (x, y, z [m], yaw [rad]) with the base at (-0.42, 0, 0):
#: every point of it is reachable with the hand pointing down (tests/test_panda.py checks the
#: corners), so a command inside never fails for reach.
PANDA_TCP_LOW = (-0.12, -0.3, -0.05, -math.pi / 2)
PANDA_TCP_HIGH = (0.2, 0.3, 0.5, math.pi / 2)
#: A posture above the table, hand down, elbow up: the IK's first seed and null-space target.
PANDA_REST_Q = (0.0, -0.2, 0.0, -2.2, 0.0, 2.0, math.pi / 4)
IK_POSITION_TOL_M = 5e-4
IK_YAW_TOL_RAD = 5e-3
_IK_ITERATIONS = 200
_IK_DAMPING = 1e-2
_IK_NULLSPACE_GAIN = 0.05
_LIMIT_MARGIN_RAD = 1e-3


class UnreachableError(ValueError):
    """The arm cannot put the TCP at the commanded pose within its joint limits without
    touching itself."""


def _yaw_quat(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a turn by ``yaw`` about world z."""
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


class PandaArm(Hand):
    """Indices of the Panda and its hand in a compiled model, and Cartesian / joint commands.

    ``tcp_low`` / ``tcp_high`` bound Cartesian commands (:data:`PANDA_TCP_LOW`, ``_HIGH``);
    ``target_tcp`` is the last commanded TCP, ``target_q`` its joint solution."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model

        def ident(kind, name):
            return model_id(model, kind, name, "an aas_gym Panda scene "
                            "(build one with aas_gym.scene.build_scene(..., robot='panda'))")

        j, a = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR
        self.arm_joint_ids = np.array([ident(j, n) for n in PANDA_JOINTS])
        self.arm_qpos = model.jnt_qposadr[self.arm_joint_ids]
        self.arm_qvel = model.jnt_dofadr[self.arm_joint_ids]
        self.arm_actuators = np.array([ident(a, n) for n in PANDA_JOINTS])
        self.q_low = model.jnt_range[self.arm_joint_ids, 0] + _LIMIT_MARGIN_RAD
        self.q_high = model.jnt_range[self.arm_joint_ids, 1] - _LIMIT_MARGIN_RAD
        self.finger_joint_ids = np.array([ident(j, "finger_left"), ident(j, "finger_right")])
        self.finger_qpos = model.jnt_qposadr[self.finger_joint_ids]
        self.finger_qvel = model.jnt_dofadr[self.finger_joint_ids]
        self.gripper_actuator = ident(a, "gripper")
        self.actuator_site = ident(mujoco.mjtObj.mjOBJ_SITE, "aas_actuator")
        self.mic_site = ident(mujoco.mjtObj.mjOBJ_SITE, "aas_mic")
        self.tcp_site = ident(mujoco.mjtObj.mjOBJ_SITE, "tcp")
        self.tcp_low, self.tcp_high = np.array(PANDA_TCP_LOW), np.array(PANDA_TCP_HIGH)
        base = ident(mujoco.mjtObj.mjOBJ_BODY, "panda_link0")
        self._robot_bodies = np.flatnonzero(np.asarray(model.body_rootid) == base)
        # Per geom: on the robot, on an arm link. A contact of an arm link with any robot part is a
        # self-collision; contacts inside the hand (fingers closed on nothing) are the gripper's.
        arm_bodies = [ident(mujoco.mjtObj.mjOBJ_BODY, f"panda_link{i}") for i in range(8)]
        self._geom_on_robot = np.isin(model.geom_bodyid, self._robot_bodies)
        self._geom_on_arm = np.isin(model.geom_bodyid, arm_bodies)
        self._ik = mujoco.MjData(model)
        self._jac = np.zeros((6, model.nv))
        self.target_q = np.array(PANDA_REST_Q)
        self.target_tcp = None

    # --- state ------------------------------------------------------------------------------
    def tcp(self, data: mujoco.MjData) -> np.ndarray:
        """TCP x, y, z [m] and yaw [rad] (the heading of the tcp site's x axis)."""
        pos, rot = data.site_xpos[self.tcp_site], data.site_xmat[self.tcp_site]
        return np.array([pos[0], pos[1], pos[2], math.atan2(rot[3], rot[0])])

    def tcp_velocity(self, data: mujoco.MjData) -> np.ndarray:
        """TCP linear velocity [m/s] and yaw rate [rad/s] (world frame)."""
        v = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_SITE, self.tcp_site, v, 0)
        return np.array([v[3], v[4], v[5], v[2]])

    def joint_positions(self, data: mujoco.MjData) -> np.ndarray:
        """The seven arm joint angles [rad]."""
        return data.qpos[self.arm_qpos].copy()

    # --- commands ---------------------------------------------------------------------------
    def command(self, data: mujoco.MjData, tcp=None, opening_m: float | None = None) -> None:
        """Set servo targets: ``tcp`` = (x, y, z, yaw) through inverse kinematics (outside
        ``tcp_low``..``tcp_high`` or unreachable: :class:`UnreachableError`), ``opening_m``
        (0 = close and squeeze)."""
        if tcp is not None:
            q = self.solve_ik(data, tcp, seed=self.target_q)
            self.command_joints(data, q)
            self.target_tcp = np.asarray(tcp, float).copy()
        if opening_m is not None:
            super().command(data, opening_m=opening_m)

    def command_joints(self, data: mujoco.MjData, q) -> None:
        """Joint-space control: servo targets for the seven joints [rad], within their limits
        (outside: ``ValueError``)."""
        q = np.asarray(q, float)
        if q.shape != (7,) or not np.all(np.isfinite(q)):
            raise ValueError(f"joint targets must be 7 finite angles, got {q!r}")
        if np.any(q < self.q_low - 2 * _LIMIT_MARGIN_RAD) or np.any(q > self.q_high + 2 * _LIMIT_MARGIN_RAD):
            raise ValueError(f"joint targets {np.round(q, 4).tolist()} outside the Panda's limits "
                             f"{np.round(self.q_low, 4).tolist()} .. {np.round(self.q_high, 4).tolist()}")
        data.ctrl[self.arm_actuators] = q
        self.target_q = q.copy()

    def teleport(self, data: mujoco.MjData, tcp, opening_m: float, forward: bool = True) -> None:
        """Put the arm at rest with the TCP at ``tcp`` (inverse kinematics, from the rest
        posture) and the fingers at ``opening_m``; targets set there; ``forward=False``: as
        ``Hand.teleport``."""
        q = self.solve_ik(data, tcp, seed=PANDA_REST_Q)
        opening_m = float(np.clip(opening_m, 0.0, MAX_OPENING_M))
        data.qpos[self.arm_qpos] = q
        data.qvel[self.arm_qvel] = 0.0
        data.qpos[self.finger_qpos] = opening_m / 2
        data.qvel[self.finger_qvel] = 0.0
        self.command_joints(data, q)
        self.target_tcp = np.asarray(tcp, float).copy()
        super().command(data, opening_m=opening_m)
        if forward:
            mujoco.mj_forward(self.model, data)

    def tcp_target(self, data: mujoco.MjData) -> np.ndarray:
        """The last commanded TCP (the current TCP before any command)."""
        return self.tcp(data) if self.target_tcp is None else self.target_tcp.copy()

    # --- inverse kinematics -----------------------------------------------------------------
    def solve_ik(self, data: mujoco.MjData, tcp, seed=None) -> np.ndarray:
        """Joint angles putting the TCP at ``tcp`` = (x, y, z [m], yaw [rad]) with the hand
        pointing down, within the joint limits and free of self-collision. Tries ``seed``
        (default the rest posture), then postures turned towards the target; none converging
        raises :class:`UnreachableError` naming the pose and the closest miss."""
        tcp = np.asarray(tcp, float)
        if tcp.shape != (4,) or not np.all(np.isfinite(tcp)):
            raise ValueError(f"tcp must be 4 finite numbers (x, y, z [m], yaw [rad]), got {tcp!r}")
        if np.any(tcp < self.tcp_low - 1e-9) or np.any(tcp > self.tcp_high + 1e-9):
            raise UnreachableError(f"TCP {np.round(tcp, 4).tolist()} is outside the Panda's command box "
                                   f"{list(self.tcp_low.round(4))} .. {list(self.tcp_high.round(4))}")
        ik = self._ik
        ik.qpos[:] = data.qpos  # the objects where they are, for the self-collision test
        best = (np.inf, None)
        for q0 in self._seeds(tcp, seed):
            q, err_m, err_rad = self._converge(tcp, np.clip(q0, self.q_low, self.q_high))
            if err_m <= IK_POSITION_TOL_M and err_rad <= IK_YAW_TOL_RAD:
                if not self.self_collides(q):
                    return q
                best = min(best, (0.0, "self-collision"), key=lambda b: b[0])
            else:
                best = min(best, (err_m, f"{err_m * 1e3:.1f} mm / {math.degrees(err_rad):.1f} deg off"),
                           key=lambda b: b[0])
        raise UnreachableError(f"the Panda cannot reach TCP {np.round(tcp, 4).tolist()} with the hand pointing "
                               f"down within its joint limits (closest: {best[1]})")

    def _seeds(self, tcp: np.ndarray, seed):
        """``seed`` (a warm start: usually enough), then postures turned towards the target
        (shoulder) and its yaw (wrist), stretched and folded."""
        yield np.asarray(seed if seed is not None else PANDA_REST_Q, float)
        base = self.model.body_pos[self._robot_bodies[0]]
        q1 = math.atan2(tcp[1] - base[1], tcp[0] - base[0])
        q7 = math.pi / 4 + tcp[3] - q1
        for shoulder, elbow, wrist in ((-0.2, -2.2, 2.0), (0.4, -2.6, 3.0), (-0.6, -1.6, 1.0)):
            yield np.array([q1, shoulder, 0.0, elbow, 0.0, wrist, q7])

    def _converge(self, tcp: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, float, float]:
        m, ik, jac = self.model, self._ik, self._jac
        target_pos, target_quat = tcp[:3], _yaw_quat(float(tcp[3]))
        rest = np.array(PANDA_REST_Q)
        dofs, qadr, site = self.arm_qvel, self.arm_qpos, self.tcp_site
        e, quat = np.zeros(6), np.zeros(4)
        damping, eye7 = _IK_DAMPING ** 2 * np.eye(6), np.eye(7)
        err_m = err_rad = np.inf
        for _ in range(_IK_ITERATIONS):
            ik.qpos[qadr] = q
            mujoco.mj_kinematics(m, ik)
            mujoco.mj_comPos(m, ik)
            e[:3] = target_pos - ik.site_xpos[site]
            # Orientation error: the rotation vector from the site's orientation to the target's.
            mujoco.mju_mat2Quat(quat, ik.site_xmat[site])
            mujoco.mju_subQuat(e[3:], target_quat, quat)
            e[3:] = ik.site_xmat[site].reshape(3, 3) @ e[3:]  # site frame -> world
            err_m, err_rad = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2), math.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2)
            if err_m <= IK_POSITION_TOL_M * 0.2 and err_rad <= IK_YAW_TOL_RAD * 0.2:
                break
            mujoco.mj_jacSite(m, ik, jac[:3], jac[3:], site)
            J = jac[:, dofs]
            # Damped least squares, plus a drift towards the rest posture in the null space
            # (keeps the elbow up and the joints away from their limits).
            solved = np.linalg.solve(J @ J.T + damping, np.column_stack([e, J]))
            dq = J.T @ solved[:, 0] + (eye7 - J.T @ solved[:, 1:]) @ (_IK_NULLSPACE_GAIN * (rest - q))
            q = np.clip(q + dq, self.q_low, self.q_high)
        return q, err_m, err_rad

    def self_collides(self, q) -> bool:
        """Whether an arm link touches another part of the robot at ``q`` (MuJoCo's
        collision detection; parent and child links never collide)."""
        m, ik = self.model, self._ik
        ik.qpos[self.arm_qpos] = np.asarray(q, float)
        mujoco.mj_kinematics(m, ik)
        mujoco.mj_collision(m, ik)
        if ik.ncon == 0:
            return False
        geoms = ik.contact.geom[:ik.ncon]
        robot, arm = self._geom_on_robot[geoms], self._geom_on_arm[geoms]
        return bool(np.any(robot[:, 0] & robot[:, 1] & (arm[:, 0] | arm[:, 1])))
