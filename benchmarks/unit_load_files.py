"""A new process's first env steps with kept unit-load solves on disk (``sensors.modal.unit_load_files``)
against solving them again (issue 27: what every vector-env worker, dataset worker and new run pays).

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/unit_load_files.py \
        [--envs aas_gym/ObjectRecognition-v0:1200 moving:abs_bar:60] [--repeats 2] [--out docs/benchmarks/unit_load_files.md]

Each trial is a new process that makes the env (modal models already in the cache), then times
the CPU seconds of its first N steps (random actions, seed 0, resets included; ``moving:OBJ`` is
``benchmarks/streaming_env.py``'s moving scene: ContactFormation-v0 streaming OBJ on a steel-bar
plinth, action 0; ``vec:ENV`` is ``gym.make_vec(ENV, num_envs=2, vectorization_mode="async")``, N
vector steps, timed in wall seconds: two worker processes that share the files as they write them).  Three kinds, alternating, ``--repeats`` times: ``off`` (files off: every node
solved, the reference), ``first`` (files on, none yet: solves and writes them) and ``read``
(files on, those ``first`` wrote).  Every trial's observations are hashed (sha256 over all steps):
the three must be equal.  The files go to a folder of their own, removed at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

HERE = Path(__file__).resolve().parent


def child(spec: str, steps: int, kind: str, folder: str) -> dict:
    import hashlib

    import numpy as np

    from sensors._infra.cache import default_cache_dir
    from sensors.modal import unit_load_files

    unit_load_files.ENABLED = kind != "off"
    unit_load_files.FOLDER = folder
    if spec.startswith("vec:"):     # two async workers (forked: they inherit the settings above); wall seconds
        import gymnasium as gym

        import aas_gym  # noqa: F401

        venv = gym.make_vec(spec.split(":", 1)[1], num_envs=2, vectorization_mode="async")
        venv.reset(seed=0)
        venv.action_space.seed(0)
        h = hashlib.sha256()
        t = time.perf_counter()
        for _ in range(steps):
            obs = venv.step(venv.action_space.sample())[0]
            for k in sorted(obs):
                h.update(np.ascontiguousarray(obs[k]).tobytes())
        wall_s = time.perf_counter() - t
        venv.close()
        files = list((default_cache_dir() / folder).glob("*/node-*.bin"))
        return {"cpu_s": None, "wall_s": wall_s, "sha": h.hexdigest()[:16], "files": len(files),
                "files_mb": sum(p.stat().st_size for p in files) / 1e6}
    sys.path.insert(0, str(HERE))
    import stream_profile

    if spec.startswith("moving:"):
        env, step = stream_profile.moving_scene(spec.split(":", 1)[1])
    else:
        import aas_gym  # noqa: F401  (registers the envs)

        env, step = stream_profile.random_steps(spec)
    h = hashlib.sha256()
    t, w = time.process_time(), time.perf_counter()
    for _ in range(steps):
        obs = step()
        for k in sorted(obs):
            h.update(np.ascontiguousarray(obs[k]).tobytes())
    cpu_s, wall_s = time.process_time() - t, time.perf_counter() - w
    unit_load_files.flush()
    files = list((default_cache_dir() / folder).glob("*/node-*.bin"))
    return {"cpu_s": cpu_s, "wall_s": wall_s, "sha": h.hexdigest()[:16], "files": len(files),
            "files_mb": sum(p.stat().st_size for p in files) / 1e6}


def trial(spec: str, steps: int, kind: str, folder: str) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", spec, str(steps), kind, folder],
                         capture_output=True, text=True, check=False)
    if out.returncode:
        raise RuntimeError(f"{spec} {kind}: exit {out.returncode}\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--child":
        spec, steps, kind, folder = sys.argv[2:6]
        print(json.dumps(child(spec, int(steps), kind, folder)))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--envs", nargs="+", default=["aas_gym/ObjectRecognition-v0:1200", "moving:abs_bar:60"],
                    help="ENV_ID:STEPS, moving:OBJECT:STEPS or vec:ENV_ID:STEPS")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default=None, help="write the table (Markdown) here")
    args = ap.parse_args(argv)
    from sensors._infra.cache import default_cache_dir

    rows = []
    for item in args.envs:
        spec, steps = item.rsplit(":", 1)
        steps = int(steps)
        got = {"off": [], "first": [], "read": []}
        for r in range(args.repeats):
            folder = f"unit_loads-bench-{uuid.uuid4().hex[:8]}"
            try:
                order = ("off", "first", "read") if r % 2 == 0 else ("first", "read", "off")
                for kind in order:
                    got[kind].append(trial(spec, steps, kind, folder))
                    print(f"{spec} {kind}: {got[kind][-1]}", flush=True)
            finally:
                shutil.rmtree(default_cache_dir() / folder, ignore_errors=True)
        shas = {t["sha"] for ts in got.values() for t in ts}
        for clock in ("cpu_s", "wall_s"):
            if got["off"][0][clock] is not None:
                mean = {k: sum(t[clock] for t in ts) / len(ts) for k, ts in got.items()}
                rows.append((spec, steps, clock, mean, got, len(shas) == 1))
    lines = [
        f"`python benchmarks/unit_load_files.py --envs {' '.join(args.envs)} --repeats {args.repeats}`, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the end.",
        "",
        "CPU and wall seconds of a new process's first steps (``vec:``: wall seconds of two async workers; means of the repeats;",
        "the processes alternate; the files are written by a background thread, whose CPU the CPU column counts). *off*: every",
        "unit-load solve made (the reference); *first*: files on, none yet (solves and writes them); *read*: files on,",
        "those the first wrote. *Equal*: the observations' sha256 over all steps is the same in every process.",
        "",
        "| env | steps | clock | off [s] | first | read | off / read | first / off | files (MB) | equal |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for spec, steps, clock, mean, got, equal in rows:
        f = got["first"][-1]
        lines.append(f"| {spec} | {steps} | {clock[:-2]} | {mean['off']:.1f} | {mean['first']:.1f} | {mean['read']:.1f} | "
                     f"{mean['off'] / mean['read']:.2f}x | {mean['first'] / mean['off']:.2f}x | {f['files']} ({f['files_mb']:.0f}) | "
                     f"{'yes' if equal else 'NO'} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        from sensors._infra.atomic import atomic_write_text

        atomic_write_text(args.out, "# Kept unit-load solves on disk: a new process's first steps\n\n" + text)


if __name__ == "__main__":
    main()
