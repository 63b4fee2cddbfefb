"""Sections of physics replayed from a cache: a reset does only what differs.

MuJoCo's step is a deterministic function of the model and the integration state
(``mj_getState(..., mjSTATE_INTEGRATION)``: time, positions, velocities, activations, warm
start, controls, applied forces, mocap, equality flags, user data).  A deterministic section
of physics (letting a placed scene settle, a scripted grasp) started from the same state of the
same model with the same arguments therefore ends in the same ``MjData``, bit for bit.
:class:`PhysicsMemo` keys each run by that state, the parts of the model the envs edit at run
time (:data:`EDITED_MODEL_FIELDS`: the gripper's force range, i.e. the grip force, and the
bodies' inertial properties a filled container changes) and the section's arguments, and
keeps the whole
``MjData`` it ended in (``mj_copyData``: the derived quantities a step leaves, contacts and
constraint forces included, are those of the run, not recomputed), about 0.5 MB each.
"""

from __future__ import annotations

from typing import Any, Callable, Hashable

import mujoco
import numpy as np

from sensors._infra.lru import CACHE_SIZES, LRU

__all__ = ["EDITED_MODEL_FIELDS", "PhysicsMemo"]

_STATE = mujoco.mjtState.mjSTATE_INTEGRATION

#: The model arrays the envs change between runs (``Hand.set_grip_force``; ``FillLevel-v0``'s
#: liquid mass, then ``mj_setConst``, whose derived constants follow from these): part of the
#: key, and restored on a hit. An env that edits another model field must add it here.
EDITED_MODEL_FIELDS = ("actuator_forcerange", "body_mass", "body_ipos", "body_inertia", "body_iquat")


class PhysicsMemo:
    """Runs of deterministic physics sections on one model, by start state and arguments.

    ``run(data, args, section)`` returns ``section()``'s result and leaves ``data`` as the
    section leaves it: computed on a miss, copied from the cache on a hit.  ``section`` must
    depend only on ``data``'s integration state, the model (whose :data:`EDITED_MODEL_FIELDS`
    are part of the key and restored) and ``args`` (hashable).  ``max_size`` defaults to
    ``CACHE_SIZES["env.physics_runs"]``; ``hits``/``misses`` say how well it works.
    """

    def __init__(self, model: mujoco.MjModel, max_size: int | None = None) -> None:
        self.model = model
        self._lru: LRU = LRU(CACHE_SIZES["env.physics_runs"] if max_size is None else int(max_size))
        self._state = np.empty(mujoco.mj_stateSize(model, _STATE))

    @property
    def hits(self) -> int:
        return self._lru.hits

    @property
    def misses(self) -> int:
        return self._lru.misses

    def __len__(self) -> int:
        return len(self._lru)

    def clear(self) -> None:
        self._lru.clear()

    def key(self, data: mujoco.MjData, args: Hashable) -> tuple:
        """What determines a section's run: start state, the model's force range, ``args``."""
        mujoco.mj_getState(self.model, data, self._state, _STATE)
        edited = b"".join(getattr(self.model, f).tobytes() for f in EDITED_MODEL_FIELDS)
        return (self._state.tobytes(), edited, args)

    def run(self, data: mujoco.MjData, args: Hashable, section: Callable[[], Any]) -> Any:
        key = self.key(data, args)
        hit = self._lru.get(key)
        if hit is not None:
            end, edited, result = hit
            mujoco.mj_copyData(data, self.model, end)
            for f, value in zip(EDITED_MODEL_FIELDS, edited):
                getattr(self.model, f)[:] = value
            return result
        result = section()
        if len(self._lru) >= self._lru.max_size:   # the oldest run is dropped below: reuse its MjData
            end = next(iter(self._lru.values()))[0]
        else:
            end = mujoco.MjData(self.model)
        mujoco.mj_copyData(end, self.model, data)
        self._lru.put(key, (end, tuple(getattr(self.model, f).copy() for f in EDITED_MODEL_FIELDS), result))
        return result
