"""Kept unit-load solves on disk: a process reads back what an earlier one solved.

A node's projected unit-load solve Y (n_dof, 3) (:class:`sensors.modal.static_correction.UnitLoadStore`)
costs a forward and backward solve with the model's factorization per column and two
projections: ~10 ms per node on the 10,935-dof ABS bar, the largest part of a moving stream's
first minutes (a rocking bar touches ~300 nodes of the bar and of its plinth before its store
stops growing).  Every new process (a vector env's worker, a dataset worker, the next run)
paid it again.

The bytes are the solve's: a node's columns do not depend on the call that solved them
(``MIN_SOLVE_COLUMNS``, ``SOLVE_COLUMN_BLOCK``), so a file holds exactly what a solve in this
process would give.  A file is used only when all of this is the same as when it was written,
which its folder's key hashes: the model's K, M, kept modes and shift, the factorization
(solver and pivoting), the settings that change a solve's bytes, the code of the modules that
compute it, the machine's architecture and the numpy version.  Each file carries the key, its
node and a sha256 of its bytes: a corrupt, truncated or foreign file is a miss, solved again
and rewritten.  Raw bytes, not ``.npz``: a node reads in 0.5 ms instead of 2.3 and writes in 1.6
instead of 3.5 (0.26 MB, with fsync), in a background thread (:func:`flush` waits for it).
Writes are atomic; a full disk only logs (once) and solves on.

Disk use grows with the nodes a scene touches (24 n_dof bytes per node: 0.26 MB on the ABS
bar, 2.4 MB on a 99k-dof mug), so each model's folder is bounded by
:data:`MAX_MB_PER_MODEL`; once full, new solves are kept in memory only (said once per model).
Each process counts the folder's files when it first writes, so processes writing at once may
overshoot the bound by what they write meanwhile.
Folder: ``$AAS_GYM_CACHE/unit_loads/<model key>/`` (delete it to free the space).
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import logging
import os
import platform
import queue
import shutil
import struct
import threading
import time
from pathlib import Path

import numpy as np

from .._infra import cache as cache_mod
from .._infra.atomic import atomic_open, remove_stale_temp_files

__all__ = ["ENABLED", "MAX_MB_PER_MODEL", "MAX_MB_TOTAL", "FOLDER", "UnitLoadFiles", "flush"]

log = logging.getLogger(__name__)

#: Whether kept unit-load solves are read from and written to disk (True) or solved in every
#: process (False: the reference path).  Read at each call.
ENABLED = True
#: The most disk one model's unit-load files may take [MB]; new solves beyond it stay in memory.
MAX_MB_PER_MODEL = 256.0
#: The most disk all models' unit-load files may take together [MB]: when a process first writes
#: a model's files and the others' folders hold more, the least recently written of them are
#: removed (a change of the code or of a setting in the key leaves its folders behind: they go first).
MAX_MB_TOTAL = 2048.0
#: The folder under the cache directory.
FOLDER = "unit_loads"
# A file: this, the folder's key (64 hex), node and n_dof (int64), Y (n_dof, 3) column-major float64, and the
# sha256 of all that.
_MAGIC = b"AASULF1\n"
# The modules whose code decides a kept solve's bytes.
_MODULES = ("sensors.modal.static_correction", "sensors.fem.pardiso", "sensors.fem.direct_solver",
            "sensors.fem.eigen", "sensors.fem.assembly")


@functools.cache
def _code() -> str:
    # parsing the modules takes ~0.2 s: once per process
    return cache_mod.source_version(*_MODULES)


class UnitLoadFiles:
    """The unit-load files of one :class:`ContactFlexibility` (made by its store on first use).

    Args:
        flex: the model's ``ContactFlexibility`` (K, M, U, sigma, factor).
        settings: the settings that change a solve's bytes (hashed into the folder's key).
        cache_dir: the cache directory (default ``$AAS_GYM_CACHE`` or ``~/.cache/aas_gym``).
    """

    def __init__(self, flex, settings: tuple, cache_dir=None) -> None:
        self.factor, self.settings = flex.factor, settings
        self.cache_dir = Path(cache_dir) if cache_dir is not None else cache_mod.default_cache_dir()
        self.n_dof = int(flex.n_dof)
        pivoting = getattr(getattr(flex.factor, "_f", None), "pivoting", "")
        K, M = flex.K, flex.M
        self.key = cache_mod.content_key(
            "unit-loads", [K.data, K.indices, K.indptr, M.data, M.indices, M.indptr, flex.U], float(flex.sigma),
            getattr(flex.factor, "name", type(flex.factor).__name__), pivoting, settings,
            _code(), platform.machine(), np.__version__, code=False)
        self.folder = self.cache_dir / FOLDER / self.key[:32]
        self.node_mb = self.n_dof * 3 * 8 / 1e6
        self._files: int | None = None      # files in the folder (counted once, then kept up to date)
        self._full_said = False
        self._write_failed = False

    def _path(self, node: int) -> Path:
        return self.folder / f"node-{int(node)}.bin"

    def _header(self, node: int) -> bytes:
        return _MAGIC + self.key.encode() + struct.pack("<qq", int(node), self.n_dof)

    def load(self, nodes) -> dict[int, np.ndarray]:
        """The kept solves (n_dof, 3) of those ``nodes`` that have a valid file."""
        out = {}
        if not self.folder.is_dir():
            return out
        size = len(_MAGIC) + 64 + 16 + 24 * self.n_dof + 32
        for n in nodes:
            path = self._path(n)
            try:
                data = path.read_bytes()
            except FileNotFoundError:
                continue
            except OSError as exc:
                log.warning("ignoring unreadable unit-load file %s: %s", path, exc)
                continue
            if len(data) != size or hashlib.sha256(data[:-32]).digest() != data[-32:]:
                log.warning("ignoring corrupt unit-load file %s (truncated or its checksum does not match); solving again", path)
                continue
            head = len(_MAGIC) + 80
            y = np.frombuffer(data, "<f8", 3 * self.n_dof, head).reshape((self.n_dof, 3), order="F")
            if data[:head] != self._header(n) or not np.isfinite(y).all():
                log.warning("ignoring unit-load file %s: not this model's node %d; solving again", path, n)
                continue
            out[int(n)] = y
        return out

    def save(self, nodes, Y: np.ndarray) -> None:
        """Write each node's columns ``Y[:, 3 i:3 i + 3]`` (within :data:`MAX_MB_PER_MODEL`), in
        the background: the writer thread's file writes overlap the caller's work (written in the
        caller, a first run's steps took 1.11-1.15x longer; now 1.04-1.06x).  :func:`flush` waits for them."""
        if not self._write_failed:
            _enqueue((self, list(nodes), Y))

    def _write(self, nodes, Y: np.ndarray) -> None:
        # the writer thread's part of save (the only thread that touches _files and the flags below)
        if self._write_failed:
            return
        if self._files is None:
            self._files = sum(1 for _ in self.folder.glob("node-*.bin")) if self.folder.is_dir() else 0
            if self.folder.is_dir():
                remove_stale_temp_files(self.folder)             # temporary files of killed writers
            _prune(self.folder.parent, self.folder)
        room = int(MAX_MB_PER_MODEL // self.node_mb) - self._files
        if room < len(nodes) and not self._full_said:
            self._full_said = True
            log.info("unit-load files of model %s: %.0f MB limit reached (%d nodes of %.2f MB); further solves are "
                     "kept in memory only (raise sensors.modal.unit_load_files.MAX_MB_PER_MODEL, or delete %s)",
                     self.key[:12], MAX_MB_PER_MODEL, self._files, self.node_mb, self.folder)
        for i, n in enumerate(list(nodes)[:max(room, 0)]):
            body = self._header(n) + np.asfortranarray(Y[:, 3 * i:3 * i + 3], "<f8").tobytes(order="F")
            try:
                with atomic_open(self._path(n)) as fh:
                    fh.write(body + hashlib.sha256(body).digest())
            except OSError as exc:  # full disk, read-only cache: say so once, solve on in memory
                self._write_failed = True
                log.warning("unit-load files: cannot write %s (%s); solves are kept in memory only", self._path(n), exc)
                return
            self._files += 1


def _prune(root: Path, keep: Path) -> None:
    """Remove the least recently written model folders under ``root`` (never ``keep``) while all
    of them hold more than :data:`MAX_MB_TOTAL`.  Files another process removes meanwhile are
    skipped: a reader of a removed folder solves again."""
    folders, total = [], 0
    try:
        entries = [d for d in root.iterdir() if d.is_dir()]
    except OSError:
        return
    for d in entries:
        try:
            size = sum(f.stat().st_size for f in d.glob("node-*.bin"))
            mtime = d.stat().st_mtime
        except OSError:
            continue
        total += size
        if d != keep:
            folders.append((mtime, size, d))
    for _, size, d in sorted(folders):
        if total <= MAX_MB_TOTAL * 1e6:
            break
        shutil.rmtree(d, ignore_errors=True)
        total -= size
        log.info("unit-load files: removed %s (%.0f MB, least recently written) to stay within %.0f MB "
                 "(sensors.modal.unit_load_files.MAX_MB_TOTAL)", d, size / 1e6, MAX_MB_TOTAL)


# The background writer: one daemon thread per process, started on the first write.  A bounded
# queue (its pending columns: at most _PENDING models' calls) makes a caller wait rather than
# pile up memory when the disk is slow.  At exit pending writes get EXIT_FLUSH_S; a write cut
# short leaves only a temporary file, which a later writer removes.
_PENDING = 16
EXIT_FLUSH_S = 10.0
_state: dict = {"queue": None, "thread": None}
_lock = threading.Lock()


def _writer(q: queue.Queue) -> None:
    while True:
        files, nodes, Y = q.get()
        try:
            files._write(nodes, Y)
        except Exception:  # never let the thread die with writes pending
            log.exception("unit-load files: a write failed; solves are kept in memory only")
            files._write_failed = True
        finally:
            q.task_done()


def _enqueue(item) -> None:
    with _lock:
        if _state["thread"] is None or not _state["thread"].is_alive():
            _state["queue"] = queue.Queue(maxsize=_PENDING)
            _state["thread"] = threading.Thread(target=_writer, args=(_state["queue"],),
                                                name="aas-gym unit-load writer", daemon=True)
            _state["thread"].start()
        q = _state["queue"]
    q.put(item)


def flush(timeout_s: float | None = None) -> bool:
    """Wait until every unit-load file saved so far is written (at most ``timeout_s``); whether
    none is pending."""
    q = _state["queue"]
    if q is None or _state["thread"] is None or not _state["thread"].is_alive():
        return True
    end = None if timeout_s is None else time.monotonic() + timeout_s
    while q.unfinished_tasks:
        if end is not None and time.monotonic() >= end:
            return False
        time.sleep(0.005)
    return True


def _after_fork() -> None:
    # a forked child (an async vector env's worker) has no writer thread: it starts its own
    global _lock
    _lock = threading.Lock()
    _state["queue"] = _state["thread"] = None


os.register_at_fork(after_in_child=_after_fork)
atexit.register(lambda: flush(EXIT_FLUSH_S))
