"""``aas_gym/ObjectRecognition-v0``: active acoustic object recognition."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from aas_gym.envs.base import EXCITATION_NAMES, AasEnv, resolve_excitation
from aas_gym.scene import DEFAULT_OBJECT_NAMES


class ObjectRecognitionEnv(AasEnv):
    """Probe an unknown object by grasping it where you choose and playing the excitation you
    choose; finally name it.

    Action (Dict): ``command`` (0 = probe, 1 = answer), ``position`` (Box [-1, 1]: grasp point
    along the main axis as a fraction of ``max_position_m``), ``excitation`` (0 impulse,
    1 linear sweep, 2 exponential sweep), ``label`` (index into ``labels``, used on answer).
    Observation (Dict): proprioception, ``acoustic`` (140-d, latest probe), ``waveform``
    (optional), ``probe`` (position fraction and excitation one-hot of the latest probe),
    ``n_probes``.
    Reward: ``-probe_cost`` per probe; on answer 1 if correct else 0, and the episode ends.
    With ``scene="multi"`` other objects lie across one end of the target (random contacts).
    ``info``: true ``label`` / ``label_index``, material, shape, grasp position, contacts.
    """

    def __init__(self, objects=None, *, probe_cost: float = 0.01, max_position_m: float = 0.05, **kwargs) -> None:
        super().__init__(objects if objects is not None else DEFAULT_OBJECT_NAMES, **kwargs)
        self.labels = [o.label for o in self.objects]
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"object labels must be unique, got {self.labels}")
        self.probe_cost = float(probe_cost)
        self.max_position_m = float(max_position_m)
        self.excitations = [resolve_excitation(n) for n in EXCITATION_NAMES]
        self.action_space = spaces.Dict({
            "command": spaces.Discrete(2),
            "position": spaces.Box(-1.0, 1.0, (1,), np.float32),
            "excitation": spaces.Discrete(len(self.excitations)),
            "label": spaces.Discrete(len(self.labels)),
        })
        obs = self._proprio_spaces()
        obs.update(self._acoustic_spaces())
        obs["probe"] = spaces.Box(-1.0, 1.0, (1 + len(self.excitations),), np.float32)
        obs["n_probes"] = spaces.Box(0.0, np.inf, (1,), np.float32)
        self.observation_space = spaces.Dict(obs)

    def _obs(self) -> dict:
        obs = self._proprio()
        obs.update({k: v.copy() for k, v in self._acoustic.items()})
        obs["probe"] = self._probe.copy()
        obs["n_probes"] = np.array([self._n_probes], np.float32)
        return obs

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        options = options or {}
        k = int(options.get("label_index", self.np_random.integers(len(self.objects))))
        if not 0 <= k < len(self.objects):
            raise ValueError(f"label_index must be in [0, {len(self.objects)}), got {k}")
        self._label_index = k
        self._get_scene(self._choose_objects(self.objects[k]))
        self._place_objects()
        self._randomize_sensor()
        self._grip = self._episode_grip_force()
        self._acoustic = self._empty_acoustic()
        self._probe = np.zeros(1 + len(self.excitations), np.float32)
        self._n_probes = 0
        info = self._ground_truth(contacts=False)
        info["label_index"] = k
        return self._obs(), info

    def step(self, action):
        if not isinstance(action, dict) or not {"command", "position", "excitation", "label"} <= set(action):
            raise ValueError("action must be a dict with keys command, position, excitation, label")
        command = int(action["command"])
        if command == 1:
            guess = int(action["label"])
            correct = guess == self._label_index
            info = {"label": self.labels[self._label_index], "label_index": self._label_index,
                    "guess": guess, "is_success": correct}
            return self._obs(), 1.0 if correct else 0.0, True, False, info
        fraction = float(np.clip(np.asarray(action["position"], dtype=np.float64).reshape(-1)[0], -1, 1))
        e = int(action["excitation"])
        if not 0 <= e < len(self.excitations):
            raise ValueError(f"excitation must be in [0, {len(self.excitations)}), got {e}")
        grasp = self._grasp(fraction * self.max_position_m, self._grip)
        self._acoustic, rec = self._sense(self.excitations[e])
        self._probe = np.zeros_like(self._probe)
        self._probe[0], self._probe[1 + e] = fraction, 1.0
        self._n_probes += 1
        info = self._ground_truth(contacts=True)
        info.update(grasp, label_index=self._label_index, excitation=EXCITATION_NAMES[e],
                    recording_grasped=bool(rec.metadata.get("grasped", False)))
        if self.render_mode == "human":
            self.render()
        return self._obs(), -self.probe_cost, False, False, info
