"""Modal accuracy benchmark: run time against frequency error, P1 vs P2, bar and tube.

Error = largest relative deviation, over every beam-theory mode below 10 kHz (Timoshenko
bending, exact torsion, Rayleigh-Love axial; see tests/test_modal_accuracy.py), of the FE
frequency of the same family. Also measures the issue-3 goals for the default objects in
every table material: cold build (default options, 22.05 kHz band), cached build, error.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/modal_accuracy.py [--quick]

Prints Markdown tables and writes docs/benchmarks/modal_accuracy.md and .png.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sensors import ModalModel  # noqa: E402
from sensors.atomic import atomic_write_text  # noqa: E402
from sensors.beam_theory import BAR, TABLE, TUBE, classify_modes, compare_to_beam  # noqa: E402

BAND_HZ = 10000.0


def pct(err: float) -> str:
    return f"{100 * err:.3f}" if math.isfinite(err) else "modes missing"


def max_error(model) -> float:
    rows = compare_to_beam(model, BAND_HZ)
    return max(abs(fe / ref - 1) if math.isfinite(fe) else float("inf") for _, ref, fe in rows)


def sweep(material: str, quick: bool):
    grid = {
        "p2": [0.5, 0.75, 1.0] if quick else [0.5, 0.75, 1.0, 1.5],
        "p1": [1.0, 2.0] if quick else [1.0, 2.0, 3.0],
    }
    rows = []
    for kind, dims, build in (("bar", BAR, ModalModel.bar), ("tube", TUBE, ModalModel.tube)):
        for element, resolutions in grid.items():
            for res in resolutions:
                if element == "p1" and kind == "tube":
                    res = res * 0.75  # the tube's default is already fine around the circle
                t0 = time.perf_counter()
                m = build(**dims, material=material, element=element, resolution=res, cache=False, progress=False,
                          max_frequency_hz=BAND_HZ * 1.05)
                dt = time.perf_counter() - t0
                err = max_error(m)
                rows.append(dict(kind=kind, element=element, resolution=res, n_dof=m.metadata["n_dof"],
                                 n_tets=m.metadata["n_tets"], time_s=dt, error=err))
                print(f"  {kind:4s} {element} res {res:4.2f}: {m.metadata['n_dof']:6d} dof {dt:6.2f} s "
                      f"max error {pct(err)} %", flush=True)
    return rows


def goals():
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        for kind, dims, build in (("bar", BAR, ModalModel.bar), ("tube", TUBE, ModalModel.tube)):
            for name in TABLE:
                t0 = time.perf_counter()
                m = build(**dims, material=name, cache_dir=cache, progress=False)
                cold = time.perf_counter() - t0
                t0 = time.perf_counter()
                m2 = build(**dims, material=name, cache_dir=cache, progress=False)
                warm = time.perf_counter() - t0
                assert m2.metadata.get("cache_hit") and np.array_equal(m2.frequencies_hz, m.frequencies_hz)
                err = max_error(m)
                rows.append(dict(kind=kind, material=name, n_dof=m.metadata["n_dof"], n_modes=m.n_modes,
                                 cold_s=cold, cached_ms=1000 * warm, error=err))
                print(f"  {kind:4s} {name:9s}: {m.n_modes:3d} modes, cold {cold:5.2f} s, cached {1000 * warm:5.1f} ms, "
                      f"max error below 10 kHz {100 * err:.3f} %", flush=True)
    return rows


def self_convergence(material: str = "abs"):
    """Default tube vs a 1.5x finer mesh, per mode family (ring modes have no beam reference)."""
    opts = dict(material=material, cache=False, progress=False, max_frequency_hz=BAND_HZ * 1.05)
    coarse = ModalModel.tube(**TUBE, **opts)
    fine = ModalModel.tube(**TUBE, resolution=1.5, **opts)
    labels_c, labels_f = classify_modes(coarse), classify_modes(fine)
    rows = {}
    for family in ("bending", "torsion", "axial", "other"):
        fc = sorted(f for f, lab in zip(coarse.frequencies_hz, labels_c) if lab == family and f < BAND_HZ)
        ff = sorted(f for f, lab in zip(fine.frequencies_hz, labels_f) if lab == family and f < BAND_HZ)
        n = min(len(fc), len(ff))
        if n:
            rows[family] = (n, max(abs(a / b - 1) for a, b in zip(fc[:n], ff[:n])))
    for family, (n, err) in rows.items():
        print(f"  tube {material} {family:8s}: {n:2d} modes, default vs 1.5x finer mesh: max {100 * err:.3f} %")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer resolutions")
    ap.add_argument("--material", default="abs", help="material of the sweep (abs has the most modes)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks"))
    args = ap.parse_args(argv)
    print(f"Resolution sweep ({args.material}, modes below {BAND_HZ:.0f} Hz):")
    sweep_rows = sweep(args.material, args.quick)
    print("Default objects (P2, 22.05 kHz band):")
    goal_rows = goals()
    print("Self-convergence of the default tube (ABS: ring modes below 10 kHz):")
    conv_rows = self_convergence()

    lines = [
        "# Modal accuracy benchmark",
        "",
        "Generated by `OMP_NUM_THREADS=1 .venv/bin/python benchmarks/modal_accuracy.py`. Error: largest",
        f"relative deviation from beam theory (Timoshenko bending, exact torsion, Rayleigh-Love axial) over",
        f"all beam modes below {BAND_HZ:.0f} Hz. Bar 200 x 25 x 25 mm, tube 200 mm x 25 / 19 mm diameter.",
        "Times are wall-clock on a shared 2-core machine (other jobs running), one BLAS thread.",
        "\"modes missing\": P1 locking pushed beam modes above the computed band. The tube's floor of",
        "~0.9% is Timoshenko theory's own deviation from 3D elasticity for this thick tube (it stays",
        "when the mesh is refined 3x); tube ring (ovalling) modes, below 10 kHz only in ABS, are not",
        "covered by beam theory.",
        "",
        f"## Run time against error ({args.material})",
        "",
        "| shape | element | resolution | dof | tets | time s | max error % |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in sweep_rows:
        lines.append(f"| {r['kind']} | {r['element'].upper()} | {r['resolution']:.2f} | {r['n_dof']} | {r['n_tets']} | "
                     f"{r['time_s']:.2f} | {pct(r['error'])} |")
    lines += [
        "",
        "## Default objects, default options (P2, band 22.05 kHz)",
        "",
        "| shape | material | dof | modes | cold build s | cached build ms | max error % below 10 kHz |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in goal_rows:
        lines.append(f"| {r['kind']} | {r['material']} | {r['n_dof']} | {r['n_modes']} | {r['cold_s']:.2f} | "
                     f"{r['cached_ms']:.1f} | {pct(r['error'])} |")
    lines += [
        "",
        f"## Default ABS tube against a 1.5x finer mesh (all modes below {BAND_HZ:.0f} Hz)",
        "",
        "Ring (ovalling) modes have no beam-theory reference; this shows how far the default mesh",
        "is from a finer one (a convergence indicator, not an independent reference).",
        "",
        "| family | modes | max deviation % |",
        "|---|---|---|",
    ]
    for family, (n, err) in conv_rows.items():
        lines.append(f"| {family} | {n} | {100 * err:.3f} |")
    text = "\n".join(lines) + "\n\n![run time against error](modal_accuracy.png)\n"
    print()
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "modal_accuracy.md", text)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for kind, marker in (("bar", "o"), ("tube", "s")):
        for element, color in (("p1", "tab:red"), ("p2", "tab:blue")):
            rs = [r for r in sweep_rows if r["kind"] == kind and r["element"] == element]
            ax.loglog([r["time_s"] for r in rs], [100 * r["error"] for r in rs], marker=marker, color=color,
                      label=f"{kind} {element.upper()}")
    ax.axhline(1.0, color="gray", ls="--", lw=0.8)
    ax.set_xlabel("build time [s]")
    ax.set_ylabel(f"max frequency error below {BAND_HZ / 1000:.0f} kHz [%]")
    ax.set_title(f"Modal accuracy vs run time ({args.material})")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "modal_accuracy.png", dpi=120)
    print(f"wrote {out / 'modal_accuracy.md'} and {out / 'modal_accuracy.png'}")


if __name__ == "__main__":
    main()
