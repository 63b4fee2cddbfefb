"""A/B in one process: FillLevel-v0 with ``aas_gym.rest_states.REST_STATES`` on and off.

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/rest_states_ab.py [--blocks 6] [--block-s 3] [--only FillLevel]

Default config (the mug, water, fill uniform in 0-0.9, default randomization), resets and the
one answering step included, episodes per CPU second with sensing on and off; the two paths
alternate in blocks of ``--block-s`` CPU seconds (order flipped every block) so that load from
other processes hits both alike, after a warm-up of each (modal caches, the rest grid).  Reports
the median block of each path and their ratio.  GraspPosition-v0 and ObjectRecognition-v0 run
the same way (steps/s): the flag does not touch them, so their ratio says what the noise is.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym import rest_states

CASES = (("FillLevel-v0", "aas_gym/FillLevel-v0", {}, "episodes"),
         ("FillLevel-v0", "aas_gym/FillLevel-v0", {"acoustic": {"enabled": False}}, "episodes"),
         ("GraspPosition-v0", "aas_gym/GraspPosition-v0", {}, "steps"),
         ("ObjectRecognition-v0", "aas_gym/ObjectRecognition-v0", {}, "steps"))


def _run(env, budget_s: float, seed: int) -> tuple[int, float, int]:
    """Random-action steps with resets for ``budget_s`` CPU seconds: (steps, seconds, next seed)."""
    n, t0 = 0, time.process_time()
    done = True
    while time.process_time() - t0 < budget_s:
        if done:
            env.reset(seed=seed)
            env.action_space.seed(seed)
            seed += 1
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
        n += 1
    return n, time.process_time() - t0, seed


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blocks", type=int, default=6)
    p.add_argument("--block-s", type=float, default=3.0)
    p.add_argument("--warmup-s", type=float, default=8.0)
    p.add_argument("--only", default="", help="run only the envs whose name contains this")
    args = p.parse_args()
    print("| env | sensing | REST_STATES on [/s] | off [/s] | on / off |")
    print("|---|---|---|---|---|")
    for label, env_id, kwargs, unit in CASES:
        if args.only not in label:
            continue
        env = gym.make(env_id, disable_env_checker=True, **kwargs)
        seed = 0
        for flag in (True, False):
            rest_states.REST_STATES = flag
            seed = _run(env, args.warmup_s, seed)[2]
        rates = {True: [], False: []}
        for b in range(args.blocks):
            for flag in ((True, False) if b % 2 == 0 else (False, True)):
                rest_states.REST_STATES = flag
                n, dt, seed = _run(env, args.block_s, seed)
                rates[flag].append(n / dt)
        rest_states.REST_STATES = True    # the default
        on, off = (sorted(rates[f])[len(rates[f]) // 2] for f in (True, False))
        sensing = "off" if kwargs.get("acoustic", {}).get("enabled", True) is False else "on"
        print(f"| {label} | {sensing} | {on:.1f} {unit} | {off:.1f} {unit} | {on / off:.2f} |", flush=True)
        env.close()


if __name__ == "__main__":
    main()
