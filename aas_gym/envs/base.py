"""Shared machinery of the aas_gym environments: scenes per object set (built lazily and
cached), object placement with random contacts, proprioception, sensing, rendering.

Follows Gymnasium's MuJoCo-env conventions (``frame_skip``, ``dt``, ``render_mode`` in
``human`` / ``rgb_array`` / ``depth_array``, ``width``/``height``/``camera_name``, renderer
created on first ``render``) without depending on ``gymnasium.envs.mujoco`` (it needs
imageio). All randomness comes from ``self.np_random``.
"""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import mujoco
import numpy as np

from aas_gym import has_display
from aas_gym.canonical_settle import canonical_quat, run_after_settle, settle_placed
from aas_gym.contacts import ContactStream
from aas_gym import grasp as grasp_module
from aas_gym.grasp import DEFAULT_GRIP_FORCE_N, Hand, planar_grasp, release
from aas_gym.robots import DEFAULT_ROBOT, check_robot, robot_controller
from aas_gym.contact_sensors import touch_sensor_name
from aas_gym.envs.info import contacts_info
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from aas_gym import scenario
from aas_gym.physics_memo import PhysicsMemo
from aas_gym.rest_states import RestStates
from aas_gym.scene import build_scene
from aas_gym.scenario import (DomainRandomization, choose_objects, default_distractors, place_objects, settle,
                              target_grasp)
from aas_gym.sim_sensor import SensorVariation, SimAcousticSensor
from aas_gym.sim_stream import SimAcousticStream
from sensors import LeakRecording, load_leak
from sensors._infra.deprecation import warn_deprecated
from sensors._infra.lru import CACHE_SIZES, LRU
from sensors.objects.catalog import ObjectSpec, get_object
from sensors.task import (HOME_TCP, LEGACY_KEYWORDS, MAX_GRIP_FORCE_N, MAX_OPENING_M, N_FEATURES, STATE_LAYOUT,
                          STATE_SIZE, AcousticConfig, AcousticEnvMixin, check_choice, check_grip_force, check_integer,
                          proprio_spaces)

__all__ = ["AasEnv", "DomainRandomization", "EXCITATION_NAMES", "HOME_TCP", "MAX_FRAME_SKIP", "N_FEATURES",
           "object_list"]

#: Default of ``AasEnv.max_frame_skip``: 5000 MuJoCo steps of 2 ms, 10 s of physics per env
#: step (a step's cost grows with it; the default 25 is 50 ms).
MAX_FRAME_SKIP = 5000

EXCITATION_NAMES = ("impulse", "linear", "exponential")
#: The scene's cameras (``aas_gym.stage``).
CAMERA_NAMES = ("closeup", "overview", "workspace")
#: ``metadata["render_fps"]`` of the probe envs: a viewing rate for frames that are one probe
#: each (Gymnasium's turn-based toy_text envs use 4), not a physical rate.
PROBE_RENDER_FPS = 4
# Where the proprioceptive entries sit in the state vector (sensors.task.grasp.STATE_LAYOUT),
# as plain ints for the per-step code.
_TCP = STATE_LAYOUT["tcp"].start
_TCP_VELOCITY = STATE_LAYOUT["tcp_velocity"].start
_OBJECT = STATE_LAYOUT["object"].start
_MOTOR_FORCE = STATE_LAYOUT["gripper"].stop - 1


_LAYOUT_ITEMS = tuple(STATE_LAYOUT.items())

#: Whether an env whose reset grasps right after the canonical settle (``_grasp_follows_placement``:
#: GraspPosition-v0) leaves out the settle's closing ``mj_forward``: the grasp's first release
#: replays from the settle's start state (``run_after_settle``: ``mj_setState``, then the run's
#: whole ``MjData`` copied or stepped), so nothing reads the poses it computed; a grasp that does
#: not replay runs it first.  False: the forward where the settle ends (the reference;
#: ``tests/test_episode_glue.py``).  Read at each reset.
LAZY_PLACEMENT_FORWARD = True


#: The attributes of a ``_Scene`` that are views into its MjData.
_DATA_VIEWS = ("sensordata", "qpos", "qvel", "ctrl", "actuator_force", "xpos", "site_xpos")


class _Scene:
    """One compiled scene (model, data, hand, sensor) for a tuple of objects, held by
    ``robot`` (``aas_gym.robots``; ``hand`` is its controller)."""

    def __init__(self, objects: tuple[ObjectSpec, ...], contact_signature: bool = False,
                 robot: str = DEFAULT_ROBOT):
        self.objects = objects
        self.model = build_scene(list(objects), contact_signature=contact_signature, robot=robot)
        self.data = mujoco.MjData(self.model)
        self.hand = robot_controller(self.model)
        # The floating hand's TCP is its carriage's joints and servo targets; an arm's is
        # computed from its tcp site and commanded through its controller (inverse kinematics).
        self.carriage = type(self.hand) is Hand
        # settled placements and grasps by start state (a reset redoes only what differs)
        self.memo = PhysicsMemo(self.model)
        self.rest = RestStates()       # a lone target's canonical rests per fill (aas_gym.rest_states)
        self.canonical_quat = canonical_quat(objects[0])   # the target's at yaw 0 (canonical_settle)
        self.sensor = SimAcousticSensor(self.model, self.data, on_no_grasp="silence")
        self.bodies = self.sensor.bodies
        self.stream: ContactStream = self.sensor.stream
        self.body_ids = [mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.bodies]
        self.free_qpos = [int(self.model.jnt_qposadr[self.model.body_jntadr[b]]) for b in self.body_ids]
        self.free_qvel = [int(self.model.jnt_dofadr[self.model.body_jntadr[b]]) for b in self.body_ids]
        self.free_joints = list(zip(self.free_qpos, self.free_qvel))
        # Contact-count sensors of the target with each fingertip: build_scene adds them to
        # every object, so the per-step grasp test is two reads of sensordata.
        self.touch_adr = tuple(
            int(self.model.sensor_adr[mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SENSOR,
                                                         touch_sensor_name(self.bodies[0], side))])
            for side in ("actuator", "mic"))
        self._bind_views()
        self.tcp_ctrl = None if not self.carriage else \
            slice(int(self.hand.tcp_actuators[0]), int(self.hand.tcp_actuators[0]) + 4) \
            if np.array_equal(self.hand.tcp_actuators, np.arange(self.hand.tcp_actuators[0], self.hand.tcp_actuators[0] + 4)) \
            else self.hand.tcp_actuators
        self.gripper = int(self.hand.gripper_actuator)
        self.tcp_low, self.tcp_high = self.hand.tcp_low.tolist(), self.hand.tcp_high.tolist()
        self.target_body = int(self.body_ids[0])
        self.tcp_site = int(self.hand.tcp_site)
        # Observation as one linear map of the physics state [qpos, qvel] (a single BLAS call
        # per step instead of a dozen small array operations): rows = TCP x, y, z, yaw (the
        # carriage joints are the TCP coordinates), their velocities, gripper opening and
        # opening speed (sums of the finger joints), a placeholder for the motor force, then
        # the target's free-joint position and quaternion (= its body pose).
        nq, nv = self.model.nq, self.model.nv
        obs_map = np.zeros((STATE_SIZE, nq + nv))
        tcp, vel, grip, obj = (STATE_LAYOUT[k] for k in ("tcp", "tcp_velocity", "gripper", "object"))
        for row, (qa, va) in enumerate(zip(self.hand.tcp_qpos, self.hand.tcp_qvel) if self.carriage else ()):
            obs_map[tcp.start + row, qa] = 1.0
            obs_map[vel.start + row, nq + va] = 1.0
        obs_map[grip.start, self.hand.finger_qpos] = 1.0
        obs_map[grip.start + 1, nq + self.hand.finger_qvel] = 1.0
        obs_map[np.arange(obj.start, obj.stop), np.arange(self.free_qpos[0], self.free_qpos[0] + 7)] = 1.0
        self.obs_map = obs_map
        self.state = np.empty(nq + nv)

    def _bind_views(self) -> None:
        """Views into the MjData arrays (their memory never moves): saves the per-access view
        creation of the mujoco bindings in the per-step code."""
        d = self.data
        self.sensordata = d.sensordata
        self.qpos, self.qvel, self.ctrl = d.qpos, d.qvel, d.ctrl
        self.actuator_force, self.xpos, self.site_xpos = d.actuator_force, d.xpos, d.site_xpos

    def __getstate__(self) -> dict:
        # copy.deepcopy and pickle would turn the views into arrays detached from the copied
        # MjData (a copied env's controls would never reach its physics): rebound on restore.
        return {k: v for k, v in self.__dict__.items() if k not in _DATA_VIEWS}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._bind_views()

    def tcp_target(self) -> list[float]:
        """The commanded TCP (x, y, z [m], yaw [rad])."""
        if self.carriage:
            return self.ctrl[self.tcp_ctrl].tolist()
        return self.hand.tcp_target(self.data).tolist()

    def set_tcp_target(self, tcp) -> None:
        """Command the TCP (x, y, z [m], yaw [rad]): the carriage's servo targets, or the
        arm's joint targets by inverse kinematics (``UnreachableError`` if it cannot)."""
        if self.carriage:
            self.ctrl[self.tcp_ctrl] = tcp
        else:
            self.hand.command(self.data, tcp=tcp)


#: The rows every env's argument table ends with (appended to each env's docstring).
COMMON_ARGUMENTS = """
    | `scene` | str | `"single"` | `"single"`: the target alone on the table; `"multi"`: one or two `distractors` lean across its ends (random object contacts) |
    | `distractors` | sequence of str or `ObjectSpec`, or None | None | objects that may lean on the target; None: the bars of the default objects |
    | `acoustic` | `sensors.task.AcousticConfig`, dict of its fields, or None | None | the acoustic sensor: `excitation`, `cadence`, `duration_s`, `waveform`, `feature_scale`, `noise_std`, `leak`, `fingertip`, `stream_tolerance`, `drive` (`"bandlimited"` or the former `"foh"`), `passive_sound` (impacts and slides heard; default on when streaming), `enabled`, `features` (`"fft140"`, `"spectrogram"`, `"mel"`), `history`, `update_period_s`, `corruption`, `max_samples` (the longest recording or streamed step, default 60 s at 44.1 kHz); None or missing fields: this env's defaults |
    | `robot` | str | `"floating_hand"` | `"floating_hand"`: the Franka hand on a Cartesian carriage (fast); `"panda"`: the Franka Panda arm with the same hand (needs `gymnasium-robotics` for its meshes), Cartesian TCP actions through inverse kinematics |
    | `grip_force_n` | float | 40.0 | nominal grip force [N], in (0, 140] |
    | `randomization` | `DomainRandomization`, dict of its knobs, None or False | None | domain randomization; None: its defaults; False: none |
    | `frame_skip` | int | 25 | MuJoCo steps (2 ms) per env step, 1 to `AasEnv.max_frame_skip` (5000) |
    | `render_mode` | str or None | None | `"rgb_array"`, `"depth_array"` or `"human"` |
    | `width`, `height` | int | 480, 480 | rendered image size [pixels], at most the scene's offscreen buffer (640 x 480) |
    | `camera_name` | str or None | None | `"closeup"` (the fingertips and the grasped part), `"overview"` or `"workspace"` (the hand at home above the object); None: this env's default (`"workspace"` for AcousticGrasp-v0, else `"closeup"`) |

    Deprecated (one more release, with a `DeprecationWarning`): the keywords `excitation`,
    `duration_s`, `include_waveform`, `sense_mode`, `leak`, `fingertip`, `stream_tolerance`
    beside `acoustic=`; write `acoustic={"excitation": ..., "waveform": ..., "cadence": ...}`.
"""


def object_list(name: str, value) -> list[ObjectSpec]:
    """Objects from a sequence of names or specs: a bare string (its letters would be read
    as names) and an empty sequence are refused."""
    if isinstance(value, (str, bytes, ObjectSpec)) or not isinstance(value, Sequence):
        raise TypeError(f"{name} must be a sequence of object names or ObjectSpecs, e.g. ('wood_bar',), "
                        f"got {value!r}")
    if not value:
        raise ValueError(f"{name} must name at least one object")
    return [get_object(o) for o in value]


def _load_leaks(leak):
    """Leak recordings loaded at construction, so a missing or foreign file fails at
    ``gym.make`` naming the file, not at the first reset inside numpy."""
    if leak is None or isinstance(leak, LeakRecording):
        return leak
    if isinstance(leak, dict):
        return {k: _load_leaks(v) for k, v in leak.items()}
    try:
        return load_leak(leak)
    except FileNotFoundError:
        raise FileNotFoundError(f"leak file {leak!s} does not exist: record one with `aas real leak` "
                                "or leave acoustic.leak None") from None


class AasEnv(AcousticEnvMixin, gym.Env):
    """Base class: not registered. Subclasses define spaces, ``reset`` and ``step``; their
    docstrings carry a table of their own arguments, to which :data:`COMMON_ARGUMENTS`
    (``scene``, ``distractors``, ``acoustic``, ``grip_force_n``, ``randomization``,
    ``frame_skip``, ``render_mode``, ``width``, ``height``, ``camera_name``) is appended.

    ``frame_skip``, ``dt``, ``render_mode``, ``width``/``height``/``camera_name`` follow
    Gymnasium's MuJoCo envs; the probe envs (a step is a scripted grasp and recording, or an
    answer) have no ``dt`` and render at :data:`PROBE_RENDER_FPS`, as Gymnasium's turn-based
    envs. Every step's ``info`` holds ``is_success``, the ground truth the task is scored
    against, and ``reward_terms`` (the keys :attr:`reward_term_names`, plain floats, summing to
    the reward); every entry has a fixed shape, so ``gym.make_vec`` stacks it
    (``aas_gym.envs.info``).
    """

    # 20 Hz control (timestep 2 ms x frame_skip 25), like Gymnasium's Ant and HalfCheetah.
    metadata = {"render_modes": ["human", "rgb_array", "depth_array"], "render_fps": 20}
    #: Narrowest grasp a surface target may be held by (0: wall pinches allowed).
    _min_grasp_width_m = 0.0
    #: Distractors only at the target's -x end (tasks that grasp on the +x half).
    _far_end_only = False

    #: A step is one scripted grasp and recording (a probe), not one control period.
    _step_is_probe = False

    #: Settle each placement as the same run moved (``aas_gym.canonical_settle``): once per
    #: target and layout of the others instead of every reset.
    _settle_canonical = False
    #: The reset's first physics after the canonical settle is ``_grasp`` (LAZY_PLACEMENT_FORWARD).
    _grasp_follows_placement = False

    #: Settle each placement until its objects are at rest, at most the settle's duration
    #: (``aas_gym.scenario.settle``): for scenes whose settle is not replayed.
    _settle_until_rest = False

    #: The camera ``render`` uses unless ``camera_name`` says otherwise (``CAMERA_NAMES``).
    _default_camera = "closeup"

    #: The keys of ``info["reward_terms"]``, in the order they are summed.
    reward_term_names: tuple[str, ...] = ()

    #: The acoustic observation's defaults for this task (subclasses override ``cadence``).
    _acoustic_defaults: dict = {}

    #: The keys ``reset(options=...)`` accepts (any other is refused, naming these).
    reset_options: tuple[str, ...] = ("object",)

    #: The largest ``frame_skip`` accepted (a limit on the cost of one step, not a setting):
    #: raise it on the class or a subclass (``AasEnv.max_frame_skip = ...``) for longer steps.
    max_frame_skip: int = MAX_FRAME_SKIP

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__doc__ and "| Parameter |" in cls.__doc__ and COMMON_ARGUMENTS.strip() not in cls.__doc__:
            cls.__doc__ = cls.__doc__.rstrip() + COMMON_ARGUMENTS

    def __init__(self, objects: Sequence[str | ObjectSpec] = DEFAULT_OBJECT_NAMES, *,
                 scene: str = "single", distractors: Sequence[str | ObjectSpec] | None = None,
                 acoustic: AcousticConfig | dict | None = None, robot: str = DEFAULT_ROBOT,
                 grip_force_n: float = DEFAULT_GRIP_FORCE_N,
                 randomization=None, frame_skip: int = 25, render_mode: str | None = None,
                 width: int = 480, height: int = 480, camera_name: str | None = None, **deprecated) -> None:
        unknown = sorted(set(deprecated) - set(LEGACY_KEYWORDS))
        if unknown:
            raise TypeError(f"{type(self).__name__}() got an unexpected keyword argument {unknown[0]!r}")
        self.acoustic = AcousticConfig.coerce(acoustic, legacy=deprecated, owner=type(self).__name__,
                                              **self._acoustic_defaults)
        self.objects = object_list("objects", objects)
        self.robot = check_robot(robot)
        self.scene_kind = check_choice("scene", scene, ("single", "multi"))
        self.distractors = (object_list("distractors", distractors) if distractors is not None else
                            default_distractors([get_object(n) for n in DEFAULT_OBJECT_NAMES]))
        self.grip_force_n = check_grip_force(grip_force_n)
        self.randomization = DomainRandomization.coerce(randomization).checked()
        try:
            self.frame_skip = check_integer("frame_skip", frame_skip, 1)
        except TypeError:
            raise TypeError(f"frame_skip must be a positive integer, got {frame_skip!r}") from None
        if self.frame_skip > self.max_frame_skip:
            raise ValueError(f"frame_skip={self.frame_skip:,} would simulate {self.frame_skip * 0.002:g} s of physics "
                             f"per env step (limit {self.max_frame_skip:,} = {self.max_frame_skip * 0.002:g} s): choose "
                             "a smaller frame_skip, or raise the limit with aas_gym.envs.AasEnv.max_frame_skip = ...")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.width, self.height = check_integer("width", width, 1), check_integer("height", height, 1)
        self.camera_name = check_choice("camera_name", self._default_camera if camera_name is None else camera_name,
                                        CAMERA_NAMES)
        self._leaks = _load_leaks(self.acoustic.leak)
        self._variation = SensorVariation()
        self._stream: SimAcousticStream | None = None
        self._placement = None      # the canonical settle of this reset (AasEnv._grasp's first release)
        self._forward_pending = False   # its closing mj_forward left out (LAZY_PLACEMENT_FORWARD)
        self._at_rest = None        # the state a settle left at rest (AasEnv._grasp skips the first release)
        self._stream_corruption = None  # the stream's sensors.signals.CorruptedStream (acoustic.corruption)
        self._scenes: LRU[_Scene] = LRU(CACHE_SIZES["env.scenes"])
        self._renderer = None
        self._viewer = None
        self._warned_no_display = False
        self._scene: _Scene = self._get_scene((self.objects[0],))
        vis = self.model.vis.global_
        if self.width > vis.offwidth or self.height > vis.offheight:
            raise ValueError(f"width x height = {self.width} x {self.height} exceeds the scene's offscreen buffer "
                             f"{vis.offwidth} x {vis.offheight} pixels (aas_gym.stage): render smaller")
        # render_fps: the control rate; a probe env's frames are probes, shown at a viewing rate
        # as Gymnasium's turn-based toy_text envs do (no physical time passes between them).
        self.metadata = dict(self.metadata, render_fps=PROBE_RENDER_FPS if self._step_is_probe
                             else max(1, int(round(1.0 / self.dt))))
        if self.acoustic.streaming and not self._step_is_probe:
            self.acoustic.check_samples(self.step_samples, f"one streamed step (frame_skip={self.frame_skip}, "
                                                           f"dt = {self.dt:g} s)")
            exact = self.dt * self.excitation.sample_rate_hz
            if abs(exact - round(exact)) > 1e-6:
                raise ValueError(f"a streamed step must hold a whole number of samples: dt = {self.dt} s gives "
                                 f"{exact:.3f} at {self.excitation.sample_rate_hz} Hz; choose frame_skip so "
                                 "that it does (the default 25 gives 2205)")
        self._init_acoustic_frames(self.audio_samples, None if self._step_is_probe else self.dt)

    @property
    def include_waveform(self) -> bool:
        """Deprecated: ``acoustic.enabled and acoustic.waveform``."""
        warn_deprecated(f"{type(self).__name__}.include_waveform", "acoustic.waveform")
        return self.acoustic.enabled and self.acoustic.waveform

    @property
    def n_samples(self) -> int:
        """Samples in one recording."""
        return self.acoustic.n_samples

    @property
    def step_samples(self) -> int:
        """Samples the microphone records during one env step (``dt`` x sample rate)."""
        return int(round(self.dt * self.excitation.sample_rate_hz))

    @property
    def audio_samples(self) -> int:
        """Length of a streamed observation's ``audio``: one step's samples (probe envs,
        whose step is a whole scripted grasp, stream the ``duration_s`` hold instead)."""
        return self.n_samples if self._step_is_probe else self.step_samples

    # --- reset template ---------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        """New episode: draw the target and its scene, place everything and let it settle
        (``mj_resetData`` first), draw the sensor's variation, then the task's own
        ``_reset_episode(options)``; renders for ``render_mode="human"``."""
        super().reset(seed=seed)
        self._reset_acoustic()
        options = self._check_options(options)
        target = self._target_object(options)
        self._get_scene(self._choose_objects(target))
        self._place_objects()
        self._variation = self._draw_variation()
        self._stream = self._new_stream() if self.acoustic.streaming and not self._step_is_probe else None
        obs, info = self._reset_episode(options)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _check_options(self, options) -> dict:
        """``options`` as a dict; ``TypeError`` for another type, ``ValueError`` for a key this
        env does not read (a typo would otherwise be silently ignored)."""
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
        unknown = sorted(map(str, set(options) - set(self.reset_options)))
        if unknown:
            raise ValueError(f"{type(self).__name__}.reset got unknown option(s) {unknown}; "
                             f"valid options: {list(self.reset_options)}")
        return dict(options)

    def _reset_episode(self, options: dict) -> tuple[dict, dict]:
        """The task's part of ``reset`` after placement: returns ``(observation, info)``."""
        raise NotImplementedError

    # --- scenes -----------------------------------------------------------------------------
    def _get_scene(self, objects: tuple[ObjectSpec, ...]) -> _Scene:
        scene = self._scenes.get_or_build(objects, lambda: self._new_scene(objects))
        if scene is not getattr(self, "_scene", None):
            self._close_renderers()  # renderers are bound to one model
        self._scene = scene
        return scene

    def _new_scene(self, objects: tuple[ObjectSpec, ...]) -> _Scene:
        scene = _Scene(objects, contact_signature=self.acoustic.streaming, robot=self.robot)
        scene.sensor.leak, scene.sensor.fingertip = self._leaks, self.acoustic.fingertip
        scene.sensor.contact_model = self.acoustic.contact_model
        scene.sensor.bandlimited = self.acoustic.drive == "bandlimited"
        return scene

    @property
    def model(self) -> mujoco.MjModel:
        return self._scene.model

    @property
    def data(self) -> mujoco.MjData:
        return self._scene.data

    @property
    def hand(self) -> Hand:
        return self._scene.hand

    @property
    def sensor(self) -> SimAcousticSensor:
        return self._scene.sensor

    @property
    def dt(self) -> float:
        """Simulated time per env step [s] (``frame_skip`` x the 2 ms timestep). A probe env
        (a step is one scripted grasp and recording, or an answer) has none: ``AttributeError``."""
        if self._step_is_probe:
            raise AttributeError(f"{type(self).__name__} has no dt: a step is a whole probe (a scripted grasp "
                                 "and recording) or an answer, not a control period")
        return self._scene.model.opt.timestep * self.frame_skip

    def _target_object(self, options: dict) -> ObjectSpec:
        """The episode's target: ``options["object"]`` if given, else drawn from ``objects``.

        The draw happens either way, so the random stream does not depend on the option."""
        target = self.objects[int(self.np_random.integers(len(self.objects)))]
        if "object" in options:
            target = get_object(options["object"])
        return target

    def _choose_objects(self, target: ObjectSpec) -> tuple[ObjectSpec, ...]:
        """Target first, then distractors for multi-object scenes (``aas_gym.scenario``)."""
        return choose_objects(self.np_random, target, self.distractors, self.scene_kind,
                              max_others=1 if self._far_end_only else 2)

    def _place_objects(self, settle_s: float = 0.4) -> None:
        """Reset the data, put the hand home (open), place the objects as
        ``aas_gym.scenario.place_objects`` says, then let them settle."""
        sc, m, d = self._scene, self._scene.model, self._scene.data
        mujoco.mj_resetData(m, d)
        sc.hand.set_grip_force(self.grip_force_n)
        sc.hand.teleport(d, HOME_TCP, MAX_OPENING_M, forward=not grasp_module.LEAN_SCRIPT)  # a settle follows
        self._layout = place_objects(m, d, sc.objects, sc.free_joints, self.np_random, self.randomization,
                                     far_end_only=self._far_end_only)
        self._placement = self._at_rest = None
        self._forward_pending = False
        if self._settle_near_rest(settle_s):
            self._at_rest = scenario.SceneState.of(m, d)     # at rest: the first release is skipped
        elif self._settle_canonical:
            lazy = LAZY_PLACEMENT_FORWARD and self._grasp_follows_placement
            self._placement = settle_placed(sc.memo, m, d, sc.free_joints, self._layout, settle_s, sc.canonical_quat,
                                            forward=not lazy)
            self._forward_pending = lazy and self._placement is not None
        elif self._settle_until_rest:      # aas_gym.scenario.SETTLE_UNTIL_REST; the key says which
            rest = scenario.SETTLE_UNTIL_REST
            steps = sc.memo.run(d, ("settle", settle_s, "until rest" if rest else "whole"),
                                lambda: settle(m, d, settle_s, until_rest=True))
            # at rest before the end: the first release (the hand far above) would only tremble them
            self._at_rest = scenario.SceneState.of(m, d) if steps < scenario.settle_steps(m, settle_s) else None
        else:
            sc.memo.run(d, ("settle", settle_s), lambda: settle(m, d, settle_s))

    def _settle_near_rest(self, settle_s: float) -> bool:
        """Settle the placed scene from a predicted rest until at rest, if this env can (True);
        else leave it as placed (False: ``_place_objects`` settles it).  FillLevel-v0's lone
        container does (``aas_gym.rest_states``)."""
        return False

    def _episode_grip_force(self) -> float:
        r = self.randomization.grip_force_rel
        f = self.grip_force_n * (1 + self.np_random.uniform(-r, r)) if r > 0 else self.grip_force_n
        return float(np.clip(f, 1.0, MAX_GRIP_FORCE_N))

    def _draw_variation(self) -> SensorVariation:
        """This episode's sensor variation (noise, leak scale, material scales), a value the
        env passes to every ``sense`` call."""
        r, rng = self.randomization, self.np_random

        def scale(rel: float) -> float:
            return float(rng.uniform(1 - rel, 1 + rel)) if rel > 0 else 1.0

        damping, modulus, density = scale(r.damping_rel), scale(r.modulus_rel), scale(r.density_rel)
        lo, hi = r.leak_scale
        leak = float(rng.uniform(lo, hi)) if hi > lo else float(lo)
        noise = self.acoustic.noise_std + r.sensor_noise_std
        return SensorVariation(noise_std=noise, damping_scale=damping, modulus_scale=modulus,
                               density_scale=density, leak_scale=leak)

    def _grasp(self, position_m: float, grip_force_n: float) -> dict:
        """Scripted planar grasp of the target at ``position_m`` (+ noise) along its axis."""
        r = self.randomization
        noise = float(self.np_random.normal(0.0, r.position_noise_m)) if r.position_noise_m > 0 else 0.0
        grasp = target_grasp(self._scene.objects[0], position_m, self._layout, shift_m=noise,
                             min_width_m=self._min_grasp_width_m)

        def release_hand():
            release(self.model, self.data, self.hand, retreat_m=0.0, duration_s=0.06)

        # The first release after a canonical settle (the hand at home, nothing moved since) is
        # replayed from the canonical run; any other runs here, as part of the grasp.
        placement, self._placement = self._placement, None
        released = placement is not None and placement.is_current(self.model, self.data)
        pending, self._forward_pending = self._forward_pending, False
        if pending and not released:                    # the forward settle_placed left out
            mujoco.mj_forward(self.model, self.data)
        if released:
            run_after_settle(self._scene.memo, self.model, self.data, placement, ("release", 0.06), release_hand,
                             forward=False)   # the grasp reads its poses itself
        # After a settle that stopped at rest (nothing ran since) the first release, the hand far
        # above opening an open hand, would only tremble the objects: skipped.
        at_rest, self._at_rest = self._at_rest, None
        if not released and at_rest is not None and at_rest.is_current(self.model, self.data):
            released = "at rest"

        def section():
            if not released:
                release_hand()
            return planar_grasp(self.model, self.data, self._scene.bodies[0], position_m + noise, grip_force_n,
                                hand=self.hand, stream=self._scene.stream, grasp=grasp)

        grasp_key = None if grasp is None else (np.asarray(grasp.centre_m).tobytes(), np.asarray(grasp.axis).tobytes(),
                                                grasp.width_m, grasp.position_m)
        result = self._scene.memo.run(self.data, ("grasp", position_m + noise, grip_force_n, grasp_key, released),
                                      section)
        return {"grasp_position_m": result.grasp_position_m, "grasp_success": result.success,
                "grip_force_n": grip_force_n}

    # --- observation parts ------------------------------------------------------------------
    def _proprio_spaces(self, with_object: bool = False) -> dict:
        return proprio_spaces(with_object)

    def _acoustic_spaces(self) -> dict:
        return self.acoustic.spaces(self.audio_samples)

    def _state_obs(self, with_object: bool) -> tuple[dict, np.ndarray]:
        """Proprioception (``tcp``, ``tcp_velocity``, ``gripper`` = opening [m], opening speed
        [m/s], motor force [N]: what the real hand reports, no contact sensing) and, with
        ``with_object``, the target's pose under ``object``; plus the float64 values."""
        sc = self._scene
        nq = sc.model.nq
        state = sc.state
        state[:nq] = sc.qpos
        state[nq:] = sc.qvel
        values = sc.obs_map @ state if with_object else sc.obs_map[:_OBJECT] @ state
        values[_MOTOR_FORCE] = -sc.actuator_force[sc.gripper]
        if not sc.carriage:
            values[_TCP:_TCP + 4] = sc.hand.tcp(sc.data)
            values[_TCP_VELOCITY:_TCP_VELOCITY + 4] = sc.hand.tcp_velocity(sc.data)
        buf = values.astype(np.float32)
        obs = {name: buf[sl] for name, sl in _LAYOUT_ITEMS if with_object or name != "object"}
        return obs, values

    def _proprio(self) -> dict:
        """Proprioception only (see ``_state_obs``)."""
        return self._state_obs(False)[0]

    def _sense(self, excitation=None, contacts=None) -> tuple[dict, object]:
        """Record through the current grasp with this episode's variation: observation
        entries (per ``acoustic``) and the AcousticObservation (features only unless the
        waveform is observed). Streamed, the hand holds the grasp for ``duration_s`` while
        the physics runs and the microphone records. ``contacts``: the current state's, if read."""
        excitation = self.excitation if excitation is None else excitation
        if self.acoustic.streaming:
            return self._stream_hold(excitation)
        rec = self.sensor.sense(excitation, self.duration_s, variation=self._variation, rng=self.np_random,
                                waveform=self.acoustic.needs_waveform, contacts=contacts)
        return self._recording_entries(rec), rec

    def _sense_and_truth(self, excitation=None) -> tuple[dict, bool, dict]:
        """``_sense`` then ``_ground_truth(contacts=True)`` of the state it leaves: the entries,
        whether the recording heard a grasp, the truth; a probe that runs no physics reads the
        contacts once for both. With sensing off nothing is recorded (nothing observes it):
        no entries, and whether a grasp would be heard."""
        if self.acoustic.streaming:
            acoustic, rec = self._sense(excitation)
            return acoustic, bool(rec.metadata.get("grasped", False)), self._ground_truth(contacts=True)
        contacts = self._scene.stream.read(self.data)
        if not self.acoustic.enabled:
            return {}, self.sensor.grasped_body(contacts) is not None, self._ground_truth(contacts=contacts)
        acoustic, rec = self._sense(excitation, contacts)
        return acoustic, bool(rec.metadata.get("grasped", False)), self._ground_truth(contacts=contacts)

    def _empty_acoustic(self) -> dict:
        """The acoustic entries of an empty history (zeros)."""
        return self.acoustic_frames.zeros()

    # --- streaming --------------------------------------------------------------------------
    def _new_stream(self, excitation=None) -> SimAcousticStream:
        """A new stream; ``_stream_corruption``: its corruption (``acoustic.corruption``), new too."""
        stream = SimAcousticStream(self.sensor, self.excitation if excitation is None else excitation,
                                   variation=self._variation, rng=self.np_random,
                                   tolerance=self.acoustic.stream_tolerance, passive=self.acoustic.passive)
        self._stream_corruption = self.acoustic.corrupted_stream(self.corruption_rng, stream.stream.excitation)
        return stream

    @property
    def stream_corruption(self):
        """The running stream's ``sensors.signals.CorruptedStream`` (``acoustic.corruption``
        with cadence ``"stream"``; ``None`` otherwise): its state, seeded at each new stream."""
        return self._stream_corruption

    def _stream_features(self, stream: SimAcousticStream):
        """The features a streamed observation shows: of the corrupted stream, if corrupted."""
        return (stream if self._stream_corruption is None else self._stream_corruption).latest_features()

    def _simulate(self) -> None:
        """One env step of physics (``frame_skip`` MuJoCo steps); streamed, the microphone
        records through every one of them (``_stream_audio`` holds the samples)."""
        if self._stream is None:
            mujoco.mj_step(self._scene.model, self._scene.data, nstep=self.frame_skip)
            return
        self._stream_audio = self._stream.step_physics(self.frame_skip, self.step_samples)
        if self._stream_corruption is not None:
            self._stream_audio = self._stream_corruption.process(self._stream_audio)

    def _stream_entries(self) -> dict:
        """The streamed observation entries after ``_simulate``."""
        return self.acoustic_frames.push(self.acoustic.stream_entries(self._stream_features(self._stream),
                                                                     self._stream_audio))

    def _stream_hold(self, excitation) -> tuple[dict, object]:
        """A probe streamed: a new stream (the hand was placed anew) records while the
        physics holds the grasp for ``duration_s``; the entries and the recording."""
        from sensors import AcousticObservation

        stream = self._new_stream(excitation)
        n_steps = max(1, int(round(self.duration_s / self.model.opt.timestep)))
        audio = stream.step_physics(n_steps, self.n_samples)
        if self._stream_corruption is not None:
            audio = self._stream_corruption.process(audio).astype(np.float32)
        meta = stream.metadata
        meta.update({"grasped": stream.stream.latest_features_heard > 0.99, "heard_body": stream.heard_body})
        if self._stream_corruption is not None:
            meta["corrupted"] = True
        rec = AcousticObservation(audio, stream.sample_rate_hz, stream.stream.excitation, metadata=meta)
        return self.acoustic_frames.push(self.acoustic.stream_entries(self._stream_features(stream), audio)), rec

    def _is_grasped(self) -> bool:
        """Both sensor fingertips touch the target (this runs every step: MuJoCo's contact
        sensors computed it during the step)."""
        sc = self._scene
        a, m = sc.touch_adr
        return sc.sensordata[a] > 0 and sc.sensordata[m] > 0

    def _ground_truth(self, contacts=True) -> dict:
        """Labels, pose and variation; with ``contacts`` (True, or the contacts already read
        from the current state) the target's contact datastream under ``contacts``."""
        sc = self._scene
        target = sc.objects[0]
        info = {"label": target.label, "material": target.material, "shape": target.shape,
                "object_body": sc.bodies[0], "objects": [o.label for o in sc.objects],
                "object_pose": np.concatenate([self.data.xpos[sc.body_ids[0]],
                                               self.data.xquat[sc.body_ids[0]]]).astype(np.float64)}
        info["randomization"] = self._variation.to_dict()
        if contacts is not False:
            read = sc.stream.read(self.data) if contacts is True else contacts
            info["contacts"] = contacts_info(read)
        return info

    # --- rendering --------------------------------------------------------------------------
    def render(self):
        """``rgb_array``: (height, width, 3) uint8; ``depth_array``: (height, width) float32
        metres; ``human``: updates a passive viewer window (needs a display)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if self.render_mode == "human":
            if self._viewer is None:
                if not has_display():
                    # MuJoCo aborts the process when GLFW cannot open a window: do not try.
                    if not self._warned_no_display:
                        gym.logger.warn("render_mode='human' but no display (DISPLAY/WAYLAND_DISPLAY unset): "
                                        "nothing is shown; use render_mode='rgb_array' headless")
                        self._warned_no_display = True
                    return None
                from mujoco import viewer as mj_viewer

                self._viewer = mj_viewer.launch_passive(self.model, self.data)
            self._viewer.sync()
            return None
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.model, self.height, self.width)
        if self.render_mode == "depth_array":
            self._renderer.enable_depth_rendering()
        self._renderer.update_scene(self.data, camera=self.camera_name)
        return self._renderer.render()

    def _close_renderers(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def close(self) -> None:
        self._close_renderers()
        super().close()
