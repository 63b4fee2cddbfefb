"""``aas_gym/GraspPosition-v0``: the paper's grasp-position task."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import AasEnv


class GraspPositionEnv(AasEnv):
    """Planar grasps at positions along the object's main axis; estimate the position.

    Each episode grasps the object at one of ``n_positions`` points ``spacing_m`` apart on the
    +x half of its main axis (paper: 13 positions 5 mm apart, 0-60 mm from the centre), drawn
    from ``np_random`` (or ``options={"position_index": k}``), and records the excitation.

    Observation (Dict): proprioception (``tcp``, ``tcp_velocity``, ``gripper``), ``acoustic``
    (140-d), ``waveform`` (with ``include_waveform=True``).
    Action (Box, 1): the estimated grasp position [m] along the axis from the centre.
    Reward: minus the absolute error [m]; the episode ends after the estimate.
    ``info``: ``grasp_position_m`` (true, including the randomized placement error),
    ``position_index``, label, material, shape, object pose, contacts.
    """

    _far_end_only = True

    def __init__(self, objects=("wood_bar",), *, n_positions: int = 13, spacing_m: float = 0.005, **kwargs) -> None:
        super().__init__(objects, **kwargs)
        if n_positions < 1 or spacing_m <= 0:
            raise ValueError("n_positions must be >= 1 and spacing_m > 0")
        self.positions_m = np.arange(n_positions) * float(spacing_m)
        half = min(o.length_m for o in self.objects) / 2
        if self.positions_m[-1] > half - 0.02:
            raise ValueError(f"grasp positions up to {self.positions_m[-1]:.3f} m do not fit on a "
                             f"{2 * half:.3f} m object (fingertip needs 20 mm)")
        self.action_space = spaces.Box(0.0, float(self.positions_m[-1]), (1,), np.float32)
        obs = self._proprio_spaces()
        obs.update(self._acoustic_spaces())
        self.observation_space = spaces.Dict(obs)
        self._true_position = 0.0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = options or {}
        target = self._target_object(options)
        k = int(options.get("position_index", self.np_random.integers(len(self.positions_m))))
        if not 0 <= k < len(self.positions_m):
            raise ValueError(f"position_index must be in [0, {len(self.positions_m)}), got {k}")
        self._get_scene(self._choose_objects(target))
        self._place_objects()
        self._randomize_sensor()
        grasp = self._grasp(float(self.positions_m[k]), self._episode_grip_force())
        acoustic, rec = self._sense()
        self._true_position = grasp["grasp_position_m"]
        obs = self._proprio()
        obs.update(acoustic)
        info = self._ground_truth(contacts=True)
        info.update(grasp, position_index=k, nominal_position_m=float(self.positions_m[k]),
                    recording_grasped=bool(rec.metadata.get("grasped", False)))
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action):
        estimate = float(np.asarray(action, dtype=np.float64).reshape(-1)[0])
        error = abs(estimate - self._true_position)
        obs = self._proprio()
        obs.update(self._empty_acoustic())
        info = {"grasp_position_m": self._true_position, "abs_error_m": error}
        return obs, -error, True, False, info
