"""Train PPO (Stable-Baselines3, CPU) on two aas-gym tasks and save the learning curves.

    python examples/train_ppo.py [--grasp-steps 30000] [--recognition-steps 3000] [--seed 0]

1. ``aas_gym/AcousticGrasp-v0``: reach, grasp and sense an aluminium bar (dense reward: minus
   the TCP-object distance, +1 while grasped, +10 for a recording of the grasped object).
2. ``aas_gym/ObjectRecognition-v0`` on two objects that differ only in material (aluminium and
   steel bars): probe with a grasp and an excitation, then name the object. Every probe
   simulates a grasp and a 0.5 s recording, so its steps are far slower than the grasp task's.

The acoustic features are given to the policy in dB (``acoustic={"feature_scale": "db"}``):
the raw amplitudes (1e-7 to 1e-4) next to proprioception of order 1 to 40 would be invisible to
the network without normalization. Both tasks use SB3's default ``MultiInputPolicy`` for the
Dict observations and the envs' default Box actions, which SB3's ``check_env`` accepts.

Saves ``outputs/train_ppo.png`` (episode return against environment steps, both tasks) and
prints the wall time of each run. Needs the ``rl`` extra (``pip install -e '.[rl]'``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import aas_gym  # noqa: F401  (registers the envs; headless rendering defaults)
import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

ACOUSTIC = {"feature_scale": "db"}


def train(env_id: str, steps: int, seed: int, acoustic: dict | None = None,
          **env_kwargs) -> tuple[np.ndarray, np.ndarray, float]:
    """PPO for ``steps`` environment steps; returns (episode end steps, episode returns, wall s)."""
    env = Monitor(gym.make(env_id, acoustic={**ACOUSTIC, **(acoustic or {})}, **env_kwargs))
    model = PPO("MultiInputPolicy", env, seed=seed, verbose=0, n_steps=512, batch_size=128,
                device="cpu")
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, progress_bar=False)
    wall = time.perf_counter() - t0
    lengths = np.asarray(env.get_episode_lengths(), dtype=float)
    returns = np.asarray(env.get_episode_rewards(), dtype=float)
    env.close()
    return np.cumsum(lengths), returns, wall


def smooth(y: np.ndarray, window: int = 20) -> np.ndarray:
    if y.size < window:
        return y
    return np.convolve(y, np.ones(window) / window, mode="valid")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grasp-steps", type=int, default=30000)
    parser.add_argument("--recognition-steps", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=OUTPUTS)
    args = parser.parse_args()

    runs = {
        "AcousticGrasp-v0 (aluminium bar)": train("aas_gym/AcousticGrasp-v0", args.grasp_steps, args.seed,
                                                  objects=["aluminium_bar"], max_episode_steps=100),
        "ObjectRecognition-v0 (aluminium vs steel bar)": train(
            "aas_gym/ObjectRecognition-v0", args.recognition_steps, args.seed,
            objects=["aluminium_bar", "steel_bar"], acoustic={"duration_s": 0.5}, max_episode_steps=10),
    }
    fig, axes = plt.subplots(1, len(runs), figsize=(11, 3.8), constrained_layout=True)
    for ax, (name, (x, y, wall)) in zip(axes, runs.items()):
        ax.plot(x, y, ".", ms=2, alpha=0.3, color="C0", label="episode return")
        w = min(20, max(1, y.size // 5))
        if y.size >= w:
            ax.plot(x[w - 1:], smooth(y, w), color="C1", lw=1.5, label=f"mean of {w} episodes")
        ax.set(title=f"{name}\nPPO, {x[-1] if x.size else 0:.0f} steps, {wall / 60:.1f} min wall",
               xlabel="environment steps", ylabel="episode return")
        ax.legend(fontsize=7)
        print(f"{name}: {len(y)} episodes, wall {wall:.0f} s, first/last 20 mean return "
              f"{np.mean(y[:20]):.2f} / {np.mean(y[-20:]):.2f}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "train_ppo.png", dpi=110)
    print(f"wrote {out / 'train_ppo.png'}")


if __name__ == "__main__":
    main()
