"""Content-addressed on-disk cache for tet meshes and modal models.

A key is the SHA-256 of everything the result depends on (geometry, material, options) plus
:data:`CODE_VERSION`, a hash of the source of the modules that compute it, so editing the
solver invalidates old entries instead of silently serving stale modes. Entries are ``.npz``
files written atomically (temp file + rename), safe with several processes sharing a cache.

Directory: ``$AAS_GYM_CACHE`` if set, else ``~/.cache/aas_gym``.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import hashlib
import importlib.util
import json
import logging
import os
import threading
from pathlib import Path

import numpy as np

from .atomic import atomic_open, remove_stale_temp_files

__all__ = ["CODE_VERSION", "code_version", "source_version", "default_cache_dir", "content_key", "load_arrays", "save_arrays", "entry_path"]

log = logging.getLogger(__name__)

# The modules whose code decides what a cache entry holds (queries on a built model do not;
# this module's own key derivation changes the keys by itself when it changes). Meshes: every
# module that makes or checks a cached or keyed tet mesh (layered meshes are keyed by their
# content, and their code by the everyday objects' own alias key).
SOURCE_MODULES = ("sensors.mesh.tets", "sensors.mesh.prisms", "sensors.mesh.quadratic", "sensors.mesh.intersections",
                  "sensors.mesh.tetwild", "sensors.mesh.surface", "sensors.fem.assembly", "sensors.fem.eigen",
                  "sensors.fem.mirror",
                  "sensors.modal.build", "sensors.modal.io", "sensors.materials.solids")


def code_digest(source: str) -> bytes:
    """What of a module's source a result can depend on: its code, without import statements,
    docstrings and comments (``ast.dump`` of the rest). Moving a module, which rewrites its
    relative imports, or editing its prose therefore changes no key; editing its code does."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        kept = [n for n in body if not isinstance(n, (ast.Import, ast.ImportFrom))]
        if kept and isinstance(kept[0], ast.Expr) and isinstance(getattr(kept[0], "value", None), ast.Constant) \
                and isinstance(kept[0].value.value, str):
            kept = kept[1:]
        node.body = kept or [ast.Pass()]
    return ast.dump(tree, include_attributes=False).encode()


def source_version(*modules: str) -> str:
    """Hash of the code of the named modules (dotted names, e.g. ``"sensors.fem.assembly"``), found where
    Python would import them from, without importing them; a key part that changes when their
    code does. Only the code is hashed, not the names, so a module moved under a new name and
    listed under it keeps every key (see :func:`code_digest`)."""
    h = hashlib.sha256()
    for name in modules:
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.origin or not spec.origin.endswith(".py"):
            raise ValueError(f"source_version: no Python source for module {name!r}")
        h.update(code_digest(Path(spec.origin).read_text(encoding="utf-8")))
        h.update(b"\0")
    return h.hexdigest()[:16]


#: One computation of :func:`code_version` per process: a cold object build asks for it in two
#: threads at once (CoACD's and the modes'), which parsed the modules twice, under the GIL.
_CODE_VERSION_LOCK = threading.Lock()


@functools.cache
def _code_version() -> str:
    return source_version(*SOURCE_MODULES)


def code_version() -> str:
    """Hash of the code of the modules that produce cached results (``CODE_VERSION``).

    Computed on first use, not at import: parsing those modules takes ~0.1 s, which
    ``import sensors`` should not pay."""
    with _CODE_VERSION_LOCK:
        return _code_version()


def __getattr__(name: str):
    if name == "CODE_VERSION":
        return code_version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def default_cache_dir() -> Path:
    """``$AAS_GYM_CACHE`` or ``~/.cache/aas_gym``."""
    env = os.environ.get("AAS_GYM_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "aas_gym"


def _feed(h, obj) -> None:
    if isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"nd{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    elif isinstance(obj, (list, tuple)):
        h.update(f"seq{len(obj)}".encode())
        for item in obj:
            _feed(h, item)
    elif isinstance(obj, dict):
        h.update(json.dumps(obj, sort_keys=True, default=repr).encode())
    else:
        h.update(repr(obj).encode())
    h.update(b"|")


def content_key(*parts, code: bool = True) -> str:
    """SHA-256 hex key of ``parts`` (arrays, numbers, strings, dicts) and, with ``code``, the code
    version (a result that none of :data:`SOURCE_MODULES` computes puts its own code in ``parts``)."""
    h = hashlib.sha256()
    if code:
        _feed(h, code_version())
    for part in parts:
        _feed(h, part)
    return h.hexdigest()


def _dir(cache_dir) -> Path:
    return Path(cache_dir) if cache_dir is not None else default_cache_dir()


def entry_path(key: str, cache_dir=None) -> Path:
    """Path of the cache entry for ``key``."""
    return _dir(cache_dir) / f"{key}.npz"


#: Name of the content checksum stored with every entry.
CHECKSUM = "_sha256"


def _checksum(arrays: dict) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        if name != CHECKSUM:
            _feed(h, name)
            _feed(h, np.asarray(arrays[name]))
    return h.hexdigest()


def load_arrays(key: str, cache_dir=None) -> dict | None:
    """The arrays stored under ``key``, or None: missing, unreadable or corrupt entries (their
    content checksum does not match, or they have none) are misses, rebuilt and rewritten."""
    path = entry_path(key, cache_dir)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as exc:  # a truncated or foreign file: treat as a miss, it will be rewritten
        log.warning("ignoring unreadable cache entry %s: %s", path, exc)
        return None
    stored = str(arrays.pop(CHECKSUM, ""))
    if stored != _checksum(arrays):
        log.warning("ignoring corrupt cache entry %s: its content checksum does not match", path)
        return None
    return arrays


#: Cache folders whose killed writers' temporary files this process has removed.
_CLEANED: set[str] = set()


def _clean_once(folder: Path) -> None:
    """Remove the temporary files killed writers left in ``folder`` (once per folder and process)."""
    if str(folder) not in _CLEANED:
        _CLEANED.add(str(folder))
        n = remove_stale_temp_files(folder)
        if n:
            log.info("removed %d temporary files left by killed cache writers in %s", n, folder)


def save_arrays(key: str, arrays: dict, cache_dir=None) -> Path | None:
    """Store ``arrays`` under ``key`` atomically with a content checksum; returns the path
    (None if not writable)."""
    path = entry_path(key, cache_dir)
    _clean_once(path.parent)
    try:
        with atomic_open(path) as f:
            np.savez(f, **arrays, **{CHECKSUM: np.array(_checksum(arrays))})
        return path
    except OSError as exc:
        log.warning("could not write cache entry %s: %s", path, exc)
        return None


@contextlib.contextmanager
def build_lock(key: str, cache_dir=None):
    """Hold an exclusive lock on ``key`` while building its entry, so that processes that
    miss the cache together (dataset workers) build it once and the others then load it.
    Without POSIX file locks, or in a read-only cache, it does not lock."""
    try:
        import fcntl
    except ImportError:  # Windows
        yield
        return
    lock_dir = _dir(cache_dir) / "locks"
    try:
        lock_dir.mkdir(parents=True, exist_ok=True)
        fh = open(lock_dir / f"{key}.lock", "a")
    except OSError:
        yield
        return
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
