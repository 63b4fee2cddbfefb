"""Train PPO with the acoustic feature extractor of ``aas_gym.rl`` and log to TensorBoard.

    python examples/train_with_extractor.py [--env GraspPosition-v0] [--timesteps 2048] [--out DIR]
    tensorboard --logdir DIR

The policy reads the Dict observation through ``aas_gym.rl.AcousticExtractor``: the 140
acoustic features (in dB) through a small 1-D CNN, proprioception flattened. The default task
is ``aas_gym/GraspPosition-v0`` (one grasp per episode, estimate where from the sound); its
``is_success`` (within half a grid spacing) is logged as ``rollout/success_rate``. The budget
is short: a demonstration that the extractor trains, not a tuned result.

Writes the TensorBoard run and the trained model to ``--out`` (default: the repository's
``outputs/train_with_extractor``, whatever the current folder). Needs the ``rl`` extra
(stable-baselines3, torch, tensorboard).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import aas_gym  # noqa: F401  (registers the envs)
import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor

from aas_gym.rl import AcousticExtractor

HERE = Path(__file__).resolve().parent


def positive_integer(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    envs = sorted(k.removeprefix("aas_gym/") for k in gym.registry if k.startswith("aas_gym/"))
    ap.add_argument("--env", default="GraspPosition-v0", choices=envs, help="an aas_gym env id (without the aas_gym/ prefix)")
    ap.add_argument("--timesteps", type=positive_integer, default=2048, help="PPO steps (256 is one rollout, the smallest)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=HERE.parent / "outputs" / "train_with_extractor",
                    help="folder of the TensorBoard run and the saved model")
    args = ap.parse_args(argv)
    # SB3 on a small CPU: one intra-op thread trains faster than several fighting for 2 cores.
    torch.set_num_threads(1)
    env = Monitor(gym.make(f"aas_gym/{args.env}", acoustic={"feature_scale": "db"}), info_keywords=("is_success",))
    model = PPO("MultiInputPolicy", env, n_steps=256, batch_size=64, seed=args.seed, device="cpu", verbose=1,
                tensorboard_log=str(args.out),
                policy_kwargs=dict(features_extractor_class=AcousticExtractor,
                                   features_extractor_kwargs=dict(audio_features_dim=64)))
    print(model.policy.features_extractor)
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, tb_log_name=args.env)
    print(f"{args.timesteps} steps in {time.perf_counter() - t0:.0f} s")
    args.out.mkdir(parents=True, exist_ok=True)
    model.save(args.out / f"ppo_{args.env}")
    env.close()
    print(f"wrote {args.out} (tensorboard --logdir {args.out})")
    return args.out


if __name__ == "__main__":
    main()
