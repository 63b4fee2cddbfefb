"""Sharded, resumable, deterministic dataset generation on processes or a Ray cluster.

Output folder::

    .dataset.json         config, its fingerprint, shard count (written first; a dot file,
                          so Arrow, pandas and Hugging Face datasets read the folder as shards)
    README.md             the dataset card (Hugging Face's format: columns, units, how it was
                          made, licence), written once every shard is on disk
    shard-00000.parquet   one Parquet file per shard, written atomically, carrying the
    ...                   config fingerprint and a checksum of its rows

Each shard is computed by a worker (a local process or a Ray task) and returned as Parquet
bytes; only the driver writes, by write-to-temporary-then-rename, so an interrupted run
leaves whole shards only, and a rerun computes just the missing ones. A shard's bytes depend
only on the config, never on the backend or the worker count. Read the result with
:func:`load_dataset` (pandas, every shard verified), Hugging Face ``datasets.load_dataset(folder)``
(through the card), or the shards themselves: ``pandas.read_parquet(folder,
ignore_prefixes=[".", "_", "README"])``, ``pyarrow.dataset.dataset(sorted(folder.glob("shard-*.parquet")))``
(Arrow reads every file of a folder as Parquet unless told to skip the card).

A shard is trusted only if its footer names this configuration's fingerprint and its rows
hash to the checksum it carries: on resume a foreign (another seed) or corrupt shard is
computed again; on load it is an error naming the shard.
"""

from __future__ import annotations

import ctypes
import contextlib
import hashlib
import io
import json
import os
import signal
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from aas_gym.experiments.config import DatasetConfig, code_version
from sensors._infra.atomic import atomic_write_bytes

FORMAT = "aas-gym-dataset/1"
#: How long an explicit Ray address may take to answer a TCP connection.
RAY_CONNECT_TIMEOUT_S = 10.0
MANIFEST = ".dataset.json"
# Datasets written before the manifest was renamed: still read, renamed on the next resume.
LEGACY_MANIFEST = "dataset.json"


class ShardError(ValueError):
    """A shard that is not this dataset's: another configuration's, or corrupt."""


class ManifestError(ValueError):
    """A dataset folder whose manifest (``.dataset.json``) cannot be read."""


def read_manifest(path: Path, remedy: str) -> dict[str, Any]:
    """The manifest at ``path``; ``ManifestError`` naming the file, what is wrong and
    ``remedy`` if it is not JSON (a truncated write) or lacks what a dataset needs."""
    try:
        manifest = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ManifestError(f"{path} is damaged ({exc}): the dataset's configuration cannot be read; {remedy}") from None
    if not (isinstance(manifest, dict) and isinstance(manifest.get("fingerprint"), str)
            and isinstance(manifest.get("n_shards"), int) and not isinstance(manifest.get("n_shards"), bool)):
        raise ManifestError(f"{path} is not an aas-gym dataset manifest (no fingerprint or shard count); {remedy}")
    return manifest


def shard_path(out_dir: Path, index: int) -> Path:
    return out_dir / f"shard-{index:05d}.parquet"


@contextlib.contextmanager
def single_threaded():
    """Every numerical thread pool of the process at one thread, for the block.

    One worker per core: threads inside a worker would only oversubscribe the cores. It is also
    what makes a shard's bytes the same in every process: PARDISO's factorization and BLAS sum in
    another order with another thread count, which moves float32 features by a rounding step.
    ``threadpoolctl`` limits only the libraries loaded when the block starts, and a fresh worker
    has not loaded MKL (PARDISO) or SciPy's BLAS yet, so they are loaded first.
    """
    import scipy.linalg  # noqa: F401 - loads SciPy's BLAS/LAPACK
    from threadpoolctl import threadpool_limits

    from sensors.fem.pardiso import mkl_library

    mkl_library()
    with threadpool_limits(1):
        yield


def compute_shard(config_dict: dict[str, Any], shard_index: int) -> bytes:
    """Simulate one shard and return it as Parquet bytes (runs in a worker)."""
    from aas_gym.experiments.simulate import run_task

    from sensors._infra.lru import clear_all

    config = DatasetConfig.from_dict(config_dict)
    tasks = config.shards()[shard_index]
    clear_all()      # the shard's bytes depend on its config only, not on the worker's history
    rows: list[dict[str, Any]] = []
    with single_threaded():
        for task in tasks:
            rows += run_task(task, config)
    return rows_to_parquet(rows, config)


def rows_to_parquet(rows: list[dict[str, Any]], config: DatasetConfig) -> bytes:
    """Rows (dicts of scalars and 1-D arrays) -> deterministic Parquet bytes."""
    columns: dict[str, pa.Array] = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        if isinstance(values[0], np.ndarray):
            flat = np.stack(values).astype(np.float32)
            columns[key] = pa.FixedSizeListArray.from_arrays(pa.array(flat.ravel()), flat.shape[1])
        else:
            columns[key] = pa.array(values)
    table = pa.table(columns)
    table = table.replace_schema_metadata({"aas_gym_format": FORMAT, "config_fingerprint": config.fingerprint(),
                                           "rows_sha256": _rows_digest(table)})
    buf = io.BytesIO()
    pq.write_table(table, buf, compression="zstd")
    return buf.getvalue()


def _rows_digest(table: pa.Table) -> str:
    """SHA-256 of the table's rows, independent of how Parquet chunks them: each column's name,
    type and values (array columns as their float32 bytes, others as exact JSON)."""
    h = hashlib.sha256()
    for name in table.column_names:
        col = table[name].combine_chunks()
        if pa.types.is_fixed_size_list(col.type):  # Parquet renames the child field: not hashed
            h.update(f"{name}:list[{col.type.list_size}]\n".encode())
            h.update(np.ascontiguousarray(col.flatten().to_numpy(zero_copy_only=False), np.float32).tobytes())
        else:
            h.update(f"{name}:{col.type}\n".encode())
            h.update(json.dumps(col.to_pylist(), default=repr).encode())
    return h.hexdigest()


def read_shard(path: Path, fingerprint: str, *, allow_unverified: bool = False) -> pa.Table:
    """The shard's rows, verified: ``ShardError`` naming the file if it belongs to another
    configuration, cannot be read, or its rows do not hash to its checksum. A shard written
    before shards carried checksums is refused, or with ``allow_unverified`` loaded with a
    warning that says so."""
    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise ShardError(f"shard {path} cannot be read ({type(exc).__name__}: {exc})") from None
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items()}
    if meta.get("config_fingerprint") != fingerprint:
        raise ShardError(f"shard {path} belongs to another configuration (fingerprint "
                         f"{meta.get('config_fingerprint')} != {fingerprint})")
    if "rows_sha256" not in meta:
        if not allow_unverified:
            raise ShardError(f"shard {path} predates shard checksums: its rows cannot be verified")
        warnings.warn(f"shard {path} predates shard checksums: its rows are not verified "
                      "(resume the generation to rewrite it with one)", stacklevel=3)
    elif meta["rows_sha256"] != _rows_digest(table):
        raise ShardError(f"shard {path} is corrupt: its rows do not match its checksum")
    return table


def _manifest_path(out_dir: Path) -> Path:
    legacy = out_dir / LEGACY_MANIFEST
    return legacy if legacy.exists() and not (out_dir / MANIFEST).exists() else out_dir / MANIFEST


def _prepare(out_dir: Path, config: DatasetConfig, overwrite: bool) -> list[int]:
    """Write or check the manifest; return the shard indices still to compute."""
    out_dir.mkdir(parents=True, exist_ok=True)
    manifest_path = _manifest_path(out_dir)
    n_shards = len(config.shards())
    manifest = {"format": FORMAT, "fingerprint": config.fingerprint(), "n_shards": n_shards,
                "n_tasks": len(config.tasks()), "config": config.to_dict(), "code_version": code_version(),
                "robot": config.robot}
    if manifest_path.exists() and not overwrite:
        old = read_manifest(manifest_path, f"regenerate into {out_dir} with overwrite=True (--overwrite), "
                                           "or choose another folder")
        same_config = old.get("config") == json.loads(json.dumps(manifest["config"]))  # tuples as JSON lists
        if old.get("fingerprint") != manifest["fingerprint"] and same_config:
            raise FileExistsError(
                f"{out_dir} holds a dataset begun by other aas-gym code (source {old.get('code_version', 'unrecorded')}"
                f" != {manifest['code_version']}): finishing it would mix shards of both; choose another folder or "
                "pass overwrite=True (--overwrite)"
            )
        if old.get("fingerprint") != manifest["fingerprint"]:
            raise FileExistsError(
                f"{out_dir} holds a dataset with another configuration (fingerprint {old.get('fingerprint')} "
                f"!= {manifest['fingerprint']}); choose another folder or pass overwrite=True (--overwrite)"
            )
    else:
        for stale in out_dir.glob("shard-*.parquet"):
            stale.unlink()
    if manifest_path.name != MANIFEST or overwrite or not manifest_path.exists():
        atomic_write_bytes(out_dir / MANIFEST, json.dumps(manifest, indent=2, sort_keys=True).encode())
        if manifest_path.name == LEGACY_MANIFEST:
            manifest_path.unlink()
    for tmp in out_dir.glob(".shard-*.tmp"):  # left by a killed run; never renamed, never whole
        tmp.unlink()
    todo = []
    for i in range(n_shards):
        path = shard_path(out_dir, i)
        if path.exists():
            try:
                read_shard(path, manifest["fingerprint"])
                continue
            except ShardError:  # foreign or corrupt: compute again
                path.unlink()
        todo.append(i)
    return todo


def _local_results(config: DatasetConfig, todo: list[int], workers: int) -> Iterator[tuple[int, bytes]]:
    cfg = config.to_dict()
    if workers <= 1:
        for i in todo:
            yield i, compute_shard(cfg, i)
        return
    # spawn: BLAS, numba and MuJoCo threads do not survive fork reliably.
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"),
                             initializer=die_with_parent, initargs=(os.getpid(),)) as pool:
        pending = {pool.submit(compute_shard, cfg, i): i for i in todo}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    yield pending.pop(fut), fut.result()
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise


def die_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """Worker initializer: end this process when the driver dies, even by ``kill -9`` (which
    runs no cleanup), so no worker (~350 MB each) outlives it. Linux delivers SIGKILL on the
    parent's death (``prctl(PR_SET_PDEATHSIG)``); a watchdog thread that polls the parent pid
    covers other systems and the race before the prctl took effect."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(1)
            time.sleep(poll_s)

    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def ray_endpoint(address: str) -> tuple[str, int] | None:
    """(host, port) of an explicit Ray address, ``None`` for ``auto``; ``ValueError`` if malformed."""
    if address == "auto":
        address = os.environ.get("RAY_ADDRESS", "auto")
        if address == "auto":
            return None  # Ray looks for a cluster started on this machine
    rest = address.split("://", 1)[1] if "://" in address else address
    host, _, port = rest.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"Ray address {address!r} is not 'local', 'auto', HOST:PORT or ray://HOST:PORT")
    return host.strip("[]"), int(port)


def check_ray_reachable(address: str, timeout_s: float = RAY_CONNECT_TIMEOUT_S) -> None:
    """Fail within ``timeout_s`` with a ``ConnectionError`` naming ``address`` if nothing
    answers there (``ray.init`` itself retries for minutes)."""
    endpoint = ray_endpoint(address)
    if endpoint is None:
        return
    try:
        socket.create_connection(endpoint, timeout=timeout_s).close()
    except OSError as exc:
        raise ConnectionError(f"cannot reach the Ray cluster at {address} within {timeout_s:.0f} s ({exc}); "
                              f"check the address, or use --ray-address local") from None


@contextmanager
def _loopback_ray(ray):
    """Make a Ray instance started in this block bind every service to 127.0.0.1.

    ``ray.init(_node_ip_address="127.0.0.1")`` alone is overridden: Ray swaps a loopback
    node address for the machine's external one unless its single-machine mode is on. That
    mode (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``, Ray's switch for laptops) is read from the
    environment by the services Ray starts, and from ``ray_constants`` by this process
    (imported before we could set the variable). ``RAY_ADDRESS`` is hidden so that nothing
    started here joins another cluster.
    """
    from ray._private import ray_constants

    saved_env = {k: os.environ.get(k) for k in ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "RAY_ADDRESS")}
    saved_flag = getattr(ray_constants, "ENABLE_RAY_CLUSTER", None)
    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    os.environ.pop("RAY_ADDRESS", None)
    ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        for key, value in saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        if saved_flag is not None:
            ray_constants.ENABLE_RAY_CLUSTER = saved_flag


def start_ray(address: str) -> None:
    """Start (``"local"``) or join (any other address) a Ray instance for this process.

    A local instance listens on 127.0.0.1 only and ignores ``$RAY_ADDRESS``; another address
    must answer within :data:`RAY_CONNECT_TIMEOUT_S`.
    """
    import ray  # optional dependency (extra 'ray')

    if address == "local":
        with _loopback_ray(ray):
            ray.init(address="local", _node_ip_address="127.0.0.1", include_dashboard=False,
                     dashboard_host="127.0.0.1", log_to_driver=False)
        node_ip = ray.util.get_node_ip_address()
        if node_ip not in ("127.0.0.1", "::1", "localhost"):
            ray.shutdown()
            raise RuntimeError(f"the local Ray instance took the address {node_ip}, not 127.0.0.1: "
                               f"refusing to run it open to the network (this Ray version binds differently)")
    else:
        check_ray_reachable(address)
        ray.init(address=address, log_to_driver=False)


def _ray_results(config: DatasetConfig, todo: list[int], address: str) -> Iterator[tuple[int, bytes]]:
    import ray  # optional dependency (extra 'ray')

    started_here = not ray.is_initialized()
    if started_here:
        start_ray(address)
    try:
        remote = ray.remote(num_cpus=1)(compute_shard)
        cfg = ray.put(config.to_dict())
        refs = {remote.remote(cfg, i): i for i in todo}
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1)
            for ref in done:
                yield refs.pop(ref), ray.get(ref)
    finally:
        if started_here:
            ray.shutdown()


def generate_dataset(
    config: DatasetConfig,
    out_dir: str | os.PathLike,
    *,
    workers: int = 1,
    ray_address: str | None = None,
    overwrite: bool = False,
    progress: bool = True,
    on_shard: Callable[[int], None] | None = None,
    command: str | None = None,
) -> Path:
    """Generate (or finish generating) a dataset into ``out_dir``.

    Args:
        config: what to generate.
        out_dir: output folder; an existing one with the same config is resumed.
        workers: local worker processes (1 = in this process). Ignored with ``ray_address``.
        ray_address: ``"local"`` to start a local Ray instance (every service on 127.0.0.1,
            ``$RAY_ADDRESS`` ignored), or a cluster address (``"auto"``,
            ``"ray://host:10001"``), which must answer within ``RAY_CONNECT_TIMEOUT_S``;
            ``None`` uses local processes.
        overwrite: discard an existing dataset with another config.
        progress: show a progress bar.
        on_shard: called with each shard index once it is on disk.
        command: how the dataset was made, for its card (``aas generate`` passes its command
            line; None: this function's call).
    """
    from aas_gym.experiments.card import write_card
    from tqdm.auto import tqdm

    out = Path(out_dir)
    if ray_address not in (None, "local"):
        check_ray_reachable(ray_address)  # before anything is written
    todo = _prepare(out, config, overwrite)
    shards = config.shards()
    results = _ray_results(config, todo, ray_address) if ray_address else _local_results(config, todo, workers)
    total = sum(len(s) for s in shards)
    done_tasks = total - sum(len(shards[i]) for i in todo)
    with tqdm(total=total, initial=done_tasks, unit="grasp", disable=not progress, desc="generating") as bar:
        for index, data in results:
            atomic_write_bytes(shard_path(out, index), data)
            bar.update(len(shards[index]))
            if on_shard is not None:
                on_shard(index)
    write_card(out, config, read_manifest(out / MANIFEST, "regenerate it with overwrite=True"), command)
    return out


def load_dataset(out_dir: str | os.PathLike):
    """All shards of a finished dataset as one pandas DataFrame, in task order.

    Array columns (``features``, ``waveform``) hold one NumPy array per row.
    """
    import pandas as pd

    out = Path(out_dir)
    manifest_path = _manifest_path(out)
    if not manifest_path.exists():
        raise FileNotFoundError(f"{out} is not a dataset: it has no {MANIFEST} (make one with `aas generate {out}`)")
    manifest = read_manifest(manifest_path, f"regenerate it with `aas generate {out} --overwrite` and its "
                                            "configuration, or generate into another folder")
    paths = [shard_path(out, i) for i in range(manifest["n_shards"])]
    missing = [p.name for p in paths if not p.exists()]
    if missing:
        raise FileNotFoundError(f"dataset in {out} is incomplete: {len(missing)} shards missing "
                                f"(first: {missing[0]}); run the generation again to finish it")
    tables = [read_shard(p, manifest["fingerprint"], allow_unverified=True) for p in paths]
    return pd.concat([t.to_pandas() for t in tables], ignore_index=True)
