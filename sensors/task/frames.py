"""What an env shows of its acoustic sensor over time: the update schedule
(``AcousticConfig.update_period_s``) and the history of the last N frames
(``AcousticConfig.history``), the same for the simulated envs and ``real.RealGraspEnv``.
"""

from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["AcousticFrames"]


class AcousticFrames:
    """The acoustic entries of an env's observation.

    ``empty``: one frame's entries before any recording (zeros); ``history``: frames kept (1:
    the frame itself, shape unchanged; N > 1: each entry stacked to ``(N, ...)``, oldest
    first); ``steps_per_update``: the update period in env steps, ``r > 0``. The sensor is due
    at the times ``0, r, 2r, ...`` (in steps from the episode's start) and updates at each step
    ``n`` whose span ``[n, n + 1)`` holds one: a whole ``k`` gives steps 0, k, 2k, ...; a
    fraction keeps the mean rate (``r = 1.4``: steps 0, 1, 2, 4, 5, 7, ...); ``r <= 1``
    updates every step.
    """

    #: Due times within this many steps of a step boundary belong to the later step (float
    #: rounding of ``period / dt``).
    _TOLERANCE_STEPS = 1e-9

    def __init__(self, empty: dict[str, np.ndarray], history: int = 1, steps_per_update: float = 1) -> None:
        self._empty = {k: np.asarray(v) for k, v in empty.items()}
        self.history = int(history)
        if not (np.isfinite(steps_per_update) and steps_per_update > 0):
            raise ValueError(f"steps_per_update must be a positive finite number, got {steps_per_update!r}")
        self.steps_per_update = steps_per_update
        self._frames: deque[dict[str, np.ndarray]] = deque(maxlen=self.history)
        self._step = 0
        self._next_due = 0  # index m of the next due time m * steps_per_update
        self.reset()

    def reset(self) -> dict[str, np.ndarray]:
        """A new episode: the history all zeros, the schedule at step 0; the observation."""
        self._frames.clear()
        self._frames.extend([self._empty] * self.history)
        self._step = 0
        self._next_due = 0
        return self.observation()

    def due(self) -> bool:
        """Whether the sensor updates at this step; advances the schedule by one step (call
        once per env step)."""
        self._step += 1
        end = self._step - self._TOLERANCE_STEPS  # this step spans [step - 1, step)
        due = self._next_due * self.steps_per_update < end
        if due:  # the first due time at or after this step's end
            self._next_due = int(np.ceil(end / self.steps_per_update))
        return due

    def push(self, entries: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """A new frame (one recording's or stream step's entries); the observation."""
        self._frames.append({k: np.asarray(v) for k, v in entries.items()})
        return self.observation()

    def observation(self) -> dict[str, np.ndarray]:
        """The entries as the observation shows them (fresh arrays)."""
        if self.history == 1:
            return {k: v.copy() for k, v in self._frames[-1].items()}
        return {k: np.stack([f[k] for f in self._frames]) for k in self._empty}

    def zeros(self) -> dict[str, np.ndarray]:
        """The observation of an empty history (the state is not changed)."""
        if self.history == 1:
            return {k: v.copy() for k, v in self._empty.items()}
        return {k: np.stack([v] * self.history) for k, v in self._empty.items()}
