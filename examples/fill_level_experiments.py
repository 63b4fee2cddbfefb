"""How full, and with what: the fill-level experiments of FillLevel-v0.

For both liquid models (compressible, the default, and incompressible) and each container
(mug, glass, can, bottle): plays ``--episodes`` episodes of ``aas_gym/FillLevel-v0`` with water
at a fill drawn uniformly in 0 .. 90 % and regresses the fill fraction from the 140-d features
with the paper's position protocol (KNN, k = 3, 3-fold CV); classifies the fill into the
CORSMAL-style classes empty / half / 90 % (``--episodes`` / 2 episodes each; the paper's
classifiers, 5-fold CV, macro F1). Then, at a fixed 60 % fill of the glass, tells water, oil,
ethanol and honey apart with the paper's classifiers (5-fold CV). Writes the tables to ``--out``.

    python examples/fill_level_experiments.py [--episodes 40] [--out docs/results/fill_level.md]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from sklearn.model_selection import KFold, cross_val_predict
from sklearn.neighbors import KNeighborsRegressor
from tqdm import tqdm

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.experiments.protocols import on_log_features, recognition
from sensors._infra.atomic import atomic_write_text

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

CONTAINERS = ("mug", "glass", "can", "bottle")
LIQUIDS = ("water", "oil", "ethanol", "honey")
#: CORSMAL-style fill classes (Xompero et al., the CORSMAL container manipulation benchmark:
#: empty, half full, 90 % full).
FILL_CLASSES = {"empty": 0.0, "half": 0.5, "90%": 0.9}
MODELS = {"compressible": True, "incompressible": False}


def macro_f1(confusion: np.ndarray) -> float:
    """Mean over classes of 2 TP / (2 TP + FP + FN) [%] (rows: truth, columns: prediction)."""
    tp = np.diag(confusion).astype(float)
    fp, fn = confusion.sum(axis=0) - tp, confusion.sum(axis=1) - tp
    return 100.0 * float(np.mean(np.where(2 * tp + fp + fn > 0, 2 * tp / np.maximum(2 * tp + fp + fn, 1), 0.0)))


def collect(env, n: int, seed: int, **options) -> tuple[np.ndarray, list[dict]]:
    """Features and ground truth of ``n`` episodes (seeds ``seed`` .. ``seed + n - 1``)."""
    X, truth = [], []
    for i in tqdm(range(n), desc=env.unwrapped.objects[0].label, leave=False):
        obs, info = env.reset(seed=seed + i, options=options or None)
        X.append(obs["acoustic"].astype(float))
        truth.append(info)
    return np.array(X), truth


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=40, help="episodes per container (fill) and per liquid")
    ap.add_argument("--excitation", default="linear")
    ap.add_argument("--out", default=OUTPUTS.parent / "docs" / "results" / "fill_level.md")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    lines = ["# FillLevel-v0: how full, and with what", "",
             f"`python examples/fill_level_experiments.py --episodes {args.episodes}` ({args.excitation} sweep), "
             "each with the compressible liquid (the default: the liquid's acoustic modes coupled to the wall) and the "
             "incompressible one (added mass only).", "",
             "The modes against fill level (0 to 100 % in 10 % steps, each container): "
             "`python examples/fill_level_sweep.py`,", "", "![modes against fill level](../images/fill_level_sweep.png)", "",
             "## Fill fraction from sound (water, 0-90 %; KNN k = 3, 3-fold CV)", "",
             "| container | episodes | RMSE compressible [% of full] | RMSE incompressible [%] | "
             "RMSE of always guessing the mean [%] |", "|---|---|---|---|---|"]
    f1_lines = ["", f"## Fill classes empty / half / 90 % (water; {max(5, args.episodes // 2)} episodes each; "
                "5-fold CV, macro F1 %)", "",
                "| container | liquid model | KNN | SVM | MLP | chance [%] |", "|---|---|---|---|---|---|"]
    for name in CONTAINERS:
        rmse, label = {}, name
        for model, compressible in MODELS.items():
            env = gym.make("aas_gym/FillLevel-v0", objects=[name], acoustic={"excitation": args.excitation},
                           compressible=compressible)
            X, truth = collect(env, args.episodes, seed=0)
            y = np.array([t["fill_fraction"] for t in truth])
            pred = cross_val_predict(on_log_features(KNeighborsRegressor(n_neighbors=3)), X, y,
                                     cv=KFold(3, shuffle=True, random_state=0))
            rmse[model] = 100 * float(np.sqrt(np.mean((pred - y) ** 2)))
            label, std = truth[0]["label"], 100 * float(np.std(y))
            Xc, yc = [], []
            for k, (cls, fill) in enumerate(FILL_CLASSES.items()):
                Xk, _ = collect(env, max(5, args.episodes // 2), seed=2000 * (k + 1), fill_fraction=fill)
                Xc.append(Xk)
                yc += [cls] * len(Xk)
            env.close()
            scores = {r.classifier: macro_f1(r.confusion) for r in
                      recognition(np.concatenate(Xc), np.array(yc), excitation=args.excitation)}
            f1_lines.append(f"| {label} | {model} | {scores['KNN']:.1f} | {scores['SVM']:.1f} | {scores['MLP']:.1f} "
                            f"| {100 / len(FILL_CLASSES):.0f} |")
        lines.append(f"| {label} | {args.episodes} | {rmse['compressible']:.1f} | {rmse['incompressible']:.1f} "
                     f"| {std:.1f} |")
    lines += f1_lines
    lines += ["", "## Liquid at 60 % fill of the glass (5-fold CV, accuracy %)", "",
              "| classifier | compressible [%] | incompressible [%] | chance [%] |", "|---|---|---|---|"]
    accuracy = {}
    for model, compressible in MODELS.items():
        env = gym.make("aas_gym/FillLevel-v0", objects=["glass"], task="liquid", liquids=LIQUIDS, fill_fraction=0.6,
                       acoustic={"excitation": args.excitation}, compressible=compressible)
        X, y = [], []
        for k in range(len(LIQUIDS)):
            Xk, truth = collect(env, max(5, args.episodes // 2), seed=1000 * (k + 1), liquid_index=k)
            X.append(Xk)
            y += [t["liquid"] for t in truth]
        env.close()
        accuracy[model] = {r.classifier: r.accuracy
                           for r in recognition(np.concatenate(X), np.array(y), excitation=args.excitation)}
    for clf in accuracy["compressible"]:
        lines.append(f"| {clf} | {accuracy['compressible'][clf]:.1f} | {accuracy['incompressible'][clf]:.1f} "
                     f"| {100 / len(LIQUIDS):.0f} |")
    lines += ["", f"Run time: {time.perf_counter() - t0:.0f} s on this project's 2-core machine.", ""]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, "\n".join(lines))
    print("\n".join(lines))
    return out


if __name__ == "__main__":
    main()
