"""Object recognition on the everyday set, and material recognition on shapes never trained on.

Generates a dataset of the seven shipped everyday objects (ceramic mug, glass bottle, steel
can, glass, ABS box, wooden spoon, aluminium L-bracket) and a paper-sized bar of each of their
materials, grasped anywhere the hand reaches them (antipodal grasps), alone on the table and
with bars leaning on them; then runs the paper's protocols on it (5-fold within single-object
scenes, single -> multi-object transfer) and the held-out-geometry test (each shape whose
material comes in another shape is held out; a material classifier trained on the others
names it). Writes the report (tables, confusion matrices, spectra) to ``--out``.

    python examples/everyday_recognition.py [--out docs/results/everyday] [--grasps 20] [--workers 2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from aas_gym.experiments.config import DatasetConfig
from aas_gym.experiments.generate import generate_dataset
from aas_gym.experiments.run import report_dataset

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

EVERYDAY = ("mug", "bottle", "can", "glass", "box", "spoon", "l_bracket")
BARS = ("ceramic_bar", "glass_bar", "steel_bar", "abs_bar", "wood_bar", "aluminium_bar")


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=OUTPUTS.parent / "docs" / "results" / "everyday", help="report folder")
    ap.add_argument("--data", default=OUTPUTS / "everyday", help="dataset folder (resumable)")
    ap.add_argument("--grasps", type=int, default=20, help="single-object grasps per object (multi: half)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    config = DatasetConfig(objects=EVERYDAY + BARS, scenes=("single", "multi"), single_grasps=args.grasps,
                           multi_grasps=max(2, args.grasps // 2))
    generate_dataset(config, args.data, workers=args.workers)
    report = report_dataset(Path(args.data), Path(args.out), workers=args.workers)
    print(f"report: {report} ({time.perf_counter() - t0:.0f} s)")
    return report


if __name__ == "__main__":
    main()
