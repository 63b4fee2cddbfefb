"""``aas_gym/ObjectRecognition-v0``: active acoustic object recognition."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import EXCITATION_NAMES, AasEnv
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from aas_gym.object_grasps import grasp_span_m
from sensors.task import check_action, check_choice, check_integer, check_number, resolve_excitation

ACTION_FORMATS = ("box", "dict")
_DICT_KEYS = ("command", "position", "excitation", "label")


class ObjectRecognitionEnv(AasEnv):
    """Probe an unknown object by grasping it where you choose and playing the excitation you
    choose; finally name it.

    Action, ``action_format="box"`` (default; any Stable-Baselines3 algorithm trains it):
    Box(4) in [-1, 1] = ``command`` (> 0 answer, else probe), ``position`` (grasp point along
    a prism's main axis as a fraction of ``max_position_m``; for another object, -1 .. 1 spans
    its grasp path), ``excitation`` and ``label`` (the
    interval [-1, 1] cut into equal bins: 3 excitations impulse / linear / exponential, then
    one bin per label). ``action_format="dict"``: Dict ``command`` Discrete(2), ``position``
    Box(1), ``excitation`` Discrete(3), ``label`` Discrete(len(labels)).
    Observation (Dict): proprioception, ``acoustic`` (140-d, latest probe), ``waveform``
    (optional), ``probe`` (position fraction and excitation one-hot of the latest probe),
    ``n_probes``.
    Reward (``info["reward_terms"]``: ``probe``, ``answer``): ``-probe_cost`` per probe; on
    answer 1 if correct else 0, and the episode ends.
    With ``scene="multi"`` other objects lie across one end of the target (random contacts).
    ``info``: ``is_success`` (the answer names the target; False on probe steps), true
    ``label`` / ``label_index``, ``reward_terms``; a probe step adds material, shape, grasp
    position, excitation, padded contacts; an answer adds ``guess``.

    ``acoustic`` defaults here: ``cadence="every_step"`` (every probe records, with the
    excitation the action chooses; ``acoustic.excitation`` is not used; with ``enabled=False``
    nothing is recorded: ``recording_grasped`` then says whether a grasp would be heard).

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `objects` | sequence of str or `ObjectSpec`, or None | None | the candidate objects, one per label; None: the paper's seven |
    | `probe_cost` | float | 0.01 | reward subtracted per probe |
    | `max_position_m` | float | 0.05 | a prism's grasp position for the position entry 1 [m] |
    | `action_format` | str | `"box"` | `"box"`: Box(4) in [-1, 1]; `"dict"`: the Dict action |
    """

    _acoustic_defaults = {"cadence": "every_step"}
    _step_is_probe = True
    _settle_canonical = True
    reset_options = ("label_index",)
    reward_term_names = ("probe", "answer")

    def __init__(self, objects=None, *, probe_cost: float = 0.01, max_position_m: float = 0.05,
                 action_format: str = "box", **kwargs) -> None:
        check_choice("action_format", action_format, ACTION_FORMATS)
        probe_cost = check_number("probe_cost", probe_cost)
        max_position_m = check_number("max_position_m", max_position_m, 0.0, low_open=True, unit="m")
        super().__init__(objects if objects is not None else DEFAULT_OBJECT_NAMES, **kwargs)
        self.labels = [o.label for o in self.objects]
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"object labels must be unique, got {self.labels}")
        self.probe_cost = float(probe_cost)
        self.max_position_m = float(max_position_m)
        self.excitations = [resolve_excitation(n) for n in EXCITATION_NAMES]
        self.action_format = action_format
        if action_format == "box":
            self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
        else:
            self.action_space = spaces.Dict({
                "command": spaces.Discrete(2),
                "position": spaces.Box(-1.0, 1.0, (1,), np.float32),
                "excitation": spaces.Discrete(len(self.excitations)),
                "label": spaces.Discrete(len(self.labels)),
            })
        obs = {**self._proprio_spaces(), **self._acoustic_spaces()}
        obs["probe"] = spaces.Box(-1.0, 1.0, (1 + len(self.excitations),), np.float32)
        obs["n_probes"] = spaces.Box(0.0, np.inf, (1,), np.float32)
        self.observation_space = spaces.Dict(obs)

    def decode_action(self, action) -> tuple[int, float, int, int]:
        """``(command, position fraction, excitation index, label index)`` of an action;
        ``ValueError`` for NaN/inf, a wrong shape or missing keys."""
        if self.action_format == "box":
            a = np.clip(check_action(action, (4,)), -1.0, 1.0)
            return (int(a[0] > 0), float(a[1]), _bin(a[2], len(self.excitations)), _bin(a[3], len(self.labels)))
        if not isinstance(action, dict) or not set(_DICT_KEYS) <= set(action):
            raise ValueError("action must be a dict with keys command, position, excitation, label")
        position = float(np.clip(check_action(action["position"], (1,))[0], -1.0, 1.0))
        command, e, label = (int(check_action(action[k], ())) for k in ("command", "excitation", "label"))
        if not 0 <= e < len(self.excitations):
            raise ValueError(f"excitation must be in [0, {len(self.excitations)}), got {e}")
        return command, position, e, label

    def _obs(self) -> dict:
        obs = self._proprio()
        obs.update({k: v.copy() for k, v in self._acoustic.items()})
        obs["probe"] = self._probe.copy()
        obs["n_probes"] = np.array([self._n_probes], np.float32)
        return obs

    def _target_object(self, options: dict):
        """The target by ``options["label_index"]`` or drawn from ``objects``."""
        k = check_integer("label_index", options.get("label_index", self.np_random.integers(len(self.objects))),
                          0, len(self.objects) - 1)
        self._label_index = k
        return self.objects[k]

    def _reset_episode(self, options: dict):
        self._grip = self._episode_grip_force()
        self._acoustic = self._empty_acoustic()
        self._probe = np.zeros(1 + len(self.excitations), np.float32)
        self._n_probes = 0
        info = self._ground_truth(contacts=False)
        info["label_index"] = self._label_index
        return self._obs(), info

    def step(self, action):
        command, fraction, e, guess = self.decode_action(action)
        if command == 1:
            correct = guess == self._label_index
            info = {"label": self.labels[self._label_index], "label_index": self._label_index,
                    "guess": guess, "is_success": bool(correct)}
            info["reward_terms"] = {"probe": 0.0, "answer": 1.0 if correct else 0.0}
            return self._obs(), 1.0 if correct else 0.0, True, False, info
        target = self._scene.objects[0]
        if target.is_prism:
            position = fraction * self.max_position_m
        else:  # the whole grasp path of a surface object
            lo, hi = grasp_span_m(target)
            position = lo + (fraction + 1.0) / 2.0 * (hi - lo)
        grasp = self._grasp(position, self._grip)
        self._acoustic, heard_grasped, truth = self._sense_and_truth(self.excitations[e])
        self._probe = np.zeros_like(self._probe)
        self._probe[0], self._probe[1 + e] = fraction, 1.0
        self._n_probes += 1
        info = truth
        info.update(grasp, is_success=False, label_index=self._label_index, excitation=EXCITATION_NAMES[e],
                    recording_grasped=heard_grasped,
                    reward_terms={"probe": -self.probe_cost, "answer": 0.0})
        if self.render_mode == "human":
            self.render()
        return self._obs(), -self.probe_cost, False, False, info


def _bin(value: float, n: int) -> int:
    """Index of the bin of [-1, 1] cut into ``n`` equal bins that holds ``value``."""
    return min(n - 1, int((float(value) + 1.0) / 2.0 * n))
