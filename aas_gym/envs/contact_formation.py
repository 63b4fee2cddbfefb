"""``aas_gym/ContactFormation-v0``: which external contact does the held object have now?

The paper's fifth capability. The hand holds an object and a scripted motion moves it:
resting on the table, pressed on it or slid along it, lifted off into the air, carried over
to another object and set down on it, slid along that one, lifted again, at random times.
The agent hears the object continuously (the streaming microphone) and reports, each step,
which contact formation holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from aas_gym.contacts import KINDS
from aas_gym.envs.base import AasEnv
from aas_gym.grasp import planar_grasp
from aas_gym.scenario import place_beside, settle
from sensors import ContactTolerance
from sensors.objects.catalog import ObjectSpec
from aas_gym.envs.base import object_list
from sensors.task import HOME_TCP, MAX_OPENING_M, check_action

# Where the table's and the other object's forces sit in ContactStream.normal_force_totals_n.
_ENVIRONMENT, _OBJECT = KINDS.index("environment"), KINDS.index("object")
#: The classes, in action order: held in the air, touching the table, touching the other object.
FORMATIONS = ("free", "table", "object")
#: A contact counts for the ground truth above this normal force [N] (MuJoCo's resting
#: contacts carry far more; grazing ones during a transition less).
TRUTH_FORCE_N = 0.2
#: Spread of the grasp height on the object [m].
GRASP_HEIGHT_M = 0.003
#: Fastest scripted TCP motion per env step [m] (0.16 m/s at 20 Hz).
MAX_STEP_M = 0.008
#: Contacts of a moving object change force at every step; within 10 % (0.2 N) of the
#: contact set a system was built for, it is reused: contact-damped decay rates within 10 %
#: (the randomized damping spans +-5 %), a third of the system builds of the defaults
#: (``docs/benchmarks/streaming_env.md``).
MOVING_TOLERANCE = ContactTolerance(force_rtol=0.1, force_atol_n=0.2)


@dataclass(frozen=True)
class _Segment:
    """One stretch of the script: move towards ``offset`` (x, y, z from the grasp pose on the
    table [m]) and hold it for ``steps`` env steps in all."""

    kind: str
    offset: tuple[float, float, float]
    steps: int


# What may follow where the target rests, and how likely (the plinth is visited often).
_NEXT = {"table": (("rest_table", "slide_table", "lift"), (0.25, 0.25, 0.5)),
         "plinth": (("rest_object", "slide_object", "lift"), (0.3, 0.3, 0.4)),
         "air": (("set_down_table", "set_down_object", "hover"), (0.35, 0.45, 0.2))}


def offset_z(script: list[_Segment]) -> float:
    """Height of the latest waypoint of a script (0: the grasp pose on the table)."""
    return script[-1].offset[2] if script else 0.0


class ContactFormationEnv(AasEnv):
    """Report the contact formation of a held, moving object from sound and proprioception.

    Each episode places the target and one other object (the plinth, from ``plinths``) side
    by side on the table, grasps the target and plays a random script: rest or press on the
    table, slide along it, lift off (1-10 mm: touching or not is a fine call), carry over the
    plinth, set down or press on it, slide along it, lift again; each segment lasts 0.25-0.7 s
    and the hand moves at up to 0.16 m/s. The grasp height on the target varies by +-3 mm, so
    proprioception alone does not place the object's bottom to the millimetre.

    Action (Discrete(3)): the reported formation, ``FORMATIONS`` = free / table / object.
    Observation (Dict): proprioception (``tcp``, ``tcp_velocity``, ``gripper``), ``acoustic``
    (140-d features of the latest complete excitation period, scaled per
    ``acoustic.feature_scale``, zeros during the first period) and ``audio`` (the samples of
    this step); by default the microphone streams (``acoustic.cadence="stream"``). With
    ``acoustic={"enabled": False}`` the observation is proprioception only.
    Reward (``info["reward_terms"]``: ``report``): 1 when the report matches the formation
    after the step, else 0.
    ``info``: ``formation`` / ``formation_index`` (ground truth from the contact forces of
    the target: table, plinth, or neither), ``segment`` (the script's current kind), the
    external forces ``table_force_n`` and ``object_force_n``, ``grasped``, ``label``;
    ``is_success``: this step's report is right (the episode never ends by itself).

    ``scene`` is not accepted (the env builds its own). ``acoustic`` defaults here:
    ``cadence="stream"``, ``feature_scale="db"``, ``stream_tolerance=MOVING_TOLERANCE``.

    ## Arguments

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | `objects` | sequence of str or `ObjectSpec` | `("aluminium_bar", "steel_bar", "wood_bar")` | candidate held objects, one drawn per episode |
    | `plinths` | sequence of str or `ObjectSpec` | `("aluminium_bar", "steel_bar", "wood_bar")` | the other object beside it, drawn among those that are not the target |
    """

    _acoustic_defaults = {"cadence": "stream", "feature_scale": "db", "stream_tolerance": MOVING_TOLERANCE}
    reward_term_names = ("report",)

    def __init__(self, objects=("aluminium_bar", "steel_bar", "wood_bar"), *,
                 plinths=("aluminium_bar", "steel_bar", "wood_bar"), **kwargs) -> None:
        if "scene" in kwargs:
            raise ValueError("ContactFormation-v0 builds its own scene (target beside a plinth); drop scene=")
        super().__init__(objects, scene="multi", distractors=object_list("plinths", plinths), **kwargs)
        self.action_space = spaces.Discrete(len(FORMATIONS))
        self.observation_space = spaces.Dict({**self._proprio_spaces(), **self._acoustic_spaces()})

    # --- episode ------------------------------------------------------------------------------
    def _choose_objects(self, target: ObjectSpec) -> tuple[ObjectSpec, ...]:
        others = [o for o in self.distractors if o != target] or list(self.distractors)
        return (target, others[int(self.np_random.integers(len(others)))])

    def _place_objects(self, settle_s: float = 0.4) -> None:
        import mujoco

        sc, m, d = self._scene, self._scene.model, self._scene.data
        mujoco.mj_resetData(m, d)
        sc.hand.set_grip_force(self.grip_force_n)
        sc.hand.teleport(d, HOME_TCP, MAX_OPENING_M)
        self._layout = place_beside(d, sc.objects, sc.free_joints, self.np_random, self.randomization)
        settle(m, d, settle_s)

    def _reset_episode(self, options: dict):
        sc = self._scene
        grip = self._episode_grip_force()
        # Grasp the target near its centre, resting on the table (retry if the pads slip off).
        # The height of the grasp on the object varies by +-3 mm, so the TCP height alone
        # does not say where the object's bottom is to the millimetre.
        for _ in range(3):
            position = float(self.np_random.uniform(-0.02, 0.02))
            height = float(self.np_random.uniform(-GRASP_HEIGHT_M, GRASP_HEIGHT_M))
            result = planar_grasp(sc.model, sc.data, sc.bodies[0], position, grip, height_offset_m=height,
                                  hand=sc.hand, stream=sc.stream)
            if result.success:
                break
        self._home = sc.hand.tcp(sc.data).copy()
        self._target = self._home.copy()
        plinth = sc.objects[1]
        dy = float(sc.xpos[sc.body_ids[1]][1] - sc.xpos[sc.body_ids[0]][1])
        self._plinth_offset = (dy, 2 * float(plinth.half_extents_m[2]))
        self._script = self._draw_script()
        self._segment, self._left = 0, self._script[0].steps
        self._goal = self._waypoint(0)
        if self._stream is not None:
            # a new stream: the grasp just closed (the planar grasp was not recorded)
            self._stream = self._new_stream()
        self._last_acoustic = self._empty_acoustic()
        obs = self._obs()
        info = self._ground_truth(contacts=False)
        info.update(self._truth(), grasp_success=bool(result.success), grasp_position_m=position,
                    segment=self._script[0].kind)
        return obs, info

    def _draw_script(self, max_steps: int = 400) -> list[_Segment]:
        """A random walk over segments, each 5-14 steps, until ``max_steps`` are covered."""
        rng = self.np_random
        dy, top = self._plinth_offset
        script, total, where = [], 0, "table"    # where the target rests: table / air / plinth
        x = 0.0
        while total < max_steps:
            steps = int(rng.integers(5, 15))
            press = float(rng.uniform(0.001, 0.004))
            kinds, weights = _NEXT[where]
            kind = kinds[int(rng.choice(len(kinds), p=weights))]
            y = dy if where == "plinth" else 0.0
            if kind in ("rest_table", "rest_object"):
                offset = (x, y, (top if where == "plinth" else 0.0) - press)
            elif kind in ("slide_table", "slide_object"):
                x = float(np.clip(x + rng.choice([-1, 1]) * rng.uniform(0.01, 0.03), -0.03, 0.03))
                offset = (x, y, (top if where == "plinth" else 0.0) - press)
            elif kind in ("lift", "hover"):
                # close above the surface it left (1-10 mm): touching or not is a fine call
                base = top if where == "plinth" else 0.0
                offset = (x, y, max(base, offset_z(script)) + float(rng.uniform(0.001, 0.01)))
                where = "air"
            elif kind == "set_down_table":
                offset, where = (x, 0.0, -press), "table"
            else:
                offset, where = (x, dy, top - press), "plinth"
            if kind.startswith("set_down"):
                # carry over at height first, then lower: two segments
                script.append(_Segment("carry", (x, offset[1], top + 0.02), int(rng.integers(8, 14))))
                total += script[-1].steps
            script.append(_Segment(kind, offset, steps))
            total += steps
        return script

    # --- step ---------------------------------------------------------------------------------
    def step(self, action):
        # a Discrete sample (int or numpy integer) is already a finite scalar
        report = int(action) if isinstance(action, (int, np.integer)) else int(check_action(action, ()))
        if not 0 <= report < len(FORMATIONS):
            raise ValueError(f"action must be a formation index in [0, {len(FORMATIONS)}), got {report}")
        self._advance_script()
        self._simulate()
        due = self._acoustic_due()  # acoustic.update_period_s
        if self._stream is not None and due:
            self._last_acoustic = self._stream_entries()
        truth = self._truth()
        reward = 1.0 if report == truth["formation_index"] else 0.0
        info = dict(truth, is_success=bool(reward > 0), label=self._scene.objects[0].label,
                    segment=self._script[self._segment].kind, grasped=bool(self._is_grasped()), report=report,
                    reward_terms={"report": reward})
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, False, False, info

    def _advance_script(self) -> None:
        """Move the TCP command one rate-limited step towards the segment's waypoint."""
        if self._left <= 0 and self._segment + 1 < len(self._script):
            self._segment += 1
            self._left = self._script[self._segment].steps
            self._goal = self._waypoint(self._segment)
        self._left -= 1
        delta = self._goal - self._target[:3]
        dist = math.sqrt(delta.dot(delta))  # what np.linalg.norm computes, without its overhead
        if dist > MAX_STEP_M:
            delta *= MAX_STEP_M / dist
        self._target[:3] += delta
        sc = self._scene
        sc.set_tcp_target(self._target)

    def _waypoint(self, segment: int) -> np.ndarray:
        """The TCP position [m] segment ``segment`` moves towards."""
        return self._home[:3] + np.asarray(self._script[segment].offset)

    def _truth(self) -> dict:
        """The formation from the target's external contact forces after the step."""
        totals = self._scene.stream.normal_force_totals_n(self.data, self._scene.bodies[0])
        table, other = float(totals[_ENVIRONMENT]), float(totals[_OBJECT])
        k = 2 if other > TRUTH_FORCE_N else (1 if table > TRUTH_FORCE_N else 0)
        return {"formation": FORMATIONS[k], "formation_index": k, "table_force_n": float(table),
                "object_force_n": float(other)}

    def _obs(self) -> dict:
        obs = self._proprio()
        for key, value in self._last_acoustic.items():
            obs[key] = value.copy()
        return obs
