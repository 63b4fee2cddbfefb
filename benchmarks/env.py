"""Environment throughput and the cost of an acoustic observation.

    python benchmarks/env.py [--budget-s 4] [--chunks 40] [--repeats 5] [--sections envs physics acoustic]

1. Every env (issue 27): ``gymnasium.make`` with random actions (seeded), resets included, for
   ``--budget-s`` CPU seconds each: env steps/s with sensing on (the env's default acoustic
   config; a features-only observation takes the closed form, ``sensors.synthesis.
   simulate_features``), with sensing off (``acoustic={"enabled": False}``), and bare MuJoCo
   (``mj_step`` of ``frame_skip`` steps, one control period, on the same compiled model from
   the env's state) beside them, and the env's own ``mj_step`` calls replayed (its physics
   alone); with the default domain randomization (every placement,
   grasp and material new) and, for the probe envs, without it (``randomization=False``:
   repeated grasps replay from the physics and synthesis caches). Beside the speed, the
   features of one grasp of the env's target through both paths (closed form against the
   recorded float32 waveform): the largest difference per feature relative to that feature,
   and relative to the largest feature. Goals: AcousticGrasp-v0 and ContactFormation-v0 >= 1000
   steps/s, GraspPosition-v0 and ObjectRecognition-v0 >= 500 steps/s with resets,
   FillLevel-v0 >= 200 episodes/s, moving streaming (ContactFormation-v0, ``cadence="stream"``)
   >= 50x real time.
2. Physics: ``aas_gym/AcousticGrasp-v0`` without acoustic observations (``acoustic={"cadence": "never"}``,
   created with ``gymnasium.make``, wrappers included) against the same compiled MuJoCo model
   stepped bare with the same controls from the same states. Timed in interleaved chunks so
   that load from other processes hits both alike; the ratio is the median over chunks
   (goal >= 0.9: a scene pays only for what it uses).
2b. Robots: ``aas_gym/AcousticGrasp-v0`` env steps per second with each robot (``robot=
   "floating_hand"`` and ``"panda"``), sensing off (``cadence "never"``) and on (``cadence
   "stream"``: the microphone records through every physics step), in one run.
3. Acoustics: one 1 s observation of a grasped object with warm caches (modal model built
   once beforehand), per excitation and object, as a real-time factor = 1 s / wall time
   (goal >= 20x). The cold first call (modal model built or loaded from the disk cache) is
   reported separately.
3. Vector envs: ``aas_gym/AcousticGrasp-v0`` (defaults: sensing on the action's sense entry)
   under ``gym.make_vec(..., vectorization_mode="async")`` with 1 and 2 worker processes,
   random actions, resets included: env steps per second of wall time (the workers' CPU time
   is not this process's). ``--vector-only`` runs just this part and prints it.

Times of parts 1 and 2 are CPU times of this process (``time.process_time``): the machine is shared.

Prints a Markdown table and writes ``docs/benchmarks/env.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
import gymnasium as gym
import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
# CPU time of this process (all its threads): the machine is shared, and wall time would
# charge other people's work to whichever side happened to run then.
_clock = time.process_time


def physics_ratio(chunks: int, steps: int) -> dict:
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never"}, max_episode_steps=10**9)
    env.reset(seed=0)
    u = env.unwrapped
    model, skip = u.model, u.frame_skip
    rng = np.random.default_rng(0)
    # Small random actions: the hand wanders above the table, gripper opens and closes.
    actions = [(rng.uniform(-1, 1, 6) * [0.3, 0.3, 0.3, 0.3, 1, -1]).astype(np.float32) for _ in range(steps)]
    bare = mujoco.MjData(model)
    start = mujoco.MjData(model)
    ctrls = np.empty((steps, model.nu))
    env_rates, bare_rates, ratios = [], [], []
    for chunk in range(chunks):
        mujoco.mj_copyData(start, model, u.data)
        for i, a in enumerate(actions):  # untimed pass: the controls the env applies
            env.step(a)
            ctrls[i] = u.data.ctrl
        end_state = u.data.qpos.copy()

        def run_env():
            mujoco.mj_copyData(u.data, model, start)
            t0 = _clock()
            for a in actions:
                env.step(a)
            return _clock() - t0

        def run_bare():
            mujoco.mj_copyData(bare, model, start)
            t0 = _clock()
            for i in range(steps):
                bare.ctrl[:] = ctrls[i]
                mujoco.mj_step(model, bare, nstep=skip)
            return _clock() - t0

        # Alternate the order so that caches and clock changes favour neither.
        if chunk % 2:
            t_bare, t_env = run_bare(), run_env()
        else:
            t_env, t_bare = run_env(), run_bare()
        assert np.allclose(bare.qpos, end_state) and np.allclose(u.data.qpos, end_state), "replay diverged"
        env_rates.append(steps * skip / t_env)
        bare_rates.append(steps * skip / t_bare)
        ratios.append(t_bare / t_env)
        if abs(u.data.qpos[2] - 0.3) > 0.25:  # keep the hand in its workspace
            env.reset(seed=chunk)
    env.close()
    return {"env_steps_s": statistics.median(env_rates), "bare_steps_s": statistics.median(bare_rates),
            "ratio": statistics.median(ratios), "env_dt_s": u.dt, "frame_skip": skip}


ROBOTS = ("floating_hand", "panda")
SENSING = {"off": {"cadence": "never"}, "on (stream)": {"cadence": "stream"}}


def robot_throughput(chunks: int, steps: int) -> list[dict]:
    """Env steps/s (median over ``chunks`` of ``steps`` steps, process CPU time) of
    AcousticGrasp-v0 with each robot, sensing off and on, the same small random actions."""
    rng = np.random.default_rng(1)
    actions = [(rng.uniform(-1, 1, 6) * [0.3, 0.3, 0.3, 0.3, 1, -1]).astype(np.float32) for _ in range(steps)]
    rows = []
    for robot in ROBOTS:
        for sensing, acoustic in SENSING.items():
            env = gym.make("aas_gym/AcousticGrasp-v0", robot=robot, acoustic=acoustic, max_episode_steps=10**9)
            rates = []
            for chunk in range(chunks):
                env.reset(seed=chunk)
                t0 = _clock()
                for a in actions:
                    env.step(a)
                rates.append(steps / (_clock() - t0))
            env.close()
            rows.append({"robot": robot, "sensing": sensing, "steps_s": statistics.median(rates)})
    base = {r["sensing"]: r["steps_s"] for r in rows if r["robot"] == ROBOTS[0]}
    for r in rows:
        r["relative"] = r["steps_s"] / base[r["sensing"]]
    return rows


def acoustic_cost(objects: list[str], excitations: list[str], repeats: int) -> list[dict]:
    """Per object and excitation: CPU time of ``sense`` for 1 s, (a) sensing the same grasp
    again (the synthesis reuses its per-grasp system) and (b) a new grasp every time (the
    per-grasp damping and eigen-decomposition are rebuilt: the dataset-generation case)."""
    from aas_gym.grasp import planar_grasp
    from aas_gym.scene import build_scene
    from aas_gym.sim_sensor import SimAcousticSensor
    from sensors import Excitation

    rows = []
    positions = np.linspace(0.0, 0.06, repeats + 1)
    for name in objects:
        model = build_scene([name])
        data = mujoco.MjData(model)
        planar_grasp(model, data, name, 0.03, 40.0)
        sensor = SimAcousticSensor(model, data, rng=np.random.default_rng(0))
        t0 = _clock()
        modal = sensor.modal_model(name)
        cold = _clock() - t0
        for ex_name in excitations:
            ex = Excitation.by_name(ex_name)
            planar_grasp(model, data, name, 0.03, 40.0)
            sensor.sense(ex, 1.0)  # warm-up (compiled kernels, FFT plans)
            same = []
            for _ in range(repeats):
                t0 = _clock()
                sensor.sense(ex, 1.0)
                same.append(_clock() - t0)
            new = []
            for k in range(repeats):
                planar_grasp(model, data, name, float(positions[k + 1]), 40.0)
                t0 = _clock()
                sensor.sense(ex, 1.0)
                new.append(_clock() - t0)
            rows.append({"object": name, "excitation": ex.name, "modes": len(modal.frequencies_hz),
                         "cold_s": cold, "same_s": statistics.median(same), "new_s": statistics.median(new),
                         "rtf_same": 1.0 / statistics.median(same), "rtf_new": 1.0 / statistics.median(new)})
            cold = float("nan")  # report the modal-model cost once per object
    return rows


# (label, env id, kwargs, goal kind, goal value): "steps" = env steps/s, "episodes" = episodes/s,
# "rtf" = real-time factor of the streamed env (steps/s x dt).
ENV_ROWS = [
    ("AcousticGrasp-v0", "aas_gym/AcousticGrasp-v0", {}, "steps", 1000),
    ("AcousticGrasp-v0, randomization off", "aas_gym/AcousticGrasp-v0", {"randomization": False}, "steps", 1000),
    ("ContactFormation-v0, probe cadence", "aas_gym/ContactFormation-v0", {"acoustic": {"cadence": "action"}},
     "steps", 1000),
    ("ContactFormation-v0, stream", "aas_gym/ContactFormation-v0", {}, "steps", 1000),
    ("ContactFormation-v0, stream: moving grasp", "aas_gym/ContactFormation-v0", {}, "rtf", 50),
    ("GraspPosition-v0", "aas_gym/GraspPosition-v0", {}, "steps", 500),
    ("GraspPosition-v0, randomization off", "aas_gym/GraspPosition-v0", {"randomization": False}, "steps", 500),
    ("ObjectRecognition-v0", "aas_gym/ObjectRecognition-v0", {}, "steps", 500),
    ("ObjectRecognition-v0, randomization off", "aas_gym/ObjectRecognition-v0", {"randomization": False},
     "steps", 500),
    ("FillLevel-v0", "aas_gym/FillLevel-v0", {}, "episodes", 200),
]

#: Longer warm-ups [CPU s] of sensing-on runs, where a long run's rate comes later than
#: ``--warmup-s``: ObjectRecognition-v0 solves unit loads for new nodes of its seven objects for
#: its first ~40 CPU s (default config, one process, 2026-11-27: 9 steps/s in the first 20 CPU s,
#: 120 in the next 20, then 106-166 in every 20 CPU s window up to 300 CPU s).
WARMUP_FLOOR_S = {"aas_gym/ObjectRecognition-v0": 60.0}


def _run_env(env_id: str, kwargs: dict, budget_s: float, warmup_s: float = 0.0) -> dict:
    """Random actions for ``budget_s`` CPU seconds after a short warm-up (and ``warmup_s`` CPU
    seconds more of random actions: a long run's rate, past the first objects' models,
    factorizations and kept solves): steps/s, episodes/s."""
    env = gym.make(env_id, disable_env_checker=True, **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(3):                       # warm-up: modal models, compiled kernels, FFT plans
        if any(env.step(env.action_space.sample())[2:4]):
            env.reset()
    t0 = _clock()
    while _clock() - t0 < warmup_s:
        if any(env.step(env.action_space.sample())[2:4]):
            env.reset()
    steps = episodes = 0
    t0 = _clock()
    while _clock() - t0 < budget_s:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        steps += 1
        if terminated or truncated:
            env.reset()
            episodes += 1
    elapsed = _clock() - t0
    u = env.unwrapped
    # probe envs have no dt (one step is one probe)
    out = {"steps_s": steps / elapsed, "episodes_s": episodes / elapsed, "dt_s": getattr(u, "dt", float("nan")),
           "env": env}
    # one control period of bare MuJoCo on the same model, from the env's state
    bare = mujoco.MjData(u.model)
    mujoco.mj_copyData(bare, u.model, u.data)
    n, t0 = 0, _clock()
    while _clock() - t0 < min(budget_s, 1.0):
        mujoco.mj_step(u.model, bare, nstep=u.frame_skip)
        n += 1
    out["bare_steps_s"] = n / (_clock() - t0)
    out["own_steps_s"], out["own_mismatches"] = _own_physics_rate(env, min(budget_s, 1.0))
    return out


def _own_physics_rate(env, budget_s: float) -> tuple[float, int]:
    """Env steps per CPU second if only MuJoCo ran: random actions for ``budget_s`` CPU seconds
    with every ``mujoco.mj_step`` call of the env (control periods, settles, scripted grasps)
    replayed once more on a scratch ``MjData`` from the same state and model, and only the
    replays timed. The bound of the env's own physics, where *bare* steps one period from one
    state (what that state touches moves it 2-3x). Returns the rate and the number of replays
    that did not end in the env's state bit for bit (0: the replays are the env's steps); the
    rate is infinite when no ``mj_step`` ran (every reset and grasp replayed from memory)."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    original = mujoco.mj_step
    scratch: dict[int, tuple] = {}
    spent = [0.0]
    mismatches = [0]
    calls = [0]

    def replayed_step(model, data, nstep=1):
        if id(model) not in scratch:  # the model is kept alive by the entry, so its id stays its own
            scratch[id(model)] = (model, mujoco.MjData(model))
        replay = scratch[id(model)][1]
        calls[0] += 1
        state = np.empty(mujoco.mj_stateSize(model, spec))
        mujoco.mj_getState(model, data, state, spec)
        mujoco.mj_setState(model, replay, state, spec)
        t0 = _clock()
        original(model, replay, nstep=nstep)
        spent[0] += _clock() - t0
        original(model, data, nstep=nstep)
        mujoco.mj_getState(model, replay, state, spec)
        after = np.empty_like(state)
        mujoco.mj_getState(model, data, after, spec)
        mismatches[0] += not np.array_equal(state, after)

    steps, t0 = 0, _clock()
    mujoco.mj_step = replayed_step
    try:
        while _clock() - t0 < 2 * budget_s:  # about half of it is the replays
            steps += 1
            if any(env.step(env.action_space.sample())[2:4]):
                env.reset()
    finally:
        mujoco.mj_step = original
    return (steps / spent[0] if calls[0] else float("inf")), mismatches[0]


def _grasp_once(env):
    """The env after ``reset(seed=1)``, its target grasped (by the env or, for envs whose reset
    does not grasp, by its scripted grasp)."""
    u = env.unwrapped
    env.reset(seed=1)
    if not u.sensor.grasped_body():
        from aas_gym.scenario import grasp_position

        u._grasp(grasp_position(np.random.default_rng(0), u._scene.objects[0], u._layout), u.grip_force_n)
    return u


def _reference_error(env_id: str, kwargs: dict) -> float:
    """Closed-form features of the same grasp in two fresh envs: contact modes from kept
    unit-load solves and canonical settles (the defaults) and from the direct solve of each
    contact set and the settle where placed (``sensors.modal.static_correction.REUSE_UNIT_LOADS``,
    ``aas_gym.canonical_settle.CANONICAL_SETTLE`` False, the references): largest difference per
    feature / that feature."""
    from aas_gym import canonical_settle
    from sensors.modal import static_correction

    def features_of_one_grasp():
        env = gym.make(env_id, disable_env_checker=True, **kwargs)
        u = _grasp_once(env)
        out = u.sensor.sense(u.excitation, u.duration_s, variation=u._variation,
                             rng=np.random.default_rng(0), waveform=False).features()
        env.close()
        return out

    features = [features_of_one_grasp()]
    saved_settle = canonical_settle.CANONICAL_SETTLE
    canonical_settle.CANONICAL_SETTLE = False          # the canonical-settle envs' settle where placed (reference)
    try:
        with static_correction.reference_paths():
            features.append(features_of_one_grasp())
    finally:
        canonical_settle.CANONICAL_SETTLE = saved_settle
    fast, reference = features
    return float(np.max(np.abs(fast - reference) / np.abs(reference)))


def _features_error(env) -> tuple[float, float]:
    """Both paths' features of one grasp of the env's target (after a reset; grasped by the env
    or, for envs whose reset does not grasp, by its scripted grasp): (max relative error per
    feature, max error / max feature)."""
    u = _grasp_once(env)
    ex = u.excitation
    rec = u.sensor.sense(ex, u.duration_s, variation=u._variation, rng=np.random.default_rng(0))  # the samples
    try:
        fast = u.sensor.sense(ex, u.duration_s, variation=u._variation, rng=np.random.default_rng(0), waveform=False)
    except TypeError:                        # a tree without the closed form
        return float("nan"), float("nan")
    a, b = rec.features(), fast.features()
    return float(np.max(np.abs(a - b) / np.abs(a))), float(np.max(np.abs(a - b)) / np.max(a))


def fill_cost(n: int = 8) -> tuple[float, float, float]:
    """CPU seconds of one new fill of FillLevel-v0's default container (``sensors.fluid.filled``,
    what its reset pays before any physics or sensing): from the container's fill table (the
    env's default) and by the exact solve, medians of ``n`` fills in its default range."""
    from sensors.fluid import filled

    env = gym.make("aas_gym/FillLevel-v0", disable_env_checker=True).unwrapped
    solid = env.objects[0].solid()
    lo, hi = env.fill_range
    table, exact = [], []
    for f in np.linspace(lo, hi, n + 2)[1:-1]:
        for interpolated, times in ((True, table), (False, exact)):
            t0 = _clock()
            filled(solid, float(f), liquid=env.liquids[0], interpolated=interpolated)
            times.append(_clock() - t0)
    env.close()
    return statistics.median(table), statistics.median(exact), float(n)


def env_throughput(budget_s: float, warmup_s: float = 0.0) -> list[dict]:
    rows, runs = [], {}
    for label, env_id, kwargs, goal_kind, goal in ENV_ROWS:
        key = (env_id, repr(kwargs))
        if key not in runs:                  # a second goal on the same env reuses its run
            on = _run_env(env_id, kwargs, budget_s, max(warmup_s, WARMUP_FLOOR_S.get(env_id, 0.0)) if warmup_s else 0.0)
            off = _run_env(env_id, dict(kwargs, acoustic={"enabled": False}), budget_s, warmup_s)
            runs[key] = (on, off, _features_error(on["env"]), _reference_error(env_id, kwargs))
            on["env"].close()
            off["env"].close()
        on, off, err, ref_err = runs[key]
        value = {"steps": on["steps_s"], "episodes": on["episodes_s"], "rtf": on["steps_s"] * on["dt_s"]}[goal_kind]
        row = {"label": label, "on": on["steps_s"], "episodes": on["episodes_s"], "off": off["steps_s"],
               "bare": on["bare_steps_s"], "own": on["own_steps_s"], "own_mismatches": on["own_mismatches"], "rel_err": err[0], "err_of_max": err[1], "ref_err": ref_err,
               "goal_kind": goal_kind,
               "goal": goal, "value": value, "met": value >= goal}
        if label.startswith("FillLevel"):
            row["fill_s"], row["fill_exact_s"], row["fill_n"] = fill_cost()
        print(_env_line(row), flush=True)
        rows.append(row)
    return rows


_UNITS = {"steps": "steps/s", "episodes": "episodes/s", "rtf": "x real time"}


def _env_line(r: dict) -> str:
    return (f"| {r['label']} | {r['on']:.0f} | {r['episodes']:.1f} | {r['off']:.0f} | {r['bare']:.0f} | "
            f"{'no mj_step (replayed)' if r['own'] == float('inf') else format(r['own'], '.0f')}{'' if not r['own_mismatches'] else ' (' + str(r['own_mismatches']) + ' replays differ)'} | "
            f"{r['rel_err']:.1e} | {r['err_of_max']:.1e} | {r['ref_err']:.1e} | >= {r['goal']} {_UNITS[r['goal_kind']]}: "
            f"{r['value']:.0f}, {'met' if r['met'] else 'not met'} |")


def env_lines(rows: list[dict], budget_s: float, warmup_s: float = 0.0) -> list[str]:
    lines = [
        "## Every env: steps per second with sensing on, off, and bare MuJoCo (issue 27)",
        "",
        f"`gymnasium.make`, random actions (seeded), resets included, {budget_s:g} CPU s per figure"
        + (f", timed after {warmup_s:g} CPU s of random actions (a long run's rate: the first objects' models, "
           "factorizations and kept solves are built by then; with sensing on, "
           + ", ".join(f"{e.split('/')[-1]} after {w:g} CPU s" for e, w in WARMUP_FLOOR_S.items() if w > warmup_s)
           + ": its unit-load stores fill longer)" if warmup_s else
           " from the first steps (the first objects' models, factorizations and kept solves included)")
        + ". *On*: the "
        "env's default acoustic config (features only: closed form); *off*: `acoustic={\"enabled\": False}`; "
        "*bare*: `mj_step` of one control period (`frame_skip` steps) on the same model, from the run's last state; "
        "*own physics*: the env's own `mj_step` calls (periods, settles, scripted grasps) of a further run, each "
        "replayed from its state on a scratch `MjData` and only the replays timed: the rate if only MuJoCo ran "
        "(every replay ended in the env's state bit for bit unless the row says otherwise). *Error*: features of "
        "one grasp of the target through the closed form against the recorded float32 waveform's, largest "
        "difference per feature / that feature, and / the largest feature (the float32 rounding, 2^-24 of "
        "each sample, is the whole difference: against the float64 chain it is below 1e-6 per feature, "
        "`tests/test_closed_form_features.py`). *Modes error*: the same grasp's closed-form features with the "
        "contact modes' attachment vectors combined from kept unit-load solves (the default) against the direct "
        "solve of each contact set (`sensors.modal.static_correction.REUSE_UNIT_LOADS = False`, the reference) "
        "and, in GraspPosition-v0 and ObjectRecognition-v0, the placement settled where it was drawn "
        "(`aas_gym.canonical_settle.CANONICAL_SETTLE = False`), largest difference per feature / that feature "
        "(`tests/test_unit_load_reuse.py`, `tests/test_canonical_settle.py`).",
        "",
        "| env | on [steps/s] | episodes/s | off [steps/s] | bare [steps/s] | own physics [steps/s] | error / feature | "
        "error / max | modes error | goal |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    lines += [_env_line(r) for r in rows]
    fill = next((r for r in rows if r["label"].startswith("FillLevel")), None)
    if fill is not None and "fill_s" in fill:
        lines += ["", f"FillLevel-v0: a new fill (`sensors.fluid.filled`, median of {fill['fill_n']:.0f}) costs "
                  f"{fill['fill_s'] * 1e3:.1f} ms from the container's fill table (the env's default; "
                  f"{fill['fill_exact_s'] * 1e3:.0f} ms by the exact solve) of the "
                  f"{1e3 / max(fill['episodes'], 1e-9):.0f} ms an episode takes."]
    met = [r["label"] for r in rows if r["met"]]
    missed = [r["label"] for r in rows if not r["met"]]
    lines += ["", f"Met: {', '.join(met) or 'none'}.", "", f"Not met: {', '.join(missed) or 'none'}."]
    return lines


def vector_rates(workers: tuple[int, ...], steps: int) -> list[dict]:
    """Env steps/s (wall) of AcousticGrasp-v0 in an async vector env of each worker count:
    ``steps`` vector steps after a warm-up of 50 (workers started, modal model loaded)."""
    rows = []
    for n in workers:
        venv = gym.make_vec("aas_gym/AcousticGrasp-v0", num_envs=n, vectorization_mode="async")
        try:
            venv.reset(seed=0)
            venv.action_space.seed(0)
            actions = [venv.action_space.sample() for _ in range(steps + 50)]
            for a in actions[:50]:
                venv.step(a)
            t0 = time.perf_counter()
            for a in actions[50:]:
                venv.step(a)
            wall = time.perf_counter() - t0
        finally:
            venv.close()
        rows.append({"workers": n, "env_steps": steps * n, "wall_s": wall, "steps_s": steps * n / wall,
                     "load": os.getloadavg()[0]})
    return rows


def vector_lines(rows: list[dict], steps: int) -> list[str]:
    lines = ["## Vector envs (async)", "",
             f"`gym.make_vec(\"aas_gym/AcousticGrasp-v0\", num_envs=N, vectorization_mode=\"async\")`, default "
             f"acoustic (records when the action's sense entry is positive), random actions, {steps} vector steps "
             "after 50 of warm-up; wall time (the machine is shared: other jobs slow both alike).", "",
             "| workers | env steps | wall [s] | env steps/s | load average (1 min) |", "|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['workers']} | {r['env_steps']} | {r['wall_s']:.2f} | {r['steps_s']:.0f} | {r['load']:.1f} |"
              for r in rows]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--chunks", type=int, default=40)
    parser.add_argument("--steps", type=int, default=50, help="env steps per chunk")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--robot-chunks", type=int, default=5, help="chunks per robot and sensing mode")
    parser.add_argument("--objects", nargs="+", default=list(DEFAULT_OBJECT_NAMES))
    parser.add_argument("--excitations", nargs="+", default=["impulse", "linear", "exponential"])
    parser.add_argument("--budget-s", type=float, default=4.0, help="CPU seconds per env figure")
    parser.add_argument("--warmup-s", type=float, default=0.0,
                        help="CPU seconds of random actions before each env figure is timed (0: from the first steps)")
    parser.add_argument("--sections", nargs="+", default=["envs", "physics", "robots", "acoustic", "vector"],
                        choices=["envs", "physics", "robots", "acoustic", "vector"])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "env.md")
    parser.add_argument("--vector-steps", type=int, default=2000, help="vector steps per worker count")
    parser.add_argument("--vector-only", action="store_true", help="only the vector-env rows, printed (no file)")
    args = parser.parse_args()
    if args.vector_only:
        print("\n".join(vector_lines(vector_rates((1, 2), args.vector_steps), args.vector_steps)))
        return

    envs = env_throughput(args.budget_s, args.warmup_s) if "envs" in args.sections else None
    lines = [
        "# Environment benchmark",
        "",
        f"`python benchmarks/env.py` on {platform.node() or 'this machine'} ({os.cpu_count()} CPUs, "
        f"shared, 1-minute load average {os.getloadavg()[0]:.1f}), Python {platform.python_version()}, "
        f"MuJoCo {mujoco.__version__}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
        "",
    ]
    if envs is not None:
        lines += env_lines(envs, args.budget_s, args.warmup_s) + [""]
    if "physics" in args.sections:
        phys = physics_ratio(args.chunks, args.steps)
        lines += physics_lines(phys, args)
    if "robots" in args.sections:
        lines += robot_lines(robot_throughput(args.robot_chunks, args.steps), args)
    if "acoustic" in args.sections:
        acoustic = acoustic_cost(args.objects, args.excitations, args.repeats)
        lines += acoustic_lines(acoustic, args)
    if "vector" in args.sections:
        lines += ["", *vector_lines(vector_rates((1, 2), args.vector_steps), args.vector_steps)]
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


def physics_lines(phys: dict, args) -> list[str]:
    return [
        "## Physics throughput without acoustic observations",
        "",
        f"`aas_gym/AcousticGrasp-v0`, `acoustic={{\"cadence\": \"never\"}}`, via `gymnasium.make` (wrappers included), "
        f"frame_skip {phys['frame_skip']} (env dt {phys['env_dt_s']:.3f} s); bare = the same compiled model "
        f"stepped with the same controls from the same states; median of {args.chunks} interleaved chunks "
        f"of {args.steps} env steps; process CPU time.",
        "",
        "| MuJoCo steps/s (env) | MuJoCo steps/s (bare) | ratio env/bare | goal |",
        "|---:|---:|---:|---:|",
        f"| {phys['env_steps_s']:.0f} | {phys['bare_steps_s']:.0f} | {phys['ratio']:.3f} | >= 0.9 |",
        "",
    ]


def robot_lines(robots: list[dict], args) -> list[str]:
    return [
        "## Env steps/s per robot, sensing off and on",
        "",
        f"`aas_gym/AcousticGrasp-v0` via `gymnasium.make`, the same {args.steps} small random actions per chunk, "
        f"median of {args.robot_chunks} chunks (each after a reset); process CPU time. Sensing *on*: "
        "`acoustic={\"cadence\": \"stream\"}` (the microphone records through every physics step); *off*: "
        "`\"never\"`. Relative: against the floating hand with the same sensing.",
        "",
        "| robot | sensing | env steps/s | relative |",
        "|---|---|---:|---:|",
        *[f"| {r['robot']} | {r['sensing']} | {r['steps_s']:.0f} | {r['relative']:.2f} |" for r in robots],
        "",
    ]


def acoustic_lines(acoustic: list[dict], args) -> list[str]:
    lines = [
        "## One 1 s acoustic observation (warm caches)",
        "",
        "Real-time factor = 1 s of recording / CPU time of `SimAcousticSensor.sense` (contacts, "
        "fingertip model, synthesis; 40 N grasp on the table). *Same grasp*: sensed again, the "
        "synthesis reuses its per-grasp system; *new grasp*: a different grasp position every time "
        f"(damping matrix and eigen-decomposition rebuilt). Medians of {args.repeats}. *Cold*: building "
        "the modal model, or loading it from the disk cache, once per object.",
        "",
        "| object | modes | excitation | same grasp [s] | RTF | new grasp [s] | RTF | cold [s] | goal |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in acoustic:
        cold = "" if np.isnan(r["cold_s"]) else f"{r['cold_s']:.2f}"
        lines.append(f"| {r['object']} | {r['modes']} | {r['excitation']} | {r['same_s']:.4f} | "
                     f"{r['rtf_same']:.0f}x | {r['new_s']:.4f} | {r['rtf_new']:.0f}x | {cold} | >= 20x |")
    worst = min(r["rtf_new"] for r in acoustic)
    lines += ["", f"Slowest case: {worst:.0f}x real time (goal >= 20x)."]
    below = sorted({(r["object"], r["modes"]) for r in acoustic if min(r["rtf_new"], r["rtf_same"]) < 20})
    if below:
        lines += ["", "Below the goal: " + ", ".join(f"{o} ({n} modes)" for o, n in below) + ". A new grasp "
                  "rebuilds the synthesis' per-grasp system (contact damping, eigen-decomposition of the "
                  "2r-state system in `sensors.synthesis.modal_system`), whose cost grows with the number of modes up to "
                  "the modal model's band limit (22.05 kHz by default); `SimAcousticSensor(modal_options="
                  "{'max_frequency_hz': ...})` trades feature accuracy for speed."]
    return lines


if __name__ == "__main__":
    main()
