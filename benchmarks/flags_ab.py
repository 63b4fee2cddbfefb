"""A/B of module flags on one env in one process: blocks of CPU seconds alternating the flags on
and off (the order alternating too), after a warm-up with both, so load from other processes
and the caches' filling hit both sides alike.

    python benchmarks/flags_ab.py aas_gym/GraspPosition-v0 --flags sensors.modal.contact:FAST_CONTACT_CHECKS \\
        sensors.synthesis.lti:SYMMETRIC_GAINS [--warmup-s 20] [--block-s 5] [--blocks 10] [--sensing-off]
    python benchmarks/flags_ab.py aas_gym/FillLevel-v0 --flags aas_gym.rest_states:REST_STATES

Prints env steps/s, episodes/s and CPU ms per episode (``time.process_time``) with the flags on
and off.  Random actions (seeded), resets included, the env's defaults otherwise
(``--sensing-off``: ``acoustic={"enabled": False}``).  A flag an env does not read gives a ratio
that says what the noise is.
"""

from __future__ import annotations

import argparse
import importlib
import time

import aas_gym  # noqa: F401  (registers the envs)
import gymnasium as gym


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env_id")
    ap.add_argument("--flags", nargs="+", required=True, help="module:NAME of boolean module flags")
    ap.add_argument("--warmup-s", type=float, default=20.0)
    ap.add_argument("--block-s", type=float, default=5.0)
    ap.add_argument("--blocks", type=int, default=10)
    ap.add_argument("--sensing-off", action="store_true", help='acoustic={"enabled": False}')
    args = ap.parse_args()
    flags = [(importlib.import_module(m), f) for m, f in (x.split(":") for x in args.flags)]

    def set_flags(value: bool) -> None:
        for module, name in flags:
            if not hasattr(module, name):
                raise AttributeError(f"{module.__name__} has no flag {name}")
            setattr(module, name, value)

    env = gym.make(args.env_id, **({"acoustic": {"enabled": False}} if args.sensing_off else {}))
    env.reset(seed=0)
    env.action_space.seed(0)

    def run(seconds: float):
        t0, steps, episodes = time.process_time(), 0, 0
        while time.process_time() - t0 < seconds:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            steps += 1
            if terminated or truncated:
                env.reset()
                episodes += 1
        return steps, episodes, time.process_time() - t0

    for value in (True, False):
        set_flags(value)
        run(args.warmup_s / 2)
    totals = {True: [0, 0, 0.0], False: [0, 0, 0.0]}
    for b in range(args.blocks):
        for value in ((True, False) if b % 2 else (False, True)):
            set_flags(value)
            for i, x in enumerate(run(args.block_s)):
                totals[value][i] += x
    for value in (True, False):
        steps, episodes, cpu = totals[value]
        print(f"{args.env_id} flags {'on ' if value else 'off'}: {steps / cpu:7.1f} steps/s {episodes / cpu:7.1f} "
              f"episodes/s {1e3 * cpu / max(episodes, 1):7.2f} ms/episode ({episodes} episodes, {cpu:.0f} CPU s)")
    env.close()


if __name__ == "__main__":
    main()
