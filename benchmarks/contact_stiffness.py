"""Contact stiffness: what springs cost per grasp and per streamed step, and what they change.

The project's FEM bar (200 x 25 x 25 mm aluminium, P2, all modes below 22 kHz) held by the
two fingertip pads (``FingertipModel``: 2e6 N/m normal, 1.56e6 N/m tangential) at x = 40 mm,
with 40 N grip, optionally resting on a table contact (5 N, wood, Hertz/Mindlin).  Rows, all
in this one run on ONE core (BLAS/numba threads pinned to 1):

- once per model: assembling K, M and factorizing K + sigma M for the static correction;
- per grasp: ``ModalSystem.build`` (coupled modes + damping + discretisation) with
  ``contact_model="damping"`` (the paper's) and ``"spring_damper"`` (default), the table
  contact at a new place each time (no cache hits);
- per streamed step: an ``AcousticStream`` advancing 2 ms physics steps (88 samples) whose
  table force changes beyond the tolerance every step (a new system each step), both models;
- what the springs change: the heard bending pair's frequencies, and the 140 features (dB)
  of a steady-state recording, damping-only against springs, and free against on the table.

CPU time (the machine is shared), best of ``--repeats``.

    python benchmarks/contact_stiffness.py [--repeats 5] [--no-write]

Writes docs/benchmarks/contact_stiffness.md.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sensors import (AcousticStream, Contact, Excitation, FingertipModel, GraspState, ModalModel,  # noqa: E402
                     ModalSystem, simulate_recording)
from sensors._infra.atomic import atomic_write_text  # noqa: E402
from sensors.modal.static_correction import ContactFlexibility  # noqa: E402
from sensors.synthesis.modal_system import contact_modal_model  # noqa: E402

FS = 44100
STEP = 88  # samples per 2 ms physics step


def cpu_best(fn, repeats):
    best = np.inf
    for _ in range(repeats):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def db(x):
    return 20 * np.log10(np.maximum(np.asarray(x, float), 1e-30))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    bar = ModalModel.bar(0.2, 0.025, 0.025, "aluminium", progress=False)
    h = 0.0125
    tip = FingertipModel()
    act, mic = Contact([0.04, h, 0.0], [0, 1, 0], 40.0, 0.8), Contact([0.04, -h, 0.0], [0, -1, 0], 40.0, 0.8)
    geom = (act.position_m, act.normal, mic.position_m, mic.normal)

    def table(x, force=5.0):
        return Contact([x, 0.0, -h], [0, 0, -1], force, 0.5)

    t0 = time.process_time()
    ContactFlexibility(bar)
    t_flex = time.process_time() - t0
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    contact_modal_model(bar, [tip.pad(act), tip.pad(mic)])       # warm the kept factorization

    xs = iter(np.linspace(-0.09, 0.09, 4 * args.repeats + 4))
    build = {}
    for cm in ("damping", "spring_damper"):
        build[cm] = cpu_best(lambda: ModalSystem.build(bar, FS, *geom, [tip.pad(act), tip.pad(mic), table(next(xs))],
                                                       contact_model=cm, keep_all_modes=True), args.repeats)
    ex = Excitation.linear_sweep()
    step = {}
    n_steps = 100
    for cm in ("damping", "spring_damper"):
        def run():
            s = AcousticStream(ex, tip, contact_model=cm)
            for i in range(n_steps):
                s.advance(STEP, GraspState(bar, act, mic, (table(0.0, 2.0 + 0.2 * i),)))
        step[cm] = cpu_best(run, max(1, args.repeats // 2)) / n_steps

    free = bar.frequencies_hz
    pads = contact_modal_model(bar, [tip.pad(act), tip.pad(mic)]).frequencies_hz
    on_table = contact_modal_model(bar, [tip.pad(act), tip.pad(mic), table(-0.06)]).frequencies_hz

    def pair(f):
        return f[(f > 2900) & (f < 3400)]

    feats = {}
    for cm in ("damping", "spring_damper"):
        for where, others in (("held", ()), ("table x=-60 mm", (table(-0.06),)), ("table x=+80 mm", (table(0.08),))):
            obs = simulate_recording(bar, ex, 1.0, act, mic, others, fingertip=tip, steady_state=True,
                                     contact_model=cm)
            feats[cm, where] = db(obs.features())
    d_model = np.abs(feats["spring_damper", "held"] - feats["damping", "held"])
    table_rows = []
    for where in ("table x=-60 mm", "table x=+80 mm"):
        for cm in ("damping", "spring_damper"):
            d = np.abs(feats[cm, where] - feats[cm, "held"])
            table_rows.append(f"| {where} | {cm} | {d.mean():.3g} | {d.max():.3g} |")

    text = f"""# Contact stiffness: cost and effect

`python benchmarks/contact_stiffness.py` ({platform.machine()}, Python {platform.python_version()},
one core, CPU time, best of {args.repeats}).  The FEM bar 200 x 25 x 25 mm aluminium
({bar.metadata.get('n_dof')} dof, {bar.n_modes} modes below 22 kHz), fingertip pads at x = 40 mm
(40 N), a 5 N wooden table contact (Hertz/Mindlin, R = 5 mm).

## Cost

| what | damping only | spring + damper |
|---|---|---|
| once per model: K, M, factorization of K + sigma M | - | {t_flex:.2f} s (peak RSS of the run so far {rss_gb:.2f} GB) |
| per grasp: `ModalSystem.build` (pads + table) | {build['damping'] * 1e3:.1f} ms | {build['spring_damper'] * 1e3:.1f} ms |
| per streamed 2 ms step, a new contact set every step | {step['damping'] * 1e3:.2f} ms | {step['spring_damper'] * 1e3:.2f} ms |

The factorization is kept per model (`CACHE_SIZES["modal.flexibility"]`); a contact set then
costs one solve per constrained direction and a (6 + r + a)-square eigenproblem.

## What the springs change

Heard bending pair (grip plane and across), free: {', '.join(f'{f:.1f}' for f in pair(free))} Hz;
with the pads: {', '.join(f'{f:.1f}' for f in pair(pads))} Hz
({', '.join(f'{100 * (b / a - 1):+.2f} %' for a, b in zip(pair(free), pair(pads)))});
pads and table at x = -60 mm: {', '.join(f'{f:.1f}' for f in pair(on_table))} Hz.
Suspension modes (rigid-body motion held by the springs), pads only:
{', '.join(f'{f:.0f}' for f in pads[pads < 2000])} Hz.

Features (140 bins, dB) of the steady-state recording (linear sweep): springs against
damping-only, held in the air: mean |delta| {d_model.mean():.3g} dB, max {d_model.max():.3g} dB.

Effect of a table contact on the features, per contact model:

| contact | model | mean abs delta [dB] | max abs delta [dB] |
|---|---|---|---|
""" + "\n".join(table_rows) + "\n"
    print(text)
    if not args.no_write:
        out = ROOT / "docs" / "benchmarks"
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out / "contact_stiffness.md", text)
        print(f"wrote {out / 'contact_stiffness.md'}")


if __name__ == "__main__":
    main()
