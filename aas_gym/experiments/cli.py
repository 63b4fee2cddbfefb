"""``aas run`` (the main job), ``aas generate`` and ``aas report``."""

from __future__ import annotations

import argparse
import os
import shlex
import time
from pathlib import Path

from aas_gym.experiments.config import EXCITATIONS, SCENES, DatasetConfig

#: A small configuration for smoke runs and CI (``--quick``).
QUICK = dict(single_grasps=6, multi_grasps=3, positions=7, position_repeats=3)


#: Memory of one generation worker process [bytes] (``generate.die_with_parent``: ~350 MB),
#: for the estimate in the ``--workers`` refusal.
WORKER_BYTES = 350e6
#: The most workers per core (``--workers``): more only share the cores and add memory.
MAX_WORKERS_PER_CPU = 4


def _config(args: argparse.Namespace) -> DatasetConfig:
    """The whole configuration, checked before anything is written (ValueError: exit 2)."""
    kw = dict(QUICK) if args.quick else {}
    for name in ("single_grasps", "multi_grasps", "positions", "position_repeats", "seed", "shard_size"):
        if getattr(args, name) is not None:
            kw[name] = getattr(args, name)
    if args.robot is not None:
        kw["robot"] = args.robot
    for name in ("objects", "excitations", "scenes"):
        if getattr(args, name) is not None:
            kw[name] = _split_names(f"--{name}", getattr(args, name))
    if args.waveforms:
        kw["store_waveforms"] = True
    _check_workers(args.workers)
    if args.ray_address not in (None, "local"):
        from aas_gym.experiments.generate import ray_endpoint

        ray_endpoint(args.ray_address)  # a malformed address fails here, before anything is written
    try:
        return DatasetConfig(**kw)
    except (TypeError, ValueError) as exc:  # name the flags, not the fields
        text = str(exc)
        for name in kw:
            text = text.replace(f"{name} ", f"--{name.replace('_', '-')} ", 1) if text.startswith(name) else text
        raise type(exc)(text) from None


def _split_names(flag: str, text: str) -> tuple[str, ...]:
    """Comma-separated names; an empty list or an empty name (``--objects ''``,
    ``--objects a,,b``) is refused, never read as "the defaults"."""
    names = tuple(n.strip() for n in text.split(","))
    if not all(names):
        raise ValueError(f"{flag} {text!r} has an empty name: give comma-separated names, or leave {flag} out "
                         "for the defaults")
    return names


def _check_workers(workers: int | None) -> None:
    """``--workers`` in [1, MAX_WORKERS_PER_CPU x cores], refused with its memory estimate."""
    if workers is None:
        return
    if workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    limit = MAX_WORKERS_PER_CPU * (os.cpu_count() or 1)
    if workers > limit:
        raise ValueError(f"--workers {workers} would start {workers} processes of ~{WORKER_BYTES / 1e6:.0f} MB "
                         f"(~{workers * WORKER_BYTES / 1e9:.0f} GB) on {os.cpu_count() or 1} cores (limit {limit}, "
                         f"{MAX_WORKERS_PER_CPU} per core): pass fewer")


def _writable_folder(path: Path) -> Path:
    """``path`` created if needed and checked writable now, before any computing."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".aas-write-check-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OSError(f"cannot write to the output folder {path} ({exc.strerror or exc}); "
                      "choose another folder") from None
    return path


def _add_config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="a small configuration (minutes less, noisier numbers)")
    p.add_argument("--objects", help="comma-separated object names (default: the paper's seven)")
    p.add_argument("--excitations", help=f"comma-separated subset of {','.join(EXCITATIONS)}")
    p.add_argument("--scenes", help=f"comma-separated subset of {','.join(SCENES)}")
    p.add_argument("--single-grasps", type=int, help="grasps per object, single-object scenes (paper: 20)")
    p.add_argument("--multi-grasps", type=int, help="grasps per object, multi-object scenes (paper: 10)")
    p.add_argument("--positions", type=int, help="grasp positions 5 mm apart (paper: 13)")
    p.add_argument("--position-repeats", type=int, help="recordings per position (paper: 5)")
    p.add_argument("--seed", type=int, help="root seed (default 0)")
    p.add_argument("--shard-size", type=int, help="grasps per output file (default 16)")
    p.add_argument("--waveforms", action="store_true", help="also store raw waveforms")
    p.add_argument("--robot", choices=("floating_hand", "panda"),
                   help="who grasps: the floating Franka hand (default, the paper's figures) or the Franka Panda arm")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="local worker processes")
    p.add_argument("--ray-address", help="run on Ray: 'local' starts a local instance, or a cluster address")
    p.add_argument("--overwrite", action="store_true", help="replace a dataset with another configuration or begun by other code")


def _generate(args: argparse.Namespace, out: Path) -> Path:
    from aas_gym.experiments.generate import generate_dataset

    config = _config(args)
    _writable_folder(out.parent if not out.exists() else out)
    args.interrupt_hint = "rerun the same command to resume"
    print(f"dataset: {len(config.tasks())} grasps x {len(config.excitations)} excitations -> {out}")
    argv = getattr(args, "argv", None)
    return generate_dataset(config, out, workers=args.workers, ray_address=args.ray_address,
                            overwrite=args.overwrite, command=None if argv is None else shlex.join(["aas", *argv]))


def _cmd_generate(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    out = _generate(args, Path(args.out))
    print(f"done in {time.perf_counter() - t0:.1f} s: {out}")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from aas_gym.experiments.run import report_dataset

    _check_workers(args.workers)
    dataset = Path(args.dataset)
    if not dataset.is_dir():
        raise ValueError(f"{dataset} is not a dataset folder (make one with `aas generate {dataset}`)")
    path = report_dataset(dataset, _writable_folder(Path(args.out) if args.out else dataset / "report"),
                          workers=args.workers)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from aas_gym.experiments.run import report_dataset

    t0 = time.perf_counter()
    # A quick run gets its own default folder: it must not meet a full run's dataset.
    out = Path(args.out if args.out is not None else ("outputs/quick" if args.quick else "outputs"))
    _config(args)
    report = _writable_folder(out / "report")
    dataset = _generate(args, out / "dataset")
    path = report_dataset(dataset, report, workers=args.workers)
    print(path.read_text())
    print(f"wrote {path} ({time.perf_counter() - t0:.0f} s)")
    return 0


def add_subcommands(sub) -> None:
    p = sub.add_parser("run", help="the main job: simulate the paper's experiments on the default objects "
                                   "and write the report (outputs/report/report.md)")
    p.add_argument("--out", default=None, help="output folder (default: outputs, or outputs/quick with --quick)")
    _add_config_options(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("generate", help="generate a sharded, resumable dataset (Parquet)")
    p.add_argument("out", help="output folder (resumed if it holds the same configuration, begun by the same code)")
    _add_config_options(p)
    p.set_defaults(func=_cmd_generate)

    p = sub.add_parser("report", help="run the paper's protocols on a generated dataset")
    p.add_argument("dataset", help="dataset folder")
    p.add_argument("--out", help="report folder (default: DATASET/report)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes for the protocols' fits")
    p.set_defaults(func=_cmd_report)
