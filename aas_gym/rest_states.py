"""Settling a filled container from its predicted rest, not from its placement.

A container alone on the table (the hand far above) comes to the same rest wherever it is placed
and however turned (a rigid motion of the table plane, ``aas_gym.canonical_settle``: the moved
canonical settle equals the placed one to 1e-15 m).  What differs between FillLevel-v0's episodes
is the liquid: its mass, centre of mass and inertia move the rest by a few nm (sinking
4.45-4.53e-7 m into the table, tilting 0.8-1.1 urad towards the handle from empty to full).
That rest is smooth in the fill fraction, so :class:`RestStates` settles the canonical placement
once per grid fill (``GRID_FILL`` apart, the whole settle the reference runs), interpolates the
integration state (poses, velocities, warm start) linearly between the two grid fills around
this episode's, moves it to the placement and lets it settle in place until at rest
(``aas_gym.scenario.REST_SPEED``): a few steps where the reference runs the whole settle
(0.4 s, 200 steps) and then the first release (30 steps).

Not bit for bit: the rest it ends in is the reference's within the rest test's own tolerance
(the container trembles at 1e-11-1e-9 m/s once at rest; the poses agree to about 1e-11 m, as
``aas_gym.scenario.settle(..., until_rest=True)``'s do), and FillLevel-v0's features, which
follow the table contacts' forces at that scale, within the bound ``tests/test_rest_states.py``
states beside the reference's own sensitivity.  :data:`REST_STATES` ``= False`` is the reference.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np

from aas_gym.scenario import REST_SPEED, settle_steps
from sensors._infra.lru import CACHE_SIZES, LRU

__all__ = ["GRID_FILL", "REST_STATES", "RestStates"]

#: Whether FillLevel-v0 settles a lone container from its interpolated rest (True, the default)
#: or as the reference (False: the whole settle, or ``SETTLE_UNTIL_REST``'s early stop).  Not bit
#: for bit (module docstring), and on by default: a FillLevel-v0 episode simulates a container at
#: rest, then grasped.  The reference's 0.4 s is a duration, not a better rest: settled 10 ms
#: longer it moves the features as much as this path does (``tests/test_rest_states.py``), and
#: it costs 230 of an episode's 268 MuJoCo steps.  Read at each call.
REST_STATES = True
#: Spacing of the grid fills [fill fraction] whose rests are settled and interpolated.
GRID_FILL = 0.01
#: The least steps in place before the rest test.
MIN_STEPS = 1
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


class RestStates:
    """Canonical rest states of one scene's lone target per grid fill, interpolated.

    ``state(model, data, start, fill, set_fill, settle_s)``: the integration state at rest of
    the canonical start state ``start`` (``mj_getState``) settled ``settle_s`` with the liquid of
    ``fill``; ``set_fill(f)`` puts the liquid of fill ``f`` into the model (and restores nothing:
    the caller sets this episode's fill again after)."""

    def __init__(self) -> None:
        self._runs: LRU = LRU(CACHE_SIZES["env.rest_states"])

    def __len__(self) -> int:
        return len(self._runs)

    def _grid_state(self, model, data, start: np.ndarray, key, f: float, set_fill: Callable[[float], None],
                    settle_s: float) -> np.ndarray:
        def run() -> np.ndarray:
            set_fill(f)
            mujoco.mj_setState(model, data, start, _STATE)
            mujoco.mj_step(model, data, nstep=settle_steps(model, settle_s))
            end = np.empty(start.size)
            mujoco.mj_getState(model, data, end, _STATE)
            return end

        return self._runs.get_or_build((start.tobytes(), key, round(f, 12), settle_s), run)

    def state(self, model: mujoco.MjModel, data: mujoco.MjData, start: np.ndarray, fill: float, key,
              set_fill: Callable[[float], None], settle_s: float, free_dofs: np.ndarray) -> np.ndarray | None:
        """The interpolated canonical rest (see the class); ``key`` names what else the liquid
        depends on (liquid, compressibility).  None if a grid fill's settle did not end at rest
        (``free_dofs`` faster than ``REST_SPEED``: a glass rocks again after resting at 0.1 s),
        where the reference's state is not a rest.  Leaves ``data`` and the model's liquid undefined."""
        lo = min(math.floor(fill / GRID_FILL), max(0, math.ceil(1.0 / GRID_FILL) - 1))
        f0, f1 = lo * GRID_FILL, min(1.0, (lo + 1) * GRID_FILL)
        s0 = self._grid_state(model, data, start, key, f0, set_fill, settle_s)
        s1 = self._grid_state(model, data, start, key, f1, set_fill, settle_s)
        qvel = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME) + model.nq + free_dofs
        if max(np.abs(s0[qvel]).max(initial=0.0), np.abs(s1[qvel]).max(initial=0.0)) >= REST_SPEED:
            return None
        w = (fill - f0) / (f1 - f0)
        return (1.0 - w) * s0 + w * s1


def settle_from(model: mujoco.MjModel, data: mujoco.MjData, free_dofs: np.ndarray, max_steps: int,
                min_steps: int = 1) -> int:
    """Step from a near-rest state until no free dof moves faster than ``REST_SPEED`` (after at
    least ``min_steps``, tested every step), at most ``max_steps``; returns the steps run."""
    done = 0
    while done < max_steps:
        mujoco.mj_step(model, data)
        done += 1
        if done >= min_steps and np.abs(data.qvel[free_dofs]).max(initial=0.0) < REST_SPEED:
            break
    return done
