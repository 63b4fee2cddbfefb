"""``aas_gym/GraspPosition-v0``: the paper's grasp-position task."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import AasEnv
from aas_gym.object_grasps import grasp_span_m
from sensors.task import check_action, check_choice, check_integer, check_number

ACTION_FORMATS = ("normalized", "metres")
#: The most grasp positions an env takes (``n_positions``; more would not fit on any object
#: at a resolvable spacing).
MAX_POSITIONS = 10_000


class GraspPositionEnv(AasEnv):
    """Planar grasps at positions along the object's main axis; estimate the position.

    Each episode grasps the object at one of ``n_positions`` points ``spacing_m`` apart on the
    +x half of its main axis (paper: 13 positions 5 mm apart, 0-60 mm from the centre), drawn
    from ``np_random`` (or ``options={"position_index": k}``), and records the excitation.
    Any other object (everyday shapes, user meshes) is grasped at the antipodal grasp nearest
    each point, the points measured along its grasp path from its first grasp
    (``aas_gym.object_grasps``); ``grasp_position_m`` is then that grasp's position.

    Observation (Dict): proprioception (``tcp``, ``tcp_velocity``, ``gripper``), ``acoustic``
    (140-d), ``waveform`` (with ``acoustic.waveform``).
    Action (Box, 1): the estimated grasp position. ``action_format="normalized"`` (default,
    what Stable-Baselines3 expects): -1 .. 1 maps linearly onto 0 .. the last position [m];
    ``"metres"``: the position in metres from the centre, Box(0, last position).
    Reward (``info["reward_terms"]``: ``error``): minus the absolute error [m]; the episode
    ends after the estimate.
    ``info`` (reset): ``grasp_position_m`` (true, including the randomized placement error),
    ``position_index``, ``nominal_position_m``, label, material, shape, object pose, padded
    contacts. ``info`` (step): ``is_success`` (the estimate is within half a ``spacing_m`` of
    the true position: the nearest grid position is the right one), ``grasp_position_m``,
    ``position_index``, ``label``, ``estimate_m``, ``abs_error_m``, ``reward_terms``.

    ``acoustic``: every episode records once, through its grasp, whatever the cadence (and not
    at all with ``enabled=False``: ``recording_grasped`` then says whether a grasp would be heard).

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `objects` | sequence of str or `ObjectSpec` | `("wood_bar",)` | candidate objects, one drawn per episode |
    | `n_positions` | int | 13 | grasp positions along the +x half of the main axis (paper: 13) |
    | `spacing_m` | float | 0.005 | distance between neighbouring positions [m] |
    | `action_format` | str | `"normalized"` | `"normalized"`: Box(1) in [-1, 1] onto 0 .. the last position; `"metres"`: the position [m] |
    """

    _far_end_only = True
    _step_is_probe = True
    _settle_canonical = True
    _grasp_follows_placement = True
    reset_options = ("object", "position_index")
    reward_term_names = ("error",)

    def __init__(self, objects=("wood_bar",), *, n_positions: int = 13, spacing_m: float = 0.005,
                 action_format: str = "normalized", **kwargs) -> None:
        n_positions = check_integer("n_positions", n_positions, 1, MAX_POSITIONS)
        spacing_m = check_number("spacing_m", spacing_m, 0.0, low_open=True, unit="m")
        check_choice("action_format", action_format, ACTION_FORMATS)
        super().__init__(objects, **kwargs)
        self.positions_m = np.arange(n_positions) * spacing_m
        self.spacing_m = float(spacing_m)
        for obj in self.objects:
            lo, hi = grasp_span_m(obj)
            if self.positions_m[-1] > hi - max(lo, 0.0):
                raise ValueError(f"grasp positions up to {self.positions_m[-1] * 1e3:.0f} mm do not fit on the "
                                 f"{obj.label}, grasped over {(hi - max(lo, 0.0)) * 1e3:.0f} mm from its first position: "
                                 "use fewer n_positions or a smaller spacing_m")
        self.action_format = action_format
        top = float(self.positions_m[-1])
        self.action_space = (spaces.Box(-1.0, 1.0, (1,), np.float32) if action_format == "normalized"
                             else spaces.Box(0.0, top, (1,), np.float32))
        self.observation_space = spaces.Dict({**self._proprio_spaces(), **self._acoustic_spaces()})
        self._true_position = 0.0
        self._position_index = 0

    def position_from_action(self, action) -> float:
        """The position estimate [m] an action stands for."""
        a = float(check_action(action, (1,))[0])
        if self.action_format == "normalized":
            return (float(np.clip(a, -1.0, 1.0)) + 1.0) / 2.0 * float(self.positions_m[-1])
        return a

    def _reset_episode(self, options: dict):
        k = check_integer("position_index", options.get("position_index", self.np_random.integers(len(self.positions_m))),
                          0, len(self.positions_m) - 1)
        # Prisms from their centre (the paper's +x half); other objects from their grasp path's start.
        start = 0.0 if self._scene.objects[0].is_prism else grasp_span_m(self._scene.objects[0])[0]
        grasp = self._grasp(start + float(self.positions_m[k]), self._episode_grip_force())
        grasp["grasp_position_m"] -= start
        acoustic, heard_grasped, truth = self._sense_and_truth()
        self._true_position = grasp["grasp_position_m"]
        self._position_index = int(k)
        obs = self._proprio()
        obs.update(acoustic)
        info = truth
        info.update(grasp, position_index=k, nominal_position_m=float(self.positions_m[k]),
                    recording_grasped=heard_grasped)
        return obs, info

    def step(self, action):
        estimate = self.position_from_action(action)
        error = abs(estimate - self._true_position)
        obs = self._proprio()
        obs.update(self._empty_acoustic())
        info = {"is_success": bool(error <= self.spacing_m / 2), "grasp_position_m": self._true_position,
                "position_index": self._position_index, "label": self._scene.objects[0].label,
                "estimate_m": estimate, "abs_error_m": error, "reward_terms": {"error": -error}}
        return obs, -error, True, False, info
