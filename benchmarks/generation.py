"""Dataset generation throughput: grasps per second on one process, local processes and Ray.

    python benchmarks/generation.py [--grasps 48] [--cli-workers 1,2]

Every backend generates the same configuration into a fresh folder (modal models warm in
the disk cache, as in any run after the first, loaded by each worker); the output bytes are
checked equal. Each backend runs a small and a large dataset: the difference gives the
steady throughput, the rest is start-up (spawning processes and importing, starting Ray,
loading models). Then the command users run, end to end: ``aas generate OUT --workers N``
on the default configuration (the paper's 665 grasps, 3 excitations each) for each N, in
one run, each into a fresh folder. Prints Markdown tables and writes
docs/benchmarks/generation.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from aas_gym.experiments.config import DatasetConfig
from sensors._infra.atomic import atomic_write_text

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pages import machine_line  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("shard-*.parquet"))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grasps", type=int, default=48, help="single-object grasps per object")
    parser.add_argument("--cli-workers", default="1,2", help="worker counts for the end-to-end `aas generate` rows")
    parser.add_argument("--out", default=str(ROOT / "docs" / "benchmarks" / "generation.md"))
    args = parser.parse_args()
    objects = ("aluminium_bar", "wood_bar")
    small = DatasetConfig(objects=objects, scenes=("single",), single_grasps=4, shard_size=8)
    large = DatasetConfig(objects=objects, scenes=("single",), single_grasps=args.grasps, shard_size=8)
    n_small, n_large = len(small.tasks()), len(large.tasks())
    # Warm the disk cache in another process: no backend starts with models in memory.
    subprocess.run([sys.executable, "-c", "from sensors.objects import get_object\n"
                    f"for o in {objects!r}: get_object(o).modal_model()"], check=True)
    cpus = os.cpu_count() or 1
    backends = [("in-process (1 worker)", dict(workers=1)),
                (f"local processes ({cpus} workers)", dict(workers=cpus)),
                (f"Ray, local instance ({cpus} CPUs)", dict(ray_address="local"))]
    rows, reference = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in backends:
            walls = []
            for label, config in (("small", small), ("large", large)):
                out = Path(tmp) / f"{name.split()[0]}-{label}"
                code = ("import time; from aas_gym.experiments.config import DatasetConfig;"
                        "from aas_gym.experiments.generate import generate_dataset; t0 = time.perf_counter();"
                        f"generate_dataset(DatasetConfig(**{config.to_dict()!r}), {str(out)!r}, progress=False, **{kw!r});"
                        "print(time.perf_counter() - t0)")
                # A fresh interpreter per run: every backend pays its imports and model loads.
                res = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
                walls.append(float(res.stdout.strip().splitlines()[-1]))
            data = _bytes(out)
            reference = reference or data
            rate = (n_large - n_small) / (walls[1] - walls[0])
            rows.append((name, walls[1], rate, walls[0] - n_small / rate, data == reference))
    base = rows[0][2]
    lines = [
        "# Dataset generation throughput",
        "",
        f"`python benchmarks/generation.py --grasps {args.grasps}` on {platform.machine()} with {cpus} cores, "
        f"Python {platform.python_version()}: single-object grasps of 2 objects, 3 excitations each (1 s "
        f"recordings), shards of 8 grasps, modal models in the disk cache. Each backend runs {n_small} and "
        f"{n_large} grasps in a fresh interpreter; the difference gives the steady rate, the rest is start-up.",
        "",
        f"| backend | wall for {n_large} grasps [s] | steady grasps/s | speed-up vs 1 worker | start-up [s] | same bytes |",
        "|---|---:|---:|---:|---:|---|",
    ]
    lines += [f"| {name} | {wall:.1f} | {rate:.1f} | {rate / base:.2f}x | {start:.1f} | {'yes' if same else 'NO'} |"
              for name, wall, rate, start, same in rows]
    lines += cli_rows([int(w) for w in args.cli_workers.split(",") if w])
    text = "\n".join(lines) + "\n"
    print(text)
    atomic_write_text(args.out, text)
    print(f"wrote {args.out}")


def cli_rows(workers: list[int]) -> list[str]:
    """``aas generate`` on the default configuration, once per worker count, wall and CPU time
    (this process's children: the CLI and its workers), in one run."""
    from aas_gym.experiments.config import DatasetConfig

    subprocess.run([sys.executable, "-c", "from sensors.objects import get_object\n"
                    f"for o in {DatasetConfig().objects!r}: get_object(o).modal_model()"], check=True)
    n = len(DatasetConfig().tasks())
    aas = str(Path(sys.executable).with_name("aas"))
    rows, reference = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for w in workers:
            out = Path(tmp) / f"w{w}"
            before = os.times()
            t0 = time.perf_counter()
            subprocess.run([aas, "generate", str(out), "--workers", str(w)], check=True, capture_output=True)
            wall = time.perf_counter() - t0
            after = os.times()
            cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
            data = _bytes(out)
            reference = reference or data
            rows.append((w, wall, cpu, data == reference))
    base = rows[0][1]
    return ["", "## `aas generate` end to end", "",
            f"`aas generate OUT --workers N` on the default configuration ({n} grasps, 3 excitations each, warm "
            f"modal cache), one after the other in one run, each into a fresh folder; wall time includes start-up, "
            f"import and the workers' model loads. {machine_line()}", "",
            "| workers | wall [s] | CPU [s] | speed-up vs first row | same bytes |", "|---:|---:|---:|---:|---|"] + [
        f"| {w} | {wall:.1f} | {cpu:.1f} | {base / wall:.2f}x | {'yes' if same else 'NO'} |" for w, wall, cpu, same in rows]


if __name__ == "__main__":
    main()
