"""``aas_gym/AcousticGrasp-v0``: reach, grasp and sense an object with the floating hand."""

from __future__ import annotations

import math

import mujoco
import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import _OBJECT, _TCP, AasEnv
from aas_gym.grasp import SQUEEZE_TARGET_M
from aas_gym.scenario import position_along_path
from sensors.task.grasp import HOME_TCP, MAX_DELTA, MAX_OPENING_M, check_action


class AcousticGraspEnv(AasEnv):
    """Reach, grasp and sense one object (single-object scene) or one object touched by
    others (``scene="multi"``).

    Action (Box, 6, in [-1, 1]): TCP delta x, y, z, yaw (scaled by 10 mm / 0.05 rad), gripper
    (> 0 open, <= 0 close with the grip force), sense (> 0 records ``duration_s`` of the
    excitation through the current grasp at the end of this step).

    Observation (Dict): ``tcp`` (x, y, z [m], yaw [rad]), ``tcp_velocity``, ``gripper``
    (opening [m], opening speed [m/s], motor force [N]), ``object`` (target position [m] and
    quaternion), ``acoustic`` (140-d features of the latest recording, zeros before the first,
    scaled per ``acoustic.feature_scale``), ``waveform`` (its raw samples, with
    ``acoustic.waveform``).

    Reward: minus the TCP-object distance [m], +1 while both sensor fingertips press the
    object, +10 for a recording of the grasped object, which ends the episode (success).
    ``acoustic.cadence`` (or ``sense_mode``) ``"every_step"`` records every step, ``"never"``
    never (pure control); ``acoustic=False``-like ``{"enabled": False}`` drops the entries.
    ``"stream"``: the microphone records through every physics step while the excitation
    loops; the observation adds ``audio`` (this step's ``dt`` x 44.1 kHz samples) and
    ``acoustic`` holds the features of the latest complete excitation period. The sense
    action then ends the episode with success once a whole period was heard through the
    grasp (``info["heard_fraction"]``).
    """

    _acoustic_defaults = {"cadence": "action"}

    def __init__(self, objects=("aluminium_bar",), **kwargs) -> None:
        super().__init__(objects, **kwargs)
        self.action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.observation_space = spaces.Dict({**self._proprio_spaces(with_object=True), **self._acoustic_spaces()})
        self._last_acoustic = self._empty_acoustic()

    @property
    def sense_mode(self) -> str:
        return self.acoustic.cadence if self.acoustic.enabled else "never"

    def _obs_and_values(self):
        obs, values = self._state_obs(True)
        for key, value in self._last_acoustic.items():
            obs[key] = value.copy()
        return obs, values

    def _reset_episode(self, options: dict):
        self.hand.teleport(self.data, HOME_TCP, MAX_OPENING_M)
        self.hand.set_grip_force(self._episode_grip_force())
        self._last_acoustic = self._empty_acoustic()
        info = self._ground_truth(contacts=True)
        info["grip_force_n"] = self.hand.grip_force_n
        return self._obs_and_values()[0], info

    def step(self, action):
        a = check_action(action, (6,)).tolist()
        sc = self._scene
        ctrl, low, high = sc.ctrl, sc.tcp_low, sc.tcp_high
        target = ctrl[sc.tcp_ctrl].tolist()
        # Per-step code in plain floats: four numbers do not need numpy's call overhead.
        for i in range(4):
            v = target[i] + max(-1.0, min(1.0, a[i])) * MAX_DELTA[i]
            target[i] = min(max(v, low[i]), high[i])
        ctrl[sc.tcp_ctrl] = target
        ctrl[sc.gripper] = MAX_OPENING_M if a[4] > 0 else SQUEEZE_TARGET_M
        self._simulate()
        grasped = self._is_grasped()
        mode = self.sense_mode
        sense = mode == "every_step" or (mode == "action" and a[5] > 0)
        info = {"grasped": grasped, "is_success": False}
        terminated = False
        bonus = 0.0
        if mode == "stream":
            self._last_acoustic = self._stream_entries()
            heard = self._stream.stream.latest_features_heard
            info["heard_fraction"] = heard
            # Success: asked to stop while grasping, after a whole period heard through the grasp.
            if a[5] > 0 and grasped and heard > 0.99:
                bonus, terminated, info["is_success"] = 10.0, True, True
        elif sense:
            acoustic, rec = self._sense()
            self._last_acoustic = acoustic
            info.update(self._ground_truth(contacts=True))
            info["recording_grasped"] = bool(rec.metadata.get("grasped", False))
            # Where along the object's main axis the TCP is (the grasp position when grasped).
            rot = sc.data.xmat[sc.target_body].reshape(3, 3)
            local = rot.T @ (sc.site_xpos[sc.tcp_site] - sc.xpos[sc.target_body])
            info["grasp_position_m"] = float(local[0]) if sc.objects[0].is_prism else \
                float(position_along_path(sc.objects[0], local))
            if grasped and info["recording_grasped"] and mode == "action":
                bonus = 10.0
                terminated = True
                info["is_success"] = True
        obs, v = self._obs_and_values()
        # TCP and object centre from the state vector's named entries.
        dist = math.sqrt((v[_TCP] - v[_OBJECT]) ** 2 + (v[_TCP + 1] - v[_OBJECT + 1]) ** 2
                         + (v[_TCP + 2] - v[_OBJECT + 2]) ** 2)
        reward = -dist + (1.0 if grasped else 0.0) + bonus
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), terminated, False, info
