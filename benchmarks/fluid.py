"""Filled containers: what a new fill level or tilt costs against the container's cold FEM build.

For each everyday container (mug, glass, can, bottle), in one run and in CPU seconds of this
process (``time.process_time``):

* cold FEM build: P2 assembly + eigensolve of the dry modes to the default band (22.05 kHz),
  from the cached tet mesh (the mug's pytetwild meshing is reported on its own);
* container: the per-container static correction (assembly, one factorization, one static
  solve per pressure pattern), cold, and its load from the disk cache;
* per fill, for both liquid models (incompressible added mass; compressible: plus the
  liquid's acoustic modes up to twice the band): each new fill level 10 %, 20 %, ..., 100 % of
  water (upright), and each new tilt (50 % full, free surface tilted by 5 to 25 degrees):
  liquid mesh, Laplace solve (and the liquid's modes), wet modes;
* the ratio of the slowest new fill or tilt to the cold FEM build (the target is <= 1/10);
* the fill table (``filled(..., interpolated=True)``, FillLevel-v0's default): its first build
  for water (one table serves both liquid models), then the same new fills from it, per model,
  and the largest difference of their wet frequencies from the exact solves above.

Writes docs/benchmarks/fluid.md. Run: python benchmarks/fluid.py [mug glass can bottle]
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402
from _pages import parse_args, rows_to_page  # noqa: E402

from sensors.objects import get_object  # noqa: E402
from sensors.fluid import Container, filled  # noqa: E402
from sensors.fluid.fill_table import fill_table  # noqa: E402
from sensors.materials.liquids import get_liquid  # noqa: E402
from sensors.modal.model import ModalModel  # noqa: E402

CONTAINERS = ("mug", "glass", "can", "bottle")
FILLS = tuple(np.round(np.arange(1, 11) / 10, 2))
TILTS_DEG = (5, 10, 15, 20, 25)


def cpu(fn, *args, **kwargs):
    t0 = time.process_time()
    out = fn(*args, **kwargs)
    return out, time.process_time() - t0


def tilted(angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    return np.array([math.cos(a), math.sin(a), 0.0])  # the containers' up axis is +x


def run(name: str, cache_dir: str) -> dict:
    obj = get_object(name).solid()
    tm, t_mesh = cpu(obj.tet_mesh)  # the mug's pytetwild mesh is disk-cached separately
    dry, t_fem = cpu(ModalModel.from_tet_mesh, tm, obj.material, cache_dir=cache_dir, progress=False)
    container, t_prep = cpu(Container.of, obj, dry=dry, cache_dir=cache_dir)
    _, t_load = cpu(Container.of, obj, dry=dry, cache_dir=cache_dir)
    row = dict(name=name, material=obj.material.name, dof=dry.metadata["n_dof"], n_dry=dry.n_modes,
               n_corr=container.n_correction, mesh_s=t_mesh, fem_s=t_fem, prep_s=t_prep, load_s=t_load,
               f1_dry=float(dry.frequencies_hz[0]))
    exact = {}
    for model, compressible in (("inc", False), ("cmp", True)):
        fills = []
        for f in FILLS:
            wet, t = cpu(filled, container, float(f), compressible=compressible)
            fills.append(t)
            exact[model, f] = wet
        full = wet
        tilts = [cpu(filled, container, 0.5, surface_normal=tilted(a), compressible=compressible)[1]
                 for a in TILTS_DEG]
        row.update({f"{model}_fill_median_s": float(np.median(fills)), f"{model}_fill_max_s": max(fills),
                    f"{model}_tilt_max_s": max(tilts), f"{model}_ratio": max(fills + tilts) / t_fem,
                    f"{model}_f1_full": float(full.frequencies_hz[0]), f"{model}_n_liquid": full.n_liquid_modes,
                    "liquid_kg": full.liquid.mass_kg})
    _, row["table_s"] = cpu(fill_table, container, get_liquid("water"))
    container.fills.clear()  # fills the table leaves to the exact solve pay for it again
    for model, compressible in (("inc", False), ("cmp", True)):
        fills, error = [], 0.0
        for f in FILLS:
            wet, t = cpu(filled, container, float(f), compressible=compressible, interpolated=True)
            fills.append(t)
            ref = exact[model, f]
            n = min(wet.n_modes, ref.n_modes)
            error = max(error, float(np.max(np.abs(wet.frequencies_hz[:n] / ref.frequencies_hz[:n] - 1))))
        row.update({f"{model}_table_fill_median_ms": 1e3 * float(np.median(fills)), f"{model}_table_error": error})
    return row


def table(rows) -> str:
    head = ("| container | material | dof | dry modes + correction | tet mesh s | cold FEM s | container s (cached) "
            "| liquid model | new fill s (median / max) | new tilt s (max) | slowest / cold FEM | liquid modes (full) "
            "| f1 dry -> full Hz | water full kg | fill table s (build) | new fill from the table ms (median) "
            "| table vs exact (max) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
    body = ""
    for r in rows:
        for model, label in (("inc", "incompressible"), ("cmp", "compressible")):
            first = model == "inc"
            body += (
                f"| {r['name'] if first else ''} | {r['material'] if first else ''} | "
                + (f"{r['dof']:,} | {r['n_dry']} + {r['n_corr']} | {r['mesh_s']:.1f} | {r['fem_s']:.1f} | "
                   f"{r['prep_s']:.1f} ({r['load_s']:.2f}) | " if first else "| | | | | ")
                + f"{label} | {r[model + '_fill_median_s']:.2f} / {r[model + '_fill_max_s']:.2f} | "
                f"{r[model + '_tilt_max_s']:.2f} | 1/{1 / r[model + '_ratio']:.0f} | {r[model + '_n_liquid']} | "
                f"{r['f1_dry']:.0f} -> {r[model + '_f1_full']:.0f} | {r['liquid_kg']:.3f} | "
                + (f"{r['table_s']:.1f} | " if first else "| ")
                + f"{r[model + '_table_fill_median_ms']:.1f} | {r[model + '_table_error']:.1e} |\n")
    return head + body


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], "containers", CONTAINERS, "fluid.md", argv)
    cache_dir = tempfile.mkdtemp(prefix="aas-fluid-")  # a fresh modal cache: every FEM build is cold
    rows_to_page(
        args.containers, lambda name: run(name, cache_dir), table, args.out,
        "Filled containers: cost of a new fill level or tilt",
        "`python benchmarks/fluid.py` (CPU seconds of the process, one run; fresh modal cache)",
        "Cold FEM = P2 assembly + eigensolve of the dry modes to 22.05 kHz (the tet mesh, cached, is timed on "
        "its own). Container = the static correction of the dry basis (a factorization of the wall's "
        "stiffness and one static solve per wall pressure pattern), once per container; in brackets its "
        "load from the disk cache. New fill: 10 %, 20 %, ..., 100 % of water, upright; new tilt: 50 % full, "
        f"free surface tilted by {', '.join(map(str, TILTS_DEG))} degrees. Slowest / cold FEM: the slowest new "
        "fill or tilt over the cold FEM build (target: at most 1/10). Liquid model: incompressible "
        "(potential-flow added mass) or compressible (plus the liquid's own acoustic modes up to twice the band, "
        "their number in the full container given). f1: the lowest elastic mode, dry and full of water. Fill table: "
        "`filled(..., interpolated=True)` (FillLevel-v0's default), built once per container and liquid for both "
        "models (then loaded from the disk cache); the same ten new fills from it, and the largest relative "
        "difference of any wet frequency from the exact solve of that fill (fills the table leaves to the exact "
        "solve, such as the bottle's neck, count at the exact solve's cost).")


if __name__ == "__main__":
    main()
