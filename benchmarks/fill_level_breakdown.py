"""Where a FillLevel-v0 episode's time goes: MuJoCo steps and CPU ms per episode in the settle,
the first release and the scripted grasp, and the Python around them.

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/fill_level_breakdown.py [--sensing on|off]
        [--reference] [--episodes 40] [--profile 25] [--parts] [--object mug]

Every ``mujoco.mj_step`` call is counted and timed under the phase that made it (``settle`` and
``aas_gym.rest_states.settle_from``, ``release``, ``planar_grasp``, and the rest grid's canonical
settles, once per grid fill); the rest of the episode's
CPU time is "other" (the fill's wet model, placement, sensing, gymnasium).  ``--profile N``
prints cProfile's N most expensive functions by own time.  ``--parts``: exclusive CPU ms per
episode of each part (the fill, the wet eigen-solve, the contacts, the springs, the system's
eigen-solve, the drive, the window spectra, ...: :data:`PARTS`), a part's time without the parts
it calls.  Not an A/B (``flags_ab.py aas_gym/FillLevel-v0 --flags aas_gym.rest_states:REST_STATES`` is).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import gymnasium as gym
import mujoco

import aas_gym  # noqa: F401  (registers the envs)
import aas_gym.envs.fill_level as fill_level
from aas_gym import rest_states
from aas_gym.envs import base
from _exclusive import SENSING_PARTS, ExclusiveTimes  # benchmarks/, the script's folder


#: ``--parts``: (module, class or None, function, label); a module-level function is timed
#: wherever it was imported by name.
PARTS = (
    ("aas_gym.envs.fill_level", "FillLevelEnv", "_fill", "fill: wet model (rest)"),
    ("sensors.fluid.fill_table", "_Segment", "at", "fill: table interpolation"),
    ("sensors.fluid.fill_table", None, "liquid_coupling", "fill: liquid modes (eigh)"),
    ("sensors.fluid.filled_model", "FilledModalModel", "__init__", "fill: FilledModalModel()"),
    ("aas_gym.envs.fill_level", "FillLevelEnv", "_set_liquid_mass", "fill: MuJoCo mass"),
    ("sensors.fluid.filled_model", "FilledModalModel", "_wet_solution", "wet: eigen-solve"),
    ("sensors.fluid.filled_model", "FilledModalModel", "rigid_coefficients", "wet: rigid modes"),
    ("sensors.fluid.filled_model", "FilledModalModel", "mode_shapes_at", "wet: shapes at points"),
    ("sensors.fluid.filled_model", "FilledModalModel", "rigid_mode_shapes_at", "wet: rigid shapes at points"),
    ("sensors.fluid.container", "Container", "basis_shapes_at", "wet: basis at points"),
)


def _parts(env, n: int) -> None:
    times = ExclusiveTimes(PARTS + SENSING_PARTS, clock=time.thread_time, everywhere=True)
    with times:
        for s in range(5):
            env.reset(seed=s)
        times.reset()
        t0 = time.thread_time()
        for s in range(n):
            env.reset(seed=s)
        total = time.thread_time() - t0
    spent = dict(times.seconds)
    print(f"exclusive CPU ms per episode (thread time; {n} episodes, {total / n * 1e3:.2f} ms each):")
    spent["other"] = total - sum(spent.values())
    for k, v in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {k:34s} {v / n * 1e3:7.3f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sensing", choices=("on", "off"), default="off")
    p.add_argument("--reference", action="store_true", help="aas_gym.rest_states.REST_STATES = False (the whole settle)")
    p.add_argument("--episodes", type=int, default=40)
    p.add_argument("--warmup", type=int, default=200, help="episodes first (caches, the rest grid)")
    p.add_argument("--profile", type=int, default=0)
    p.add_argument("--parts", action="store_true", help="exclusive CPU time per part (PARTS) instead")
    p.add_argument("--object", default="mug", help="the container (mug, glass, can, bottle)")
    args = p.parse_args()
    rest_states.REST_STATES = not args.reference
    env = gym.make("aas_gym/FillLevel-v0", disable_env_checker=True, objects=(args.object,),
                   acoustic={"enabled": args.sensing == "on"}).unwrapped
    for s in range(args.warmup):
        env.reset(seed=10_000 + s)
    if args.parts:
        _parts(env, args.episodes)
        return
    phase, steps, cpu = ["other"], {}, {}
    step = mujoco.mj_step

    def counted(m, d, nstep=1):
        t = time.process_time()
        step(m, d, nstep=nstep)
        steps[phase[0]] = steps.get(phase[0], 0) + nstep
        cpu[phase[0]] = cpu.get(phase[0], 0.0) + time.process_time() - t

    def under(module, name: str, label: str) -> None:
        f = getattr(module, name)

        def g(*a, **k):
            outer, phase[0] = phase[0], label
            try:
                return f(*a, **k)
            finally:
                phase[0] = outer
        setattr(module, name, g)

    mujoco.mj_step = counted
    under(base, "settle", "settle")
    under(fill_level, "settle_from", "settle")
    under(base, "release", "release")
    under(base, "planar_grasp", "grasp")
    under(rest_states.RestStates, "_grid_state", "rest grid")   # a grid fill's canonical settle, once
    n = args.episodes
    t0 = time.process_time()
    for s in range(n):
        env.reset(seed=s)
    total = time.process_time() - t0
    print(f"FillLevel-v0, sensing {args.sensing}, REST_STATES {not args.reference}: {total / n * 1e3:.2f} ms/episode")
    for k in steps:
        print(f"  {k:8s} {steps[k] / n:6.1f} mj_step  {cpu[k] / n * 1e3:6.2f} ms")
    print(f"  other    {(total - sum(cpu.values())) / n * 1e3:6.2f} ms (no mj_step)")
    if args.profile:
        mujoco.mj_step = step
        prof = cProfile.Profile()
        prof.enable()
        for s in range(n):
            env.reset(seed=s)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(args.profile)


if __name__ == "__main__":
    main()
