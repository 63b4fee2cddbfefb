"""Wet mug against the fully coupled FEM reference, as the wall mesh is refined.

tests/test_fluid_coupled.py compares the project's wet modes (dry modes + static correction,
its own liquid mesh) with a full coupled structure-liquid solve (tests/coupled_fluid_reference.py,
scikit-fem) on a coarse wall (resolution 0.5) so that the suite fits the machine. This
benchmark runs the same comparison at the wall resolutions given (default 0.5 and 1.0, the
shipped mesh; 0.75 also works) and reports, per resolution and fill (30 / 60 / 100 % of
water), the number of wet modes below 12 kHz and the largest relative discrepancy
project / coupled - 1: the convergence argument for the test's coarse case. Each resolution runs in a child process
(its peak RSS is reported; 1.0 needs about 11.5 GB: run it alone on the machine).

Writes docs/benchmarks/fluid_coupled.md. Run: python benchmarks/fluid_coupled.py [0.5 1.0]
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from _pages import parse_args, rows_to_page  # noqa: E402

RESOLUTIONS = ("0.5", "1.0")
FILLS = (0.3, 0.6, 1.0)
COMPARED_UP_TO_HZ = 12000.0


def measure(resolution: float) -> dict:
    """The comparison at one wall resolution (in this process)."""
    from coupled_fluid_reference import RHO_WATER, coupled_frequencies_hz, wall_fem
    from sensors.fluid import container, filled
    from sensors.objects import get_object

    start = time.process_time()
    mug = get_object("mug").solid()
    wall = wall_fem(mug, resolution)
    wet_container = container(mug, resolution=resolution, progress=False)
    dry = wet_container.dry.frequencies_hz
    row = {"resolution": resolution, "dof": int(wall["K"].shape[0]), "f1_dry_hz": float(dry[0]), "fills": []}
    for fill in FILLS:
        height = fill * (mug.dimensions_m["height_m"] - mug.dimensions_m["floor_m"])
        wet = filled(wet_container, fill_height_m=height, compressible=False)  # the reference is incompressible
        got = wet.frequencies_hz[wet.frequencies_hz <= COMPARED_UP_TO_HZ]
        ref = coupled_frequencies_hz(mug, wall, height, RHO_WATER, len(got) + 2)[: len(got)]
        row["fills"].append({"fill": fill, "n": len(got), "max_rel": float(np.max(np.abs(got / ref - 1))),
                             "f1_wet_hz": float(got[0]), "f1_coupled_hz": float(ref[0])})
    row["cpu_s"] = time.process_time() - start
    row["peak_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
    return row


def run(resolution: str) -> dict:
    out = subprocess.run([sys.executable, __file__, "--one", resolution], check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def table(rows) -> str:
    head = ("| wall resolution | P2 dof | f1 dry Hz | " + " | ".join(
        f"{f:.0%} full: modes, max discrepancy, f1 project / coupled Hz" for f in FILLS)
        + " | peak RSS GB | CPU s |\n|---|---|---|" + "---|" * len(FILLS) + "---|---|\n")
    body = "".join(
        f"| {r['resolution']:g} | {r['dof']:,} | {r['f1_dry_hz']:.0f} | " + " | ".join(
            f"{c['n']}, {100 * c['max_rel']:.2f} %, {c['f1_wet_hz']:.0f} / {c['f1_coupled_hz']:.0f}" for c in r["fills"])
        + f" | {r['peak_gb']:.2f} | {r['cpu_s']:.0f} |\n" for r in rows)
    return head + body


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--one"]:  # the child: one resolution, its row as JSON on the last line
        print(json.dumps(measure(float(argv[1]))))
        return
    args = parse_args(__doc__.splitlines()[0], "resolutions", RESOLUTIONS, "fluid_coupled.md", argv)
    rows_to_page(
        args.resolutions, run, table, args.out,
        "Wet mug against the coupled FEM reference, by wall mesh resolution",
        "`python benchmarks/fluid_coupled.py` (one child process per resolution; the modal cache as found: a cold dry build adds its own peak)",
        "Wall resolution: of the mug's tet mesh (1.0 is the shipped mesh; tests/test_fluid_coupled.py "
        "runs 0.5). Per fill: the wet modes below 12 kHz compared, the largest |project / coupled - 1| "
        "over them (the test asserts at most 1 %), and the lowest wet mode, project / coupled reference. "
        "Peak RSS: of the child (container, reference wall, all three fills).")


if __name__ == "__main__":
    main()
