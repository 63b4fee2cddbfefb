"""The partial files that keep a recording's samples while it runs, and after it stopped early:
``<name>.partial.f32`` (raw samples) described by ``<name>.partial.json``, turned into
``<name>.partial.npz`` by :func:`recover_partial`."""

from __future__ import annotations

import contextlib
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from sensors import AcousticObservation, Excitation
from sensors._infra.atomic import atomic_write_text

from .errors import StorageError


def partial_paths(path: str | os.PathLike) -> tuple[Path, Path, Path]:
    """``(<name>.partial.f32, <name>.partial.json, <name>.partial.npz)`` for final ``path``."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix == ".npz" else path
    return (stem.with_name(stem.name + ".partial.f32"), stem.with_name(stem.name + ".partial.json"),
            stem.with_name(stem.name + ".partial.npz"))


class PartialWriter:
    """Streams input samples to ``<name>.partial.f32`` as they arrive, described by
    ``<name>.partial.json`` (written first), so a crash loses at most the last ~0.5 s.

    A failing disk (full, file too large) never raises here: the writer keeps an exact
    prefix of the samples on disk (unbuffered writes, so a short write is counted), stops
    writing and keeps the first ``OSError`` in ``error`` for the recording loop to report;
    the samples themselves stay in the caller's memory.
    """

    FSYNC_INTERVAL_S = 0.5

    def __init__(self, final_path: Path, header: dict[str, Any]) -> None:
        self.raw_path, self.json_path, self.npz_path = partial_paths(final_path)
        self.frame_bytes = 4 * int(header["channels"])
        self.bytes_written = 0
        self.error: OSError | None = None
        self._fh = None
        self._last_sync = time.monotonic()
        try:
            self.raw_path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(self.json_path, json.dumps({**header, "partial": True, "final_path": str(final_path)}))
            self._fh = open(self.raw_path, "wb", buffering=0)
        except OSError as exc:
            self.error = exc

    @property
    def frames_written(self) -> int:
        """Whole frames on disk."""
        return self.bytes_written // self.frame_bytes

    @property
    def has_data(self) -> bool:
        """A header and at least one whole frame are on disk (what :func:`recover_partial` needs)."""
        return self.json_path.exists() and self.frames_written > 0

    def append(self, block: np.ndarray) -> None:
        """Write ``block`` (frames x channels) after what is on disk (never raises)."""
        if self.error is not None or self._fh is None:
            return
        data = memoryview(np.ascontiguousarray(block, dtype="<f4").tobytes())
        try:
            while data:
                n = self._fh.write(data)
                self.bytes_written += n
                data = data[n:]
            if time.monotonic() - self._last_sync > self.FSYNC_INTERVAL_S:
                os.fsync(self._fh.fileno())
                self._last_sync = time.monotonic()
        except OSError as exc:
            self.error = exc

    def close(self) -> None:
        """Flush to disk and close the raw file (the files stay)."""
        if self._fh is not None and not self._fh.closed:
            try:
                os.fsync(self._fh.fileno())
            except OSError as exc:
                self.error = self.error or exc
            finally:
                self._fh.close()

    def discard(self) -> None:
        """Close and remove the raw and header files (once the samples are safe elsewhere)."""
        self.close()
        for p in (self.raw_path, self.json_path):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


def recover_partial(path: str | os.PathLike, out_dir: str | os.PathLike | None = None) -> Path | None:
    """Turn the raw ``<name>.partial.f32`` + ``.partial.json`` left by a killed process (or by
    a disk that filled up) into ``<name>.partial.npz`` (an ``AcousticObservation`` with
    ``metadata["partial"] = True``). ``path`` is the final recording path or either partial
    file. Returns the .npz, or None if there is nothing to recover.

    ``out_dir``: write the .npz there instead of beside the partial files (when their disk is
    full). The raw files are removed only once the .npz is safely written; if it cannot be,
    :class:`real.StorageError` says so and they stay.
    """
    p = Path(path)
    name = p.name
    for suffix in (".partial.f32", ".partial.json", ".partial.npz"):
        if name.endswith(suffix):
            p = p.with_name(name[: -len(suffix)])
    raw, js, npz = partial_paths(p)
    if out_dir is not None:
        npz = Path(out_dir) / npz.name
    if not (raw.exists() and js.exists()):
        return npz if npz.exists() else None
    header = json.loads(js.read_text())
    channels = int(header["channels"])
    buf = raw.read_bytes()  # whole frames only: a full disk may have cut the last one short
    data = np.frombuffer(buf[: len(buf) - len(buf) % (4 * channels)], dtype="<f4").reshape(-1, channels)
    if data.shape[0] == 0:
        raw.unlink()
        js.unlink()
        return None
    meta = dict(header.get("metadata", {}))
    meta.update({"partial": True, "complete": False,
                 "error": meta.get("error") or "recovered from the partial files (the recording process ended "
                                               "abruptly, or the disk filled up)"})
    obs = AcousticObservation(waveform=data[:, int(header["mic_channel"])], sample_rate_hz=int(header["sample_rate_hz"]),
                              excitation=Excitation.from_dict(header["excitation"]), start_time_s=0.0, metadata=meta)
    try:
        obs.save(npz)  # creates out_dir
    except OSError as exc:
        raise StorageError(f"cannot write {npz} ({exc.strerror or exc}); the partial files {raw.name} and {js.name} "
                           f"are kept: real.recover_partial({str(path)!r}, out_dir=<a folder on another disk>)",
                           cause=exc) from exc
    raw.unlink()
    js.unlink()
    return npz
