"""Write files whole or not at all: a crash never leaves a half-written file that looks whole.

The data go to a temporary file in the target's folder, are flushed to disk, and the file is
renamed over the target (atomic on POSIX); on any error the temporary file is removed. The
final file gets the mode an ordinary ``open`` would give it (0666 less the user's umask): the
temporary file's private 0600 is not what the user asked for.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO]:
    """``with atomic_open(path) as fh: ...`` writes ``path`` atomically (``mode`` "wb" or "w")."""
    if mode not in ("wb", "w"):
        raise ValueError(f"mode must be 'wb' or 'w', got {mode!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # The writer's pid in the name lets a later writer tell a killed writer's leftover from a live one.
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp")
    try:
        with os.fdopen(fd, mode) as fh:
            yield fh
            fh.flush()
            os.chmod(fh.fileno(), 0o666 & ~_umask())
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


#: A temporary file older than this [s] is a leftover whatever its pid says (no write takes an hour).
STALE_TEMP_AGE_S = 3600.0


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # exists (another user's) or cannot tell: keep its file
    return True


def remove_stale_temp_files(folder: str | os.PathLike, max_age_s: float = STALE_TEMP_AGE_S) -> int:
    """Remove the temporary files of :func:`atomic_open` in ``folder`` that a killed writer left
    (kill -9 skips the clean-up): those older than ``max_age_s`` or whose writer's pid is gone
    (on this machine). Returns how many it removed; files it cannot remove are left alone."""
    removed = 0
    now = time.time()
    try:
        candidates = list(Path(folder).glob(".*.tmp"))
    except OSError:
        return 0
    for tmp in candidates:
        parts = tmp.name.split(".")  # "", <target name parts...>, <pid>, <random>, "tmp"
        pid = int(parts[-3]) if len(parts) >= 5 and parts[-3].isdigit() else None
        try:
            old = now - tmp.stat().st_mtime > max_age_s
            if old or (pid is not None and pid != os.getpid() and not _pid_alive(pid)):
                tmp.unlink()
                removed += 1
        except OSError:
            continue
    return removed


def _umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


def atomic_savefig(fig, path: str | os.PathLike, **kwargs) -> None:
    """``fig.savefig`` written atomically (the format follows ``path``'s suffix)."""
    path = Path(path)
    with atomic_open(path, "wb") as fh:
        fig.savefig(fh, format=path.suffix.lstrip(".") or None, **kwargs)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)
