"""``aas_gym/AcousticGrasp-v0``: reach, grasp and sense an object with the floating hand."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import AasEnv
from aas_gym.grasp import SQUEEZE_TARGET_M
from aas_gym.robots import DEFAULT_ROBOT, check_robot
from aas_gym.scenario import position_along_path
from sensors.task import (GRASP_REWARD_TERMS, HOME_TCP, MAX_OPENING_M, STATE_LAYOUT, GraspHold, check_action,
                          check_choice, decode_grasp_action, grasp_reward_terms, next_tcp_target, records_this_step,
                          reward_total, step_success, tcp_object_distance_m)

# The TCP position and the object's centre in the state vector.
_TCP = slice(STATE_LAYOUT["tcp"].start, STATE_LAYOUT["tcp"].start + 3)
_OBJECT = slice(STATE_LAYOUT["object"].start, STATE_LAYOUT["object"].start + 3)
#: Joint-space control (``control="joint"``): the largest joint-target change per step [rad].
MAX_JOINT_DELTA_RAD = 0.05


class AcousticGraspEnv(AasEnv):
    """Reach, grasp and sense one object (single-object scene) or one object touched by
    others (``scene="multi"``). The task's rules (``sensors.task``: action, reward, cadence)
    are those of ``real.RealGraspEnv``.

    Action (Box, 6, in [-1, 1]): TCP delta x, y, z, yaw (scaled by 10 mm / 0.05 rad), gripper
    (> 0 open, <= 0 close with the grip force), sense (> 0 records ``duration_s`` of the
    excitation through the current grasp at the end of this step).

    Observation (Dict): ``tcp`` (x, y, z [m], yaw [rad]), ``tcp_velocity``, ``gripper``
    (opening [m], opening speed [m/s], motor force [N]), ``object`` (target position [m] and
    quaternion), ``acoustic`` (140-d features of the latest recording, zeros before the first,
    scaled per ``acoustic.feature_scale``), ``waveform`` (its raw samples, with
    ``acoustic.waveform``).

    Reward (``info["reward_terms"]``: ``reach``, ``grasp``, ``success``): minus the
    TCP-object distance [m], +1 while both sensor fingertips press the object, +10 for a
    recording of the grasped object, which ends the episode (success).
    ``info`` every step: ``is_success``, ``grasped``, ``label`` (the target), ``distance_m``
    (TCP to the object's centre [m]), ``reward_terms``; on a recording step also the ground
    truth of ``reset`` (object pose, padded contacts, ...), ``recording_grasped`` and
    ``grasp_position_m``.
    ``acoustic.cadence`` ``"every_step"`` records every step, ``"never"`` never (pure
    control); ``{"enabled": False}`` drops the entries.
    ``"stream"``: the microphone records through every physics step while the excitation
    loops; the observation adds ``audio`` (this step's ``dt`` x 44.1 kHz samples) and
    ``acoustic`` holds the features of the latest complete excitation period. The sense
    action then ends the episode with success once the latest complete period was recorded
    entirely after the grasp was first seen at a step's end (``sensors.task.cadence``);
    ``info["heard_fraction"]`` is the simulator's own count of that period's samples heard
    through both fingertips.

    ``acoustic`` defaults here: ``cadence="action"``.

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `objects` | sequence of str or `ObjectSpec` | `("aluminium_bar",)` | candidate targets, one drawn per episode (`"<material>_<shape>"`, an everyday object, `"<file>:<material>"`) |
    | `control` | str | `"cartesian"` | `"cartesian"`: the Box(6) action above (any robot); `"joint"` (`robot="panda"` only): Box(9), seven joint-target deltas (scaled by 0.05 rad, kept within the joint limits), gripper, sense; the observation adds `joint_positions` [rad] and `joint_velocities` [rad/s] |
    """

    _acoustic_defaults = {"cadence": "action"}
    reward_term_names = GRASP_REWARD_TERMS
    # The episode starts with the hand 0.3 m above the object: the closeup would miss the reach.
    _default_camera = "workspace"

    def __init__(self, objects=("aluminium_bar",), *, control: str = "cartesian", **kwargs) -> None:
        self.control = check_choice("control", control, ("cartesian", "joint"))
        # the robot's name first: a misspelt robot is named as such, not as a missing arm
        if control == "joint" and check_robot(kwargs.get("robot", DEFAULT_ROBOT)) != "panda":
            raise ValueError("control='joint' needs an arm: pass robot='panda'")
        super().__init__(objects, **kwargs)
        self.action_space = spaces.Box(-1.0, 1.0, (9 if control == "joint" else 6,), np.float32)
        joints = {} if control != "joint" else {name: spaces.Box(-np.inf, np.inf, (7,), np.float32)
                                                  for name in ("joint_positions", "joint_velocities")}
        self.observation_space = spaces.Dict({**self._proprio_spaces(with_object=True), **joints,
                                              **self._acoustic_spaces()})
        self._last_acoustic = self._empty_acoustic()
        self._hold = GraspHold(self.excitation.period_samples)

    def _obs_and_values(self):
        obs, values = self._state_obs(True)
        if self.control == "joint":
            # joint-space actions need the joints: the TCP pose leaves the arm's redundancy open
            sc = self._scene
            obs["joint_positions"] = sc.qpos[sc.hand.arm_qpos].astype(np.float32)
            obs["joint_velocities"] = sc.qvel[sc.hand.arm_qvel].astype(np.float32)
        for key, value in self._last_acoustic.items():
            obs[key] = value.copy()
        return obs, values

    def _reset_episode(self, options: dict):
        self.hand.teleport(self.data, HOME_TCP, MAX_OPENING_M)
        self.hand.set_grip_force(self._episode_grip_force())
        self._last_acoustic = self._empty_acoustic()
        self._hold.reset()
        info = self._ground_truth(contacts=True)
        info["grip_force_n"] = self.hand.grip_force_n
        return self._obs_and_values()[0], info

    def step(self, action):
        sc = self._scene
        if self.control == "joint":
            a = check_action(action, (9,))
            act = decode_grasp_action(np.concatenate([np.zeros(4), a[7:]]))
            arm = sc.hand
            step = np.clip(a[:7], -1.0, 1.0) * MAX_JOINT_DELTA_RAD
            arm.command_joints(sc.data, np.clip(arm.target_q + step, arm.q_low, arm.q_high))
        else:
            act = decode_grasp_action(action)
            sc.set_tcp_target(next_tcp_target(sc.tcp_target(), act.tcp_delta, sc.tcp_low, sc.tcp_high))
        ctrl = sc.ctrl
        ctrl[sc.gripper] = MAX_OPENING_M if act.open_gripper else SQUEEZE_TARGET_M
        self._simulate()
        due = self._acoustic_due()  # acoustic.update_period_s
        grasped = self._is_grasped()
        cadence = self.cadence
        info = {"grasped": bool(grasped), "is_success": False, "label": sc.objects[0].label}
        success = False
        if cadence == "stream":
            if due:
                self._last_acoustic = self._stream_entries()
            stream = self._stream.stream
            info["heard_fraction"] = float(stream.latest_features_heard)
            self._hold.update(grasped, stream.sample_index)
            success = step_success(cadence, sense=act.sense, grasped=grasped,
                                   heard_whole_period=self._hold.heard_whole_period(stream.latest_features_period))
        elif due and records_this_step(cadence, act.sense):
            acoustic, heard_grasped, truth = self._sense_and_truth()
            self._last_acoustic = acoustic
            info.update(truth)
            info["recording_grasped"] = heard_grasped
            # Where along the object's main axis the TCP is (the grasp position when grasped).
            rot = sc.data.xmat[sc.target_body].reshape(3, 3)
            local = rot.T @ (sc.site_xpos[sc.tcp_site] - sc.xpos[sc.target_body])
            info["grasp_position_m"] = float(local[0]) if sc.objects[0].is_prism else \
                float(position_along_path(sc.objects[0], local))
            success = step_success(cadence, sense=act.sense, grasped=grasped,
                                   recording_grasped=info["recording_grasped"])
        obs, v = self._obs_and_values()
        distance_m = tcp_object_distance_m(v[_TCP], v[_OBJECT])
        terms = grasp_reward_terms(distance_m, grasped, success)
        info["is_success"] = bool(success)
        info["distance_m"] = distance_m
        info["reward_terms"] = terms
        if self.render_mode == "human":
            self.render()
        return obs, reward_total(terms), success, False, info
