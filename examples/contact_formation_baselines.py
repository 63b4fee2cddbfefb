"""Which contact formation holds now: sound against proprioception on ContactFormation-v0.

Plays episodes of ``aas_gym/ContactFormation-v0`` (the hand holds a bar and a random script
rests, presses and slides it on the table, lifts it, carries it over another bar and sets it
down there), then trains classifiers (gradient boosting by default, or random forests) on some
episodes and tests them on the others, from the streamed sound, from proprioception, and from
both. Prints the per-class recall table and writes it to ``--out``.

    python examples/contact_formation_baselines.py [--episodes 24] [--out outputs/contact_formation.md]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from aas_gym.experiments.contact_formation import CLASSIFIERS, collect, evaluate, format_table
from sensors._infra.atomic import atomic_write_text

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=24)
    ap.add_argument("--steps", type=int, default=200, help="env steps per episode (0.05 s each)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--classifier", choices=CLASSIFIERS, default="boosting",
                    help="random forests (200 trees) or histogram gradient boosting (default)")
    ap.add_argument("--out", default=OUTPUTS / "contact_formation.md", help="Markdown table to write")
    args = ap.parse_args(argv)
    method = "random forests (200 trees)" if args.classifier == "forest" else "histogram gradient boosting"
    t0 = time.perf_counter()
    data = collect(args.episodes, seed=args.seed, steps=args.steps)
    results = evaluate(data, seed=args.seed, classifier=args.classifier)
    table = format_table(results)
    minutes = (time.perf_counter() - t0) / 60
    text = (f"# Contact formation from sound and from proprioception\n\n"
            f"`python examples/contact_formation_baselines.py --episodes {args.episodes} --steps {args.steps} "
            f"--seed {args.seed} --classifier {args.classifier}` ({minutes:.1f} min). {args.episodes} episodes of "
            f"`aas_gym/ContactFormation-v0` ({len(data.label)} steps), split by episode 70/30; "
            f"{method}. Per-class recall on the test episodes:\n\n" + table + "\n\n"
            "Sound: the features of the latest complete excitation period (dB) and the level of the "
            "step's own audio in 24 bands. Proprioception: TCP pose and velocity, gripper opening, "
            "speed and motor force.\n")
    out = Path(args.out)
    atomic_write_text(out, text)
    atomic_write_text(out.with_suffix(".json"), json.dumps(results, indent=1))
    print(table)
    print(f"wrote {out}")
    return results


if __name__ == "__main__":
    main()
