"""Streaming synthesis cost per env step (sensors side only, no MuJoCo).

One env step of 0.05 s = 2205 samples at 44.1 kHz = 25 physics steps of 2 ms (88 or 89
samples).  ``sensors.synthesis.stream.AcousticStream`` records it for FEM objects of about 12, 46
and 100 modes below Nyquist, under the linear sweep with sensor noise, in four cases:

- ``same object``: the same ``GraspState`` for all 25 spans (nothing to compare);
- ``jitter``: a new ``GraspState`` every physics step whose forces and points jitter within
  the default ``ContactTolerance`` (as MuJoCo's do): one cached system, spans merged;
- ``jitter, per step``: the same, but one ``advance`` call per physics step (no merging);
- ``change``: a contact set never seen before at the start of every env step (the table
  force grows by 10 % per step): one system build per env step.

Reported: milliseconds of CPU time per env step and the real-time factor 0.05 s / cost.

    python benchmarks/streaming.py [--steps 40] [--no-write]

Writes docs/benchmarks/streaming.md.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sensors  # noqa: E402
from sensors import AcousticStream, Contact, Excitation, GraspState  # noqa: E402

FS = 44100
ENV_STEP = 2205
PHYSICS_STEPS = 25
BOUNDS = np.round(np.arange(PHYSICS_STEPS + 1) * ENV_STEP / PHYSICS_STEPS).astype(int)


def objects():
    M, T = sensors.ModalModel, sensors.MATERIALS
    # (label, model, half thickness at the grasp along y, table contact z)
    return [("steel bar 200x20x20 mm", M.bar(0.2, 0.02, 0.02, T["steel"], progress=False), 0.01, -0.01),
            ("ABS bar 250x20x20 mm", M.bar(0.25, 0.02, 0.02, T["abs"], progress=False), 0.01, -0.01),
            ("ABS tube 180 mm, 20/16 mm", M.tube(0.18, 0.01, 0.008, T["abs"], progress=False), 0.01, -0.01)]


def grasp(model, h, zt, rng=None, table_force_n=1.5):
    j = (lambda s: 1 + s * rng.standard_normal()) if rng is not None else (lambda s: 1.0)
    dx = (lambda: 5e-5 * rng.standard_normal()) if rng is not None else (lambda: 0.0)
    act = Contact([0.04 + dx(), h, 0.0], [0, 1, 0], 40.0 * j(0.004), 0.8)
    mic = Contact([0.04 + dx(), -h, 0.0], [0, -1, 0], 40.0 * j(0.004), 0.8)
    # table contacts on the lowest points of the section
    tab = tuple(Contact([x, 0.0, zt], [0, 0, -1], table_force_n * j(0.004), 0.4) for x in (-0.07, 0.0, 0.07))
    return GraspState(model, act, mic, tab, object_key="obj")


def run_case(model, h, zt, case, steps):
    exc = Excitation.linear_sweep()
    stream = AcousticStream(exc, noise_std=1e-4, rng=0)
    rng = np.random.default_rng(0)
    fixed = grasp(model, h, zt)
    sizes = np.diff(BOUNDS)

    def spans(k):
        if case == "same object":
            return [(int(n), fixed) for n in sizes]
        if case == "change":
            g = grasp(model, h, zt, table_force_n=1.5 * 1.1 ** k)
            return [(int(n), g) for n in sizes]
        return [(int(n), grasp(model, h, zt, rng)) for n in sizes]

    plans = [spans(k) for k in range(steps + 2)]   # contacts prepared outside the timing
    stream.advance(plans[0]), stream.advance(plans[1])  # warm-up (first build, drive system)
    t0 = time.process_time()  # CPU time: the machine is shared (one thread, see the top)
    for plan in plans[2:]:
        if case == "jitter, per step":
            for n, g in plan:
                stream.advance(n, g)
        else:
            stream.advance(plan)
    dt = (time.process_time() - t0) / steps
    return dt, stream.systems.misses


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    cases = ["same object", "jitter", "jitter, per step", "change"]
    rows = []
    for label, model, h, zt in objects():
        r = int((model.frequencies_hz < FS / 2).sum())
        for case in cases:
            dt, misses = run_case(model, h, zt, case, args.steps)
            rows.append((label, r, case, dt * 1e3, 0.05 / dt, misses))
            print(f"{label:28s} {r:4d} modes  {case:18s} {dt * 1e3:7.2f} ms/step  {0.05 / dt:7.1f}x real time"
                  f"  (system builds {misses})", flush=True)
    lines = ["# Streaming synthesis cost per env step", "",
             "`python benchmarks/streaming.py` (sensors only, no MuJoCo); see its docstring for the cases.",
             f"One env step = 0.05 s = {ENV_STEP} samples in {PHYSICS_STEPS} physics spans; "
             f"{args.steps} env steps timed (CPU time) after 2 warm-up steps; one BLAS thread; "
             f"{platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}.", "",
             "| object | modes < Nyquist | case | ms per env step | real-time factor | system builds |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {a} | {r} | {c} | {ms:.2f} | {rt:.0f}x | {mi} |" for a, r, c, ms, rt, mi in rows]
    text = "\n".join(lines) + "\n"
    if not args.no_write:
        out = ROOT / "docs" / "benchmarks" / "streaming.md"
        out.write_text(text)
        print(f"wrote {out}")
    return rows


if __name__ == "__main__":
    main()
