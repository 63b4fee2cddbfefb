"""Import time of what users start with: ``import sensors``, ``import aas_gym``, ``aas --help``.

    python benchmarks/imports.py [--repeats 5] [--before REV]

Each command runs in a fresh interpreter (no module cached in the process; the OS file cache
is warm after the first round). The child reports its own CPU time (``resource``: user +
system of that process) and the parent measures the wall time of the whole run. Rounds are
interleaved, every command once per round, and the table gives medians, also as ratios to
``python -c "import numpy"`` measured in the same run (the floor every command pays).
The last column lists the heavy modules the command loaded. ``--before REV`` also measures
the packages as they were at git revision REV (extracted to a temporary folder and imported
from there, same interpreter and dependencies), interleaved in the same rounds.

Prints a Markdown table and writes ``docs/benchmarks/imports.md``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from sensors._infra.atomic import atomic_write_text

ROOT = Path(__file__).resolve().parent.parent
GOAL_S = 0.5  # issue 18: each within 0.5 s
WATCHED = ("numba", "scipy.linalg", "scipy.sparse", "sklearn", "mujoco", "pyaudio")

# (label, code run in the child); the child appends its CPU time and loaded modules as JSON.
CASES = [
    ("python -c \"import numpy\" (baseline)", "import numpy"),
    ("import sensors", "import sensors"),
    ("import aas_gym", "import aas_gym"),
    ("aas --help", "import contextlib, io, sys\nsys.argv = ['aas', '--help']\nfrom aas_gym.cli import main\n"
                   "with contextlib.redirect_stdout(io.StringIO()):\n    try:\n        main()\n"
                   "    except SystemExit:\n        pass"),
]
_REPORT = ("\nimport json as _j, resource as _r, sys as _s\n_u = _r.getrusage(_r.RUSAGE_SELF)\n"
           "print(_j.dumps({'cpu_s': _u.ru_utime + _u.ru_stime, 'modules': sorted(_s.modules)}))")


def run_once(code: str, tree: Path) -> tuple[float, float, set[str]]:
    """(wall s, CPU s, loaded modules) of one fresh interpreter running ``code`` on the
    packages in ``tree`` (``python -c`` puts the working folder first on sys.path)."""
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code + _REPORT], capture_output=True, text=True, check=True,
                         cwd=tree)
    wall = time.perf_counter() - t
    rep = json.loads(out.stdout.strip().splitlines()[-1])
    return wall, rep["cpu_s"], set(rep["modules"])


def checkout(rev: str, folder: Path) -> Path:
    """The import packages at git revision ``rev``, extracted into ``folder``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "sensors", "aas_gym", "real"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def measure(repeats: int, trees: dict[str, Path]) -> list[dict]:
    cases = [(label if name == "" else f"{label} [{name}]", code, tree)
             for label, code in CASES for name, tree in trees.items()
             if name == "" or not label.endswith("(baseline)")]
    runs = {label: [] for label, _, _ in cases}
    for _ in range(repeats + 1):  # round 0 warms the file cache and numba/pyc caches: dropped
        for label, code, tree in cases:
            runs[label].append(run_once(code, tree))
    rows = []
    for label, _, _ in cases:
        kept = runs[label][1:]
        rows.append({"command": label, "wall_s": statistics.median(r[0] for r in kept),
                     "cpu_s": statistics.median(r[1] for r in kept),
                     "loaded": [m for m in WATCHED if m in kept[-1][2]]})
    base = rows[0]
    for r in rows:
        r["wall_ratio"] = r["wall_s"] / base["wall_s"]
        r["cpu_ratio"] = r["cpu_s"] / base["cpu_s"]
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--before", metavar="REV", help="also measure the packages at this git revision")
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"": ROOT}
        if args.before:
            trees[f"at {args.before}"] = checkout(args.before, Path(tmp))
        rows = measure(args.repeats, trees)
    before = f" --before {args.before}" if args.before else ""
    lines = [
        "# Import time",
        "",
        f"`python benchmarks/imports.py --repeats {args.repeats}{before}` on {platform.machine()}, Python "
        f"{platform.python_version()}: each command in a fresh interpreter, medians of {args.repeats} interleaved "
        "rounds after a warm-up round; wall time of the whole child process, CPU time (user + system) the child "
        "reports. The machine is shared: the ratios to the `import numpy` baseline of the same run are the "
        "comparable figures.",
        f"Goal (issue 18): each within {GOAL_S} s.",
        "",
        "| command | wall [s] | CPU [s] | wall / numpy | CPU / numpy | heavy modules loaded |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| `{r['command']}` | {r['wall_s']:.3f} | {r['cpu_s']:.3f} | {r['wall_ratio']:.2f}x | "
                     f"{r['cpu_ratio']:.2f}x | {', '.join(r['loaded']) or 'none'} |")
    lines += ["", f"Heavy modules watched: {', '.join(WATCHED)}. What each import defers is asserted (modules, "
              "never seconds) in `tests/test_imports.py`."]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        out = ROOT / "docs" / "benchmarks"
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out / "imports.md", text)


if __name__ == "__main__":
    main()
