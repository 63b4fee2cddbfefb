"""Train PPO (Stable-Baselines3, CPU, one thread) on ObjectRecognition-v0 or GraspPosition-v0
for a wall-clock budget, evaluate on held-out seeds, and plot the learning curves.

    python examples/train_ppo.py --env ObjectRecognition-v0 --minutes 15 --seed 0
    python examples/train_ppo.py --env GraspPosition-v0 --minutes 15 --seed 0
    python examples/train_ppo.py --plot-only          # redraw the figure from the saved logs

``ObjectRecognition-v0`` (the paper's seven objects): each step either probes (grasp position,
excitation) or answers a label; reward 1 for a right answer, minus ``probe_cost`` per probe,
so the mean return is the accuracy minus the probing cost. ``GraspPosition-v0`` (wood bar, 13
positions 0-60 mm): one recording, one estimate, reward minus the absolute error [m].

What makes these learnable in minutes (measured: the env's defaults learn slowly or not at all):

- Features in dB (``feature_scale="db"``) and ``VecNormalize`` on the observations: raw
  amplitudes of 1e-7..1e-4 next to proprioception of order 1 are invisible to the network.
- ObjectRecognition's Box(4) action (continuous numbers cut into bins) is re-expressed as
  ``MultiDiscrete`` (one of 5 grasp positions, excitation, label) by
  :class:`DiscreteRecognitionActions`: the same env actions (each maps to a bin centre), but a
  categorical policy per choice instead of Gaussians whose bins the gradient cannot see; and
  every episode is the paper's sequence, one probe, then the answer. Measured: with a learnt
  answer/probe switch and 4-step episodes, PPO at 3k steps probed until the time limit and
  never answered (7 % accuracy).
- GraspPosition's reward (metres, ~0.02) is normalized by ``VecNormalize``; its Gaussian
  policy starts with a smaller spread (``log_std_init=-1``).

Contacts are the envs' own, springs with coupled touching bodies (``--contact-model damping``
trains with the paper's cheaper damping-only model instead). A new grasp costs ~10 ms once the
object's unit-load solves are kept (``sensors.modal.unit_load_files``): the first run on a
machine fills them, later runs read them.

Writes ``<out>/ppo_<env>.json`` (evaluation log), ``<out>/ppo_<env>.zip`` (the policy) and
the figure of every log found in ``<out>`` (default ``docs/images/ppo_curves.png``). Paths are
relative to this script's folder unless absolute. Needs the ``rl`` extra.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import aas_gym  # noqa: F401  (registers the envs; headless rendering defaults)
import gymnasium as gym
import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

HERE = Path(__file__).resolve().parent
ENVS = ("ObjectRecognition-v0", "GraspPosition-v0")
#: Acoustic settings of both tasks (see the module docstring for why).
ACOUSTIC = {"feature_scale": "db", "contact_model": "spring_damper"}
#: Grasp positions the recognition policy chooses from (fractions of the env's max_position_m, 50 mm).
PROBE_POSITIONS = np.linspace(-1.0, 1.0, 5)
RECOGNITION_MAX_STEPS = 4  # a cap only: the wrapper answers at step 2
#: Held-out evaluation seeds start here (training episodes draw from the training seed's stream).
EVAL_SEED0 = 1_000_000


class DiscreteRecognitionActions(gym.ActionWrapper):
    """ObjectRecognition-v0 with a ``MultiDiscrete([len(positions), n_excitations, n_labels])``
    action: (grasp position index, excitation index, label index), each mapped onto the centre
    of the env's Box(4) bin (positions onto ``positions``, fractions in [-1, 1]). The first
    ``n_probes`` steps of an episode probe (the label is ignored), the next one answers (position
    and excitation ignored): the paper's sequence, grasp and excite, then name. The policy sees
    the phase in the observation's ``n_probes``."""

    def __init__(self, env: gym.Env, positions=PROBE_POSITIONS, n_probes: int = 1) -> None:
        super().__init__(env)
        base = env.unwrapped
        self.positions = np.asarray(positions, dtype=float)
        self.n_probes = int(n_probes)
        self.n_excitations, self.n_labels = len(base.excitations), len(base.labels)
        self.action_space = spaces.MultiDiscrete([len(self.positions), self.n_excitations, self.n_labels])
        self.probes_done = 0

    def reset(self, **kwargs):
        self.probes_done = 0
        return self.env.reset(**kwargs)

    def step(self, action):
        result = self.env.step(self.action(action))
        self.probes_done += 1
        return result

    def action(self, action) -> np.ndarray:
        p, e, label = (int(x) for x in action)
        answer = self.probes_done >= self.n_probes
        centre = lambda k, n: -1.0 + (2 * k + 1) / n  # noqa: E731  (the bin centre in [-1, 1])
        return np.array([1.0 if answer else -1.0, self.positions[p], centre(e, self.n_excitations),
                         centre(label, self.n_labels)], np.float32)


def make_env(env_id: str) -> gym.Env:
    """One env of the task as trained here (see the module docstring)."""
    if env_id == "ObjectRecognition-v0":
        env = gym.make("aas_gym/ObjectRecognition-v0", acoustic=ACOUSTIC, max_episode_steps=RECOGNITION_MAX_STEPS)
        return DiscreteRecognitionActions(env)
    if env_id == "GraspPosition-v0":
        return gym.make("aas_gym/GraspPosition-v0", acoustic=ACOUSTIC)
    raise ValueError(f"env must be one of {ENVS}, got {env_id!r}")


def evaluate(model: PPO, vec_norm: VecNormalize, env: gym.Env, env_id: str, n_episodes: int) -> dict:
    """Deterministic policy on held-out seeds ``EVAL_SEED0 + i``: accuracy (ObjectRecognition,
    targets cycled through the labels) or position RMSE [mm] (GraspPosition, positions cycled),
    with what the policy chose."""
    base = env.unwrapped
    n_cases = len(base.labels) if env_id == "ObjectRecognition-v0" else len(base.positions_m)
    key = "label_index" if env_id == "ObjectRecognition-v0" else "position_index"
    correct, errors_m, probes, chosen = [], [], [], []
    for i in range(n_episodes):
        obs, info = env.reset(seed=EVAL_SEED0 + i, options={key: i % n_cases})
        n_probes, done = 0, False
        while not done:
            action, _ = model.predict(vec_norm.normalize_obs(obs), deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            if env_id == "ObjectRecognition-v0" and not terminated:
                n_probes += 1
                chosen.append([int(action[0]), int(action[1])])  # position index, excitation index
        if env_id == "ObjectRecognition-v0":
            correct.append(bool(info.get("is_success", False)))
            probes.append(n_probes)
        else:
            errors_m.append(info["estimate_m"] - info["grasp_position_m"])
            chosen.append(info["estimate_m"])
    if env_id == "ObjectRecognition-v0":
        return {"accuracy": float(np.mean(correct)), "mean_probes": float(np.mean(probes)), "probes": chosen}
    return {"rmse_mm": float(np.sqrt(np.mean(np.square(errors_m))) * 1e3), "estimates_m": chosen}


class EvalAndBudget(BaseCallback):
    """Evaluates every ``eval_every`` steps and stops training after ``budget_s`` of wall time."""

    def __init__(self, env_id: str, budget_s: float, eval_every: int, n_eval: int) -> None:
        super().__init__()
        self.env_id, self.budget_s, self.eval_every, self.n_eval = env_id, budget_s, eval_every, n_eval
        self.eval_env = make_env(env_id)
        self.log: list[dict] = []
        self.t0 = time.perf_counter()
        self.eval_s = 0.0
        self.next_eval = 0

    def run_eval(self) -> None:
        t = time.perf_counter()
        result = evaluate(self.model, self.training_env, self.eval_env, self.env_id, self.n_eval)
        self.eval_s += time.perf_counter() - t
        result.update(steps=int(self.num_timesteps), wall_s=time.perf_counter() - self.t0)
        self.log.append(result)
        summary = {k: v for k, v in result.items() if not isinstance(v, list)}
        print(json.dumps(summary), flush=True)

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_eval:
            self.run_eval()
            self.next_eval += self.eval_every
        return time.perf_counter() - self.t0 < self.budget_s


def train(env_id: str, minutes: float, seed: int, out: Path, n_eval: int, eval_every: int) -> dict:
    """PPO on ``env_id`` for ``minutes`` of wall time (evaluations included); returns the log."""
    torch.set_num_threads(1)
    recognition = env_id == "ObjectRecognition-v0"
    venv = VecNormalize(DummyVecEnv([lambda: make_env(env_id)] * 8), norm_obs=True, norm_reward=not recognition,
                        gamma=0.99)
    venv.seed(seed)
    policy_kwargs = {"net_arch": [128, 128]} if recognition else {"net_arch": [128, 128], "log_std_init": -1.0}
    model = PPO("MultiInputPolicy", venv, seed=seed, device="cpu", verbose=0, n_steps=64, batch_size=128,
                learning_rate=5e-4, n_epochs=10, gamma=0.99, gae_lambda=0.95,
                ent_coef=0.01 if recognition else 0.0, policy_kwargs=policy_kwargs)
    load_at_start = os.getloadavg()
    callback = EvalAndBudget(env_id, minutes * 60.0, eval_every, n_eval)
    model.learn(total_timesteps=10**9, callback=callback, progress_bar=False)
    callback.run_eval()  # the final policy
    wall_s = time.perf_counter() - callback.t0
    log = {"env": env_id, "seed": seed, "minutes": minutes, "steps": int(model.num_timesteps), "wall_s": wall_s,
           "train_steps_per_s": model.num_timesteps / max(wall_s - callback.eval_s, 1e-9),
           "load_average": os.getloadavg(), "load_average_at_start": load_at_start, "acoustic": ACOUSTIC,
           "evaluations": callback.log}
    if recognition:
        log["probe_positions_mm"] = (PROBE_POSITIONS * venv.envs[0].unwrapped.max_position_m * 1e3).tolist()
        log["excitations"] = [e.kind for e in venv.envs[0].unwrapped.excitations]
    out.mkdir(parents=True, exist_ok=True)
    (out / f"ppo_{env_id}.json").write_text(json.dumps(log, indent=1))
    model.save(out / f"ppo_{env_id}.zip")
    venv.save(str(out / f"ppo_{env_id}_vecnormalize.pkl"))
    venv.close()
    return log


def plot(out: Path, figure: Path) -> None:
    """The learning curves of every ``ppo_*.json`` in ``out`` in one figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    logs = {env_id: json.loads((out / f"ppo_{env_id}.json").read_text())
            for env_id in ENVS if (out / f"ppo_{env_id}.json").exists()}
    fig, axes = plt.subplots(1, max(1, len(logs)), figsize=(5.2 * max(1, len(logs)), 3.6), constrained_layout=True,
                             squeeze=False)
    for ax, (env_id, log) in zip(axes[0], logs.items()):
        steps = [e["steps"] for e in log["evaluations"]]
        loads = [log[k][0] for k in ("load_average_at_start", "load_average") if k in log]
        title = (f"{env_id}: PPO, {log['steps']:,} steps in {log['wall_s'] / 60:.1f} min\n"
                 f"({log['train_steps_per_s']:.0f} steps/s, load average "
                 f"{' to '.join(f'{x:.1f}' for x in loads)} on 2 cores)")
        if env_id == "ObjectRecognition-v0":
            ax.plot(steps, [100 * e["accuracy"] for e in log["evaluations"]], "o-", label="accuracy, held-out seeds")
            ax.axhline(90, color="C2", ls="--", lw=1, label="goal 90 %")
            ax.axhline(100 / 7, color="0.5", ls=":", lw=1, label="chance 14 %")
            ax.set(ylabel="accuracy [%]", ylim=(0, 102))
        else:
            ax.plot(steps, [e["rmse_mm"] for e in log["evaluations"]], "o-", label="position RMSE, held-out seeds")
            ax.axhline(np.sqrt((13**2 - 1) / 12) * 5, color="0.5", ls=":", lw=1, label="guessing the mean: 18.7 mm")
            ax.set(ylabel="RMSE [mm]", ylim=(0, None))
        ax.set(xlabel="environment steps", title=title)
        ax.title.set_fontsize(9)
        ax.legend(fontsize=7)
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=110)
    print(f"wrote {figure}")


def choice_table(log: dict) -> str:
    """Markdown table of what the final recognition policy chose in its evaluation probes:
    how often each (grasp position, excitation)."""
    probes = np.asarray(log["evaluations"][-1]["probes"], dtype=int).reshape(-1, 2)
    counts = np.zeros((len(log["probe_positions_mm"]), len(log["excitations"])), dtype=int)
    np.add.at(counts, (probes[:, 0], probes[:, 1]), 1)
    rows = ["| grasp position | " + " | ".join(log["excitations"]) + " |",
            "|---:|" + "---:|" * len(log["excitations"])]
    rows += [f"| {x:+.0f} mm | " + " | ".join(str(c) for c in row) + " |"
             for x, row in zip(log["probe_positions_mm"], counts)]
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", choices=ENVS, default="ObjectRecognition-v0")
    parser.add_argument("--minutes", type=float, default=15.0, help="wall-clock budget, evaluations included")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=HERE.parent / "outputs" / "ppo",
                        help="folder of the logs and policies")
    parser.add_argument("--figure", type=Path, default=HERE.parent / "docs" / "images" / "ppo_curves.png")
    parser.add_argument("--eval-episodes", type=int, default=None,
                        help="held-out episodes per evaluation (default: 10 per label, 5 per position)")
    parser.add_argument("--eval-every", type=int, default=3072, help="environment steps between evaluations")
    parser.add_argument("--contact-model", choices=("damping", "spring_damper"), default="spring_damper",
                        help="acoustic contact_model (spring_damper: the env default; damping: the paper's)")
    parser.add_argument("--plot-only", action="store_true")
    args = parser.parse_args()
    ACOUSTIC["contact_model"] = args.contact_model
    out, figure = args.out.resolve(), args.figure.resolve()  # a relative --out is the caller's, from the cwd
    if not args.plot_only:
        n_eval = args.eval_episodes or (70 if args.env == "ObjectRecognition-v0" else 65)
        log = train(args.env, args.minutes, args.seed, out, n_eval, args.eval_every)
        final = {k: v for k, v in log["evaluations"][-1].items() if not isinstance(v, list)}
        print(f"{args.env}: {log['steps']:,} steps in {log['wall_s']:.0f} s "
              f"({log['train_steps_per_s']:.0f} steps/s), final {final}")
    plot(out, figure)
    path = out / "ppo_ObjectRecognition-v0.json"
    if path.exists() and (args.plot_only or args.env == "ObjectRecognition-v0"):
        print(choice_table(json.loads(path.read_text())))


if __name__ == "__main__":
    main()
