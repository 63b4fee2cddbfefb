"""``aas_gym/FillLevel-v0``: how full is the container, and with what?"""

from __future__ import annotations

import mujoco
import numpy as np
from gymnasium import spaces

from aas_gym import rest_states, scenario
from aas_gym.canonical_settle import from_canonical, to_canonical
from aas_gym.envs.base import AasEnv
from aas_gym.rest_states import settle_from
from sensors._infra.lru import CACHE_SIZES, LRU
from sensors.task import check_action, check_choice, check_integer, check_number

TASKS = ("fill", "liquid")
#: The everyday containers a liquid can fill (``sensors.fluid``).
CONTAINERS = ("mug", "glass", "can", "bottle")
#: Task ``"fill"`` succeeds when the estimate is within this of the true fill fraction
#: (5 percentage points of the container's height).
FILL_SUCCESS_TOLERANCE = 0.05
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


class FillLevelEnv(AasEnv):
    """A container holding a liquid is grasped and sensed; estimate its fill or its liquid.

    Each episode draws a container from ``objects`` (everyday containers: ``mug``,
    ``glass``, ``can``, ``bottle``, in any material), a fill fraction uniform in
    ``fill_range`` (task ``"fill"``; ``fill_fraction`` for task ``"liquid"``) and a liquid from
    ``liquids`` (``"water"``, ``"oil"``, ``"honey"``, ``"ethanol"`` or a density in kg/m^3).
    The container stands upright; the liquid's free surface is level. Its modes are the wet
    modes of ``sensors.fluid.filled`` (potential-flow added mass on the dry modes), and
    MuJoCo carries the liquid's mass at its centre of mass, so the grasp holds it. A container
    alone on the table starts from its rest with this liquid, interpolated between canonical
    rests settled once per 0.01 of fill and moved to its placement, and settles there until at
    rest (``aas_gym.rest_states``; a few MuJoCo steps instead of a 0.4 s settle). The hand
    grasps across the container (not pinching the wall: a finger in the liquid is not
    modelled) and records the excitation.

    Observation (Dict): proprioception, ``acoustic`` (140-d), ``waveform`` (optional).
    Action: Box(1) in [-1, 1]. Task ``"fill"``: the fill fraction estimate, -1 .. 1 mapped
    onto 0 .. 1; reward minus the absolute error. Task ``"liquid"``: the interval cut into
    ``len(liquids)`` equal bins, one per liquid; reward 1 if right, else 0. One step.
    ``info``: ``fill_fraction``, ``liquid``, ``liquid_index``, ``liquid_mass_kg``, ``liquid_model``
    (``"compressible"`` or ``"incompressible"``), label,
    grasp, padded contacts; the step adds ``estimate``, ``is_success`` (task ``"fill"``: the
    estimate within :data:`FILL_SUCCESS_TOLERANCE` of the true fraction; ``"liquid"``: the
    right liquid) and ``reward_terms`` (``error`` for task ``"fill"``, ``answer`` for
    ``"liquid"``).

    ``acoustic``: every episode records once, through its grasp, whatever the cadence (and not
    at all with ``enabled=False``: ``recording_grasped`` then says whether a grasp would be heard).

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `objects` | sequence of str or `ObjectSpec` | `("mug",)` | candidate containers (`mug`, `glass`, `can`, `bottle`, any material) |
    | `task` | str | `"fill"` | `"fill"`: estimate the fill fraction; `"liquid"`: name the liquid |
    | `liquids` | sequence of str or float | `("water",)` | candidate liquids (`"water"`, `"oil"`, `"honey"`, `"ethanol"` or a density [kg/m^3]) |
    | `fill_range` | (float, float) | (0.0, 0.9) | task `"fill"`: the fill fraction is drawn uniformly in it |
    | `fill_fraction` | float | 0.6 | task `"liquid"`: the fill fraction of every episode |
    | `compressible` | bool | True | the liquid compresses (its acoustic modes couple to the wall); False: incompressible added mass |
    | `interpolated_fill` | bool | True | wet modes from the container's fill table (milliseconds, within 0.1 % of the exact solve; `sensors.fluid.fill_table`); False: the exact solve of each fill |
    """

    _step_is_probe = True
    #: Every fill is a new liquid mass, so no settle is replayed: each stops once at rest.
    _settle_until_rest = True
    reset_options = ("object", "fill_fraction", "liquid_index")
    #: Grasp across the container, never a pinch of its wall.
    _min_grasp_width_m = 0.02

    def __init__(self, objects=("mug",), *, task: str = "fill", liquids=("water",),
                 fill_range: tuple[float, float] = (0.0, 0.9), fill_fraction: float = 0.6, compressible: bool = True,
                 interpolated_fill: bool = True, **kwargs) -> None:
        for flag, value in (("compressible", compressible), ("interpolated_fill", interpolated_fill)):
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{flag} must be True or False, got {value!r}")
        check_choice("task", task, TASKS)
        if isinstance(fill_range, (str, bytes)) or not hasattr(fill_range, "__len__") or len(fill_range) != 2:
            raise TypeError(f"fill_range must be a pair (low, high), got {fill_range!r}")
        lo, hi = (check_number("fill_range", v, 0.0, 1.0) for v in fill_range)
        fill_fraction = check_number("fill_fraction", fill_fraction, 0.0, 1.0)
        if isinstance(liquids, (str, bytes)) or not hasattr(liquids, "__iter__"):
            raise TypeError(f"liquids must be a sequence of liquid names or densities, e.g. ('water',), got {liquids!r}")
        super().__init__(objects, **kwargs)
        for obj in self.objects:
            if obj.shape not in CONTAINERS:
                raise ValueError(f"{obj.label} holds no liquid: FillLevel-v0 takes the containers {list(CONTAINERS)}")
        if not lo <= hi:
            raise ValueError(f"fill_range must satisfy 0 <= low <= high <= 1, got {fill_range}")
        from sensors.materials.liquids import get_liquid

        self.liquids = tuple(liquids)
        if not self.liquids:
            raise ValueError("liquids is empty")
        for liquid in self.liquids:
            if isinstance(liquid, bool):
                raise TypeError(f"liquids holds {liquid!r}: give liquid names or densities [kg/m^3]")
            get_liquid(liquid)  # an unknown name fails here, not at reset
        if task == "liquid" and len(self.liquids) < 2:
            raise ValueError("task 'liquid' needs at least two liquids to tell apart")
        self.task, self.fill_range, self.fill_fraction = task, (lo, hi), float(fill_fraction)
        self.reward_term_names = ("error",) if task == "fill" else ("answer",)
        self.compressible = bool(compressible)
        self.interpolated_fill = bool(interpolated_fill)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = spaces.Dict({**self._proprio_spaces(), **self._acoustic_spaces()})
        self._truth = {}
        self._dry_inertia: dict = {}
        self._containers = LRU(CACHE_SIZES["env.containers"])  # the target's Container, per ObjectSpec

    def reset(self, *, seed=None, options=None):
        """As every env (``options``: ``fill_fraction``, ``liquid_index``, ``object``)."""
        self._options = dict(options) if isinstance(options, dict) else {}
        return super().reset(seed=seed, options=options)

    def _place_objects(self, settle_s: float = 0.4) -> None:
        """Fill the container first, so the scene settles with this episode's liquid."""
        rng, options = self.np_random, getattr(self, "_options", {})
        lo, hi = self.fill_range
        fill = float(rng.uniform(lo, hi)) if self.task == "fill" else self.fill_fraction
        k = int(rng.integers(len(self.liquids))) if self.task == "liquid" else 0
        fill = check_number("fill_fraction", options.get("fill_fraction", fill), 0.0, 1.0)
        k = check_integer("liquid_index", options.get("liquid_index", k), 0, len(self.liquids) - 1)
        self._wet = self._fill(fill, self.liquids[k])
        self._truth = {"fill_fraction": fill, "liquid": str(self.liquids[k]), "liquid_index": k,
                       "liquid_mass_kg": float(self._wet.liquid.mass_kg), "liquid_model": self._wet.liquid_model}
        super()._place_objects(settle_s)

    def _settle_near_rest(self, settle_s: float) -> bool:
        """A lone container settles from its interpolated canonical rest (``aas_gym.rest_states``,
        with ``REST_STATES``): a few steps, not kept in the ``PhysicsMemo`` (a new fill each
        episode; an entry would cost more than the steps).  Not with ``interpolated_fill=False``:
        a grid fill would cost an exact wet solve (0.3-0.6 s)."""
        sc, m, d = self._scene, self.model, self.data
        if not rest_states.REST_STATES or len(sc.objects) != 1 or not self.interpolated_fill:
            return False
        placed = np.empty(mujoco.mj_stateSize(m, _STATE))
        mujoco.mj_getState(m, d, placed, _STATE)
        steps = self._settle_from_rest_state(settle_s)
        if steps < scenario.settle_steps(m, settle_s):
            return True
        mujoco.mj_setState(m, d, placed, _STATE)     # no rest (a rocking glass): the reference settles
        return False

    def _settle_from_rest_state(self, settle_s: float) -> int:
        sc, m, d = self._scene, self.model, self.data
        to_canonical(d, sc.free_joints, self._layout, sc.canonical_quat)
        start = np.empty(mujoco.mj_stateSize(m, _STATE))
        mujoco.mj_getState(m, d, start, _STATE)
        liquid, bid = self.liquids[self._truth["liquid_index"]], sc.body_ids[0]
        edited = []

        def set_fill(f: float) -> None:
            edited.append(f)
            self._set_liquid_mass(bid, self._wet_model(f, liquid).liquid)

        key = (str(liquid), self.compressible, self.interpolated_fill, m.actuator_forcerange.tobytes(),
               m.opt.timestep)
        dofs = np.concatenate([np.arange(v, v + 6) for _, v in sc.free_joints])
        rest = sc.rest.state(m, d, start, self._truth["fill_fraction"], key, set_fill, settle_s, dofs)
        if edited:                                   # a grid fill was settled: this episode's liquid back
            self._set_liquid_mass(bid, self._wet.liquid)
        if rest is None:                             # the reference does not end at rest: it settles
            return scenario.settle_steps(m, settle_s)
        mujoco.mj_setState(m, d, rest, _STATE)
        from_canonical(m, d, sc.free_joints, self._layout, forward=False)
        return settle_from(m, d, dofs, scenario.settle_steps(m, settle_s), rest_states.MIN_STEPS)

    def _reset_episode(self, options: dict):
        grasp = self._grasp(self._grasp_position(), self._episode_grip_force())
        # sensing off: no recording, and whether a grasp would be heard (AasEnv._sense_and_truth)
        acoustic, heard_grasped, truth = self._sense_and_truth()
        obs = self._proprio()
        obs.update(acoustic)
        info = truth
        info.update(grasp, **self._truth, recording_grasped=heard_grasped)
        return obs, info

    def _grasp_position(self) -> float:
        """A position along the container's grasp path, taken by a grasp across it."""
        from aas_gym.scenario import grasp_position

        return grasp_position(self.np_random, self._scene.objects[0], self._layout)

    def _wet_model(self, fill_fraction: float, liquid):
        """The target container's wet model with this liquid (``sensors.fluid.filled``)."""
        from sensors.fluid import container, filled

        target = self._scene.objects[0]
        # the memoized container itself (``sensors.fluid.container``): the same wet model as
        # ``filled(target.solid(), ...)``, without keying the solid's description every episode
        held = self._containers.get_or_build(target, lambda: container(target.solid()))
        return filled(held, fill_fraction, liquid=liquid, compressible=self.compressible,
                      interpolated=self.interpolated_fill)

    def _fill(self, fill_fraction: float, liquid):
        """Put the liquid in: the sensor hears the wet modes, MuJoCo carries its mass."""
        sc = self._scene
        wet = self._wet_model(fill_fraction, liquid)
        sc.sensor.set_modal_model(sc.bodies[0], wet)
        self._set_liquid_mass(sc.body_ids[0], wet.liquid)
        return wet

    def _set_liquid_mass(self, bid: int, liquid) -> None:
        """Body mass, centre of mass and inertia of container + liquid (restored from the dry
        values each episode); then MuJoCo's derived constants. Called before the placement's
        ``mj_resetData`` (it leaves the data's state undefined)."""
        m = self.model
        key = (id(m), bid)
        if key not in self._dry_inertia:
            self._dry_inertia[key] = (float(m.body_mass[bid]), m.body_ipos[bid].copy(), m.body_inertia[bid].copy(),
                                      m.body_iquat[bid].copy())
        mass0, com0, diag0, quat0 = self._dry_inertia[key]
        rot0 = np.zeros(9)
        mujoco.mju_quat2Mat(rot0, quat0)
        rot0 = rot0.reshape(3, 3)
        inertia0 = rot0 @ np.diag(diag0) @ rot0.T
        m1, com1 = float(liquid.mass_kg), np.asarray(liquid.centre_of_mass_m, float)
        total = mass0 + m1
        com = (mass0 * com0 + m1 * com1) / total

        def shifted(inertia, mass, c):  # parallel-axis theorem to the common centre of mass
            d = c - com
            return inertia + mass * (d @ d * np.eye(3) - np.outer(d, d))

        inertia = shifted(inertia0, mass0, com0) + shifted(np.asarray(liquid.inertia_kg_m2, float), m1, com1)
        values, vectors = np.linalg.eigh(inertia)
        if np.linalg.det(vectors) < 0:
            vectors[:, 0] *= -1
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, vectors.ravel())
        m.body_mass[bid], m.body_ipos[bid], m.body_inertia[bid], m.body_iquat[bid] = total, com, values, quat
        # masses the solver's scaling derives from; it uses the data as scratch, which the reset
        # that follows (``AasEnv._place_objects``: ``mj_resetData``) rewrites
        mujoco.mj_setConst(m, self.data)

    def estimate_from_action(self, action):
        """The fill fraction (task ``"fill"``) or liquid index (task ``"liquid"``) an action stands for."""
        a = float(np.clip(check_action(action, (1,))[0], -1.0, 1.0))
        if self.task == "fill":
            return (a + 1.0) / 2.0
        return min(len(self.liquids) - 1, int((a + 1.0) / 2.0 * len(self.liquids)))

    def step(self, action):
        estimate = self.estimate_from_action(action)
        obs = self._proprio()
        obs.update(self._empty_acoustic())
        info = dict(self._truth, estimate=estimate, label=self._scene.objects[0].label)
        if self.task == "fill":
            error = abs(estimate - self._truth["fill_fraction"])
            info["abs_error"] = error
            info["is_success"] = bool(error <= FILL_SUCCESS_TOLERANCE)
            info["reward_terms"] = {"error": -error}
            return obs, -error, True, False, info
        correct = estimate == self._truth["liquid_index"]
        info["is_success"] = bool(correct)
        info["reward_terms"] = {"answer": 1.0 if correct else 0.0}
        return obs, 1.0 if correct else 0.0, True, False, info
