"""What MuJoCo alone costs per env step: the floor under every env's rate (issue 27).

    OMP_NUM_THREADS=1 python benchmarks/physics_floor.py [--warmup-steps 1000] [--env-steps 300] \
        [--repeats 5] [--envs aas_gym/FillLevel-v0 ...] [--out docs/benchmarks/physics_floor.md]

Each env runs ``--warmup-steps`` random steps first (a long run's physics: FillLevel-v0 settles
each grid fill's rest once, 200 steps, and the physics memos fill), then ``--env-steps`` random
steps (seeded, sensing off, resets included) while every
``mujoco.mj_step`` call it makes is split into single physics steps and the integration state
before each is kept (``mj_step`` with ``nstep=k`` is k single steps, so the env's run is
unchanged). Those states are then replayed on a scratch ``MjData``, stage by stage, and only the
replays are timed (the median of ``--repeats``), ``mj_step`` whole and its stages one by one in
its order: the position stage (kinematics, collision and the constraints' set-up), of it
collision alone, velocity, actuation and acceleration, the constraint solve, and the integration. Beside them: contacts,
constraint rows and solver iterations per physics step, physics steps per env step, and the
floor, 1 / (physics steps per env step x time per physics step): the rate of an env whose
Python and sensing cost nothing. A goal above the floor is out of reach for the physics as
modelled (geoms, solver settings); below it, the rest is the env's own.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from pathlib import Path

import aas_gym  # noqa: F401  (registers the envs)
import gymnasium as gym
import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
ENVS = ("aas_gym/AcousticGrasp-v0", "aas_gym/ContactFormation-v0", "aas_gym/GraspPosition-v0",
        "aas_gym/ObjectRecognition-v0", "aas_gym/FillLevel-v0")
GOALS = {"aas_gym/AcousticGrasp-v0": 1000, "aas_gym/ContactFormation-v0": 1000, "aas_gym/GraspPosition-v0": 500,
         "aas_gym/ObjectRecognition-v0": 500, "aas_gym/FillLevel-v0": 200}
SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


def capture(env_id: str, env_steps: int, warmup_steps: int, seed: int = 0) -> tuple[dict, int]:
    """{model: [states]} of every physics step ``env_steps`` random env steps take after
    ``warmup_steps``, and the number of env steps (a one-step episode's reset counts with its step)."""
    env = gym.make(env_id, acoustic={"enabled": False})
    env.reset(seed=seed)
    env.action_space.seed(seed)

    def run(n: int) -> None:
        for _ in range(n):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()

    run(warmup_steps)
    states: dict = {}
    original = mujoco.mj_step

    def split_step(model, data, nstep=1):
        for _ in range(nstep):
            s = np.empty(mujoco.mj_stateSize(model, SPEC))
            mujoco.mj_getState(model, data, s, SPEC)
            states.setdefault(model, []).append(s)
            original(model, data)

    mujoco.mj_step = split_step
    try:
        run(env_steps)
    finally:
        mujoco.mj_step = original
        env.close()
    return states, env_steps


_INTEGRATORS = {int(mujoco.mjtIntegrator.mjINT_EULER): mujoco.mj_Euler,
                int(mujoco.mjtIntegrator.mjINT_RK4): mujoco.mj_RungeKutta,
                int(mujoco.mjtIntegrator.mjINT_IMPLICIT): mujoco.mj_implicit,
                int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): mujoco.mj_implicit}


def replay_us(model, states: list, repeats: int) -> dict:
    """Median µs per physics step: ``mj_step`` whole, and its stages timed one by one in the
    order ``mj_step`` runs them (position, velocity/actuation/acceleration, constraint solve,
    integration; collision timed on its own afterwards, on the same kinematics), with contacts, constraint rows
    and solver iterations per step."""
    data = mujoco.MjData(model)
    integrate = _INTEGRATORS[int(model.opt.integrator)]
    if integrate is mujoco.mj_RungeKutta:
        integrate = lambda m, d: mujoco.mj_RungeKutta(m, d, 4)  # noqa: E731
    clock = time.perf_counter_ns
    names = ("position", "collision", "to_acceleration", "solve", "integrate", "step")
    runs = {k: [] for k in names}
    for _ in range(repeats):
        acc = dict.fromkeys(names, 0)
        for s in states:
            mujoco.mj_setState(model, data, s, SPEC)
            t0 = clock()
            mujoco.mj_fwdPosition(model, data)
            t2 = clock()
            mujoco.mj_fwdVelocity(model, data)
            mujoco.mj_fwdActuation(model, data)
            mujoco.mj_fwdAcceleration(model, data)
            t3 = clock()
            mujoco.mj_fwdConstraint(model, data)
            t4 = clock()
            integrate(model, data)
            t5 = clock()
            mujoco.mj_setState(model, data, s, SPEC)
            t6 = clock()
            mujoco.mj_step(model, data)
            t7 = clock()
            # collision alone, again on the state's kinematics (it resets the constraint rows: last)
            mujoco.mj_setState(model, data, s, SPEC)
            mujoco.mj_fwdPosition(model, data)
            t8 = clock()
            mujoco.mj_collision(model, data)
            t9 = clock()
            for k, dt in zip(names, (t2 - t0, t9 - t8, t3 - t2, t4 - t3, t5 - t4, t7 - t6)):
                acc[k] += dt
        for k in names:
            runs[k].append(acc[k] / len(states) / 1e3)
    out = {k: statistics.median(v) for k, v in runs.items()}
    ncon, nefc, iters = [], [], []
    for s in states:
        mujoco.mj_setState(model, data, s, SPEC)
        mujoco.mj_step(model, data)
        ncon.append(data.ncon)
        nefc.append(data.nefc)
        iters.append(int(data.solver_niter[0]))
    out.update(ncon=float(np.mean(ncon)), nefc=float(np.mean(nefc)), iterations=float(np.mean(iters)))
    return out


def measure(env_id: str, env_steps: int, warmup_steps: int, repeats: int) -> dict:
    states, n = capture(env_id, env_steps, warmup_steps)
    total = sum(len(v) for v in states.values())
    if not total:
        return {"env": env_id, "physics_per_env_step": 0.0}
    # models weighted by their share of the steps (an env may compile several scenes)
    parts = [(len(v) / total, replay_us(m, v, repeats)) for m, v in states.items()]
    row = {k: sum(w * p[k] for w, p in parts) for k in parts[0][1]}
    row["env"] = env_id
    row["geoms"] = max(m.ngeom for m in states)
    row["mesh_geoms"] = max(int(np.sum(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)) for m in states)
    row["physics_per_env_step"] = total / n
    row["floor"] = 1e6 / (row["physics_per_env_step"] * row["step"])
    return row


def lines(rows: list[dict], env_steps: int, warmup_steps: int, repeats: int) -> list[str]:
    out = [
        "# Physics floor: what MuJoCo alone costs per env step",
        "",
        f"`python benchmarks/physics_floor.py --warmup-steps {warmup_steps} --env-steps {env_steps} --repeats {repeats}` "
        f"on {platform.node()} "
        f"(Python {platform.python_version()}, MuJoCo {mujoco.__version__}), "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Every physics step of {env_steps} random env steps "
        f"after {warmup_steps} (sensing off, resets included) replayed from its state on a scratch `MjData`, stage by stage; µs "
        f"per physics step (wall clock of this process, nothing else running), median of {repeats}; the stages are "
        "timed one by one in `mj_step`'s order, `mj_step` whole on its own. *Position*: kinematics, collision and the constraints' set-up "
        "(`mj_fwdPosition`); *collision*: `mj_collision` alone, again on the same kinematics; *vel/act/acc*: `mj_fwdVelocity`, "
        "`mj_fwdActuation`, `mj_fwdAcceleration`; *solve*: `mj_fwdConstraint`; *integrate*: the integrator's step. "
        "*Floor*: env steps/s if the env's Python and sensing cost nothing (for the one-step-episode envs, "
        "episodes/s).",
        "",
        "| env | mesh geoms / geoms | contacts | constraint rows | solver iterations | position (collision) | "
        "vel/act/acc | solve | integrate | `mj_step` | physics steps per env step | floor [env steps/s] | goal |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        if not r["physics_per_env_step"]:
            out.append(f"| {r['env'].split('/')[-1]} | | | | | | | | | | 0 | no physics | {GOALS.get(r['env'], '')} |")
            continue
        vaa, solve, integrate = r["to_acceleration"], r["solve"], r["integrate"]
        out.append(
            f"| {r['env'].split('/')[-1]} | {r['mesh_geoms']} / {r['geoms']} | {r['ncon']:.1f} | {r['nefc']:.0f} | "
            f"{r['iterations']:.1f} | {r['position']:.0f} ({r['collision']:.0f}) | {vaa:.0f} | {solve:.0f} | "
            f"{integrate:.0f} | {r['step']:.0f} | {r['physics_per_env_step']:.1f} | {r['floor']:.0f} | "
            f"{GOALS.get(r['env'], '')} |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--envs", nargs="+", default=list(ENVS))
    ap.add_argument("--env-steps", type=int, default=300, help="random env steps captured per env")
    ap.add_argument("--warmup-steps", type=int, default=1000, help="random env steps run before the capture")
    ap.add_argument("--repeats", type=int, default=5, help="replays per stage (the median is kept)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks" / "physics_floor.md")
    args = ap.parse_args()
    if args.env_steps < 1 or args.repeats < 1 or args.warmup_steps < 0:
        ap.error("--env-steps and --repeats must be at least 1, --warmup-steps at least 0")
    rows = []
    for env_id in args.envs:
        rows.append(measure(env_id, args.env_steps, args.warmup_steps, args.repeats))
        print(f"{env_id}: done", flush=True)
    text = "\n".join(lines(rows, args.env_steps, args.warmup_steps, args.repeats)) + "\n"
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
