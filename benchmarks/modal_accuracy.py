"""Modal accuracy benchmark: run time against frequency error, P1 vs P2, bar and tube.

Error = largest relative deviation, over every beam-theory mode below 10 kHz (Timoshenko
bending, exact torsion, Rayleigh-Love axial; see tests/test_modal_accuracy.py), of the FE
frequency of the same family. Also measures the goals for the default objects in every
material they use: cold build (default options, 22.05 kHz band, empty cache), cached build,
error; and (issue 18) the default bars against an independent scikit-fem P2 solve of the same
mesh (equal error: the same discretization), both measured in this run, interleaved.

Times are CPU time of this process (one BLAS thread), medians of ``--repeats`` runs.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/modal_accuracy.py [--quick] [--repeats 3]

Prints Markdown tables and writes docs/benchmarks/modal_accuracy.md and .png.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aas_gym.object_names import DEFAULT_OBJECT_NAMES  # noqa: E402
from sensors import MATERIALS, ModalModel  # noqa: E402
from sensors._infra.atomic import atomic_write_text  # noqa: E402
from sensors.fem.beam_theory import BAR, TUBE, classify_modes, compare_to_beam  # noqa: E402
from sensors.mesh.prisms import bar_mesh  # noqa: E402

BAND_HZ = 10000.0
#: Every material of the default objects, in their order (aluminium, pla, abs, steel, wood).
DEFAULT_MATERIALS = tuple(dict.fromkeys(name.rsplit("_", 1)[0] for name in DEFAULT_OBJECT_NAMES))
COLD_GOAL_S = 1.0        # issue 18: a default bar within 1 s cold
SKFEM_GOAL_RATIO = 3.0   # issue 18: at least 3x faster than scikit-fem P2 at equal error


def cpu(fn):
    t = time.process_time()
    out = fn()
    return time.process_time() - t, out


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
                dt, m = cpu(lambda: build(**dims, material=material, element=element, resolution=res, cache=False,
                                          progress=False, max_frequency_hz=BAND_HZ * 1.05))
                err = max_error(m)
                rows.append(dict(kind=kind, element=element, resolution=res, n_dof=m.metadata["n_dof"],
                                 n_tets=m.metadata["n_tets"], time_s=dt, error=err))
                print(f"  {kind:4s} {element} res {res:4.2f}: {m.metadata['n_dof']:6d} dof {dt:6.2f} s "
                      f"max error {pct(err)} %", flush=True)
    return rows


def goals(repeats: int):
    rows = []
    for kind, dims, build in (("bar", BAR, ModalModel.bar), ("tube", TUBE, ModalModel.tube)):
        for name in DEFAULT_MATERIALS:
            cold, warm = [], []
            for _ in range(repeats):
                with tempfile.TemporaryDirectory() as cache:
                    t, m = cpu(lambda: build(**dims, material=name, cache_dir=cache, progress=False))
                    cold.append(t)
                    t, m2 = cpu(lambda: build(**dims, material=name, cache_dir=cache, progress=False))
                    warm.append(t)
                    assert m2.metadata.get("cache_hit") and np.array_equal(m2.frequencies_hz, m.frequencies_hz)
            err = max_error(m)
            rows.append(dict(kind=kind, material=name, n_dof=m.metadata["n_dof"], n_modes=m.n_modes,
                             cold_s=statistics.median(cold), cached_ms=1000 * statistics.median(warm), error=err))
            print(f"  {kind:4s} {name:9s}: {m.n_modes:3d} modes, cold {rows[-1]['cold_s']:5.2f} s, cached "
                  f"{rows[-1]['cached_ms']:5.1f} ms, max error below 10 kHz {100 * err:.3f} %", flush=True)
    return rows


def skfem_bar_hz(material: str, n_modes: int) -> np.ndarray:
    """The default bar by scikit-fem alone: the same structured mesh (equal discretization),
    skfem's P2 vector basis, its linear-elasticity and mass forms, and ARPACK shift-invert
    (scipy's eigsh) for the six rigid-body and ``n_modes`` elastic modes."""
    import scipy.sparse.linalg
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    mat = MATERIALS[material]
    tm = bar_mesh(**BAR)
    basis = Basis(MeshTet(tm.vertices_m.T.copy(), tm.tets.T.copy()), ElementVector(ElementTetP2()))
    E, nu, rho = mat.youngs_modulus_pa, mat.poisson_ratio, mat.density_kg_m3
    K = asm(linear_elasticity(E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))), basis)

    @BilinearForm
    def mass(u, v, w):
        return rho * dot(u, v)

    M = asm(mass, basis)
    vals = scipy.sparse.linalg.eigsh(K, k=n_modes + 6, M=M, sigma=-((2 * math.pi * 100.0) ** 2), which="LM",
                                     return_eigenvectors=False)
    return np.sqrt(np.sort(vals)[6:]) / (2 * math.pi)


def against_skfem(repeats: int):
    """Cold default bar against scikit-fem on the same mesh, interleaved in this run (after
    one untimed run of each: scikit-fem's first assembly pays one-time set-up)."""
    skfem_bar_hz("steel", 12)
    ModalModel.bar(**BAR, material="steel", cache=False, progress=False)
    rows = []
    for name in DEFAULT_MATERIALS:
        ours, theirs = [], []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory() as cache:
                t, m = cpu(lambda: ModalModel.bar(**BAR, material=name, cache_dir=cache, progress=False))
            ours.append(t)
            t, ref = cpu(lambda: skfem_bar_hz(name, m.n_modes))
            theirs.append(t)
        dev = float(np.max(np.abs(m.frequencies_hz / ref - 1)))
        a, b = statistics.median(ours), statistics.median(theirs)
        rows.append(dict(material=name, n_dof=m.metadata["n_dof"], n_modes=m.n_modes, ours_s=a, skfem_s=b,
                         ratio=b / a, dev=dev, error=max_error(m)))
        print(f"  bar {name:9s}: ours {a:5.2f} s, scikit-fem {b:5.2f} s ({b / a:4.1f}x), same mesh, largest "
              f"frequency difference {dev:.1e}", flush=True)
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
    ap.add_argument("--repeats", type=int, default=3, help="runs per cold-build figure (median)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks"))
    args = ap.parse_args(argv)
    print(f"Resolution sweep ({args.material}, modes below {BAND_HZ:.0f} Hz):")
    sweep_rows = sweep(args.material, args.quick)
    print("Default objects (P2, 22.05 kHz band):")
    goal_rows = goals(args.repeats)
    print("Default bars against scikit-fem (same mesh, P2, all modes below 22.05 kHz):")
    skfem_rows = against_skfem(args.repeats)
    print("Self-convergence of the default tube (ABS: ring modes below 10 kHz):")
    conv_rows = self_convergence()

    lines = [
        "# Modal accuracy benchmark",
        "",
        f"Generated by `OMP_NUM_THREADS=1 .venv/bin/python benchmarks/modal_accuracy.py --repeats {args.repeats}`. "
        "Error: largest",
        f"relative deviation from beam theory (Timoshenko bending, exact torsion, Rayleigh-Love axial) over",
        f"all beam modes below {BAND_HZ:.0f} Hz. Bar 200 x 25 x 25 mm, tube 200 mm x 25 / 19 mm diameter.",
        "Times are CPU time of the benchmark process (one BLAS thread) on a shared 2-core machine, medians of",
        f"{args.repeats} runs where marked; comparisons are measured in the same run.",
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
        f"Goal (issue 18): a default bar within {COLD_GOAL_S:g} s cold (CPU). Medians of {args.repeats} builds, each "
        "into an empty cache.",
        "",
        "| shape | material | dof | modes | cold build s | cached build ms | max error % below 10 kHz |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in goal_rows:
        lines.append(f"| {r['kind']} | {r['material']} | {r['n_dof']} | {r['n_modes']} | {r['cold_s']:.2f} | "
                     f"{r['cached_ms']:.1f} | {pct(r['error'])} |")
    lines += [
        "",
        "## Default bars against scikit-fem (same mesh, P2, every mode below 22.05 kHz)",
        "",
        f"Goal (issue 18): at least {SKFEM_GOAL_RATIO:g}x faster than an independent scikit-fem P2 solve at equal "
        "error. scikit-fem",
        "gets the same structured mesh (so the same discretization and error), assembles with its own P2",
        "elasticity and mass forms and solves with scipy's ARPACK shift-invert (`eigsh`, sigma = -(2 pi 100 Hz)^2)",
        "for the same number of modes; ours is the cold build (mesh, P2, assembly, eigensolve, cache write).",
        f"CPU-time medians of {args.repeats} interleaved runs.",
        "",
        "| material | dof | modes | ours cold s | scikit-fem s | ours faster | max frequency difference | "
        "max error % below 10 kHz |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in skfem_rows:
        lines.append(f"| {r['material']} | {r['n_dof']} | {r['n_modes']} | {r['ours_s']:.2f} | {r['skfem_s']:.2f} | "
                     f"{r['ratio']:.1f}x | {r['dev']:.1e} | {pct(r['error'])} |")
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
    ax.set_xlabel("build time (CPU) [s]")
    ax.set_ylabel(f"max frequency error below {BAND_HZ / 1000:.0f} kHz [%]")
    ax.set_title(f"Modal accuracy vs run time ({args.material})")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "modal_accuracy.png", dpi=120)
    print(f"wrote {out / 'modal_accuracy.md'} and {out / 'modal_accuracy.png'}")


if __name__ == "__main__":
    main()
