"""``aas_gym/AcousticGrasp-v0``: reach, grasp and sense an object with the floating hand."""

from __future__ import annotations

import math

import mujoco
import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import HOME_TCP, AasEnv

# Largest TCP change per env step (action 1, dt = 0.05 s): 10 mm, 0.05 rad.
MAX_DELTA = (0.01, 0.01, 0.01, 0.05)


class AcousticGraspEnv(AasEnv):
    """Reach, grasp and sense one object (single-object scene) or one object touched by
    others (``scene="multi"``).

    Action (Box, 6, in [-1, 1]): TCP delta x, y, z, yaw (scaled by 10 mm / 0.05 rad), gripper
    (> 0 open, <= 0 close with the grip force), sense (> 0 records ``duration_s`` of the
    excitation through the current grasp at the end of this step).

    Observation (Dict): ``tcp`` (x, y, z [m], yaw [rad]), ``tcp_velocity``, ``gripper``
    (opening [m], opening speed [m/s], motor force [N]), ``object`` (target position [m] and
    quaternion), ``acoustic`` (140-d features of the latest recording, zeros before the first),
    ``waveform`` (its raw samples, with ``include_waveform=True``).

    Reward: minus the TCP-object distance [m], +1 while both sensor fingertips press the
    object, +10 for a recording of the grasped object, which ends the episode (success).
    ``sense_mode="every_step"`` records every step, ``"never"`` never (pure control).
    """

    def __init__(self, objects=("aluminium_bar",), *, sense_mode: str = "action", **kwargs) -> None:
        super().__init__(objects, **kwargs)
        if sense_mode not in ("action", "every_step", "never"):
            raise ValueError(f"sense_mode must be 'action', 'every_step' or 'never', got {sense_mode!r}")
        self.sense_mode = sense_mode
        self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        obs = self._proprio_spaces()
        obs["object"] = spaces.Box(-np.inf, np.inf, (7,), np.float32)
        obs.update(self._acoustic_spaces())
        self.observation_space = spaces.Dict(obs)
        self._last_acoustic = self._empty_acoustic()

    def _obs(self) -> dict:
        return self._obs_and_values()[0]

    def _obs_and_values(self):
        obs, values = self._state_obs(True)
        for key, value in self._last_acoustic.items():
            obs[key] = value.copy()
        return obs, values

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = options or {}
        target = self._target_object(options)
        self._get_scene(self._choose_objects(target))
        self._place_objects()
        self.hand.teleport(self.data, HOME_TCP, 0.08)
        self.hand.set_grip_force(self._episode_grip_force())
        self._randomize_sensor()
        self._last_acoustic = self._empty_acoustic()
        info = self._ground_truth(contacts=True)
        info["grip_force_n"] = self.hand.grip_force_n
        if self.render_mode == "human":
            self.render()
        return self._obs(), info

    def step(self, action):
        try:
            a = np.asarray(action, dtype=np.float64).reshape(6).tolist()
        except ValueError:
            raise ValueError(f"action must have 6 entries, got shape {np.shape(action)}") from None
        sc = self._scene
        ctrl, low, high = sc.ctrl, sc.tcp_low, sc.tcp_high
        target = ctrl[sc.tcp_ctrl].tolist()
        # Per-step code in plain floats: four numbers do not need numpy's call overhead.
        for i in range(4):
            v = target[i] + max(-1.0, min(1.0, a[i])) * MAX_DELTA[i]
            target[i] = min(max(v, low[i]), high[i])
        ctrl[sc.tcp_ctrl] = target
        ctrl[sc.gripper] = 0.08 if a[4] > 0 else 0.0
        mujoco.mj_step(sc.model, sc.data, nstep=self.frame_skip)
        grasped = self._is_grasped()
        sense = self.sense_mode == "every_step" or (self.sense_mode == "action" and a[5] > 0)
        info = {"grasped": grasped, "is_success": False}
        terminated = False
        bonus = 0.0
        if sense:
            acoustic, rec = self._sense()
            self._last_acoustic = acoustic
            info.update(self._ground_truth(contacts=True))
            info["recording_grasped"] = bool(rec.metadata.get("grasped", False))
            # Where along the object's main axis the TCP is (the grasp position when grasped).
            rot = sc.data.xmat[sc.target_body].reshape(3, 3)
            info["grasp_position_m"] = float((rot.T @ (sc.site_xpos[sc.tcp_site] - sc.xpos[sc.target_body]))[0])
            if grasped and info["recording_grasped"] and self.sense_mode == "action":
                bonus = 10.0
                terminated = True
                info["is_success"] = True
        obs, v = self._obs_and_values()
        # TCP and object centre from the state: the carriage joints are the TCP coordinates.
        dist = math.sqrt((v[0] - v[11]) ** 2 + (v[1] - v[12]) ** 2 + (v[2] - v[13]) ** 2)
        reward = -dist + (1.0 if grasped else 0.0) + bonus
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), terminated, False, info
