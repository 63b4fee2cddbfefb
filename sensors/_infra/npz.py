"""Reading the project's ``.npz`` files (observations, leaks, modal models): one error that
names the file and what it should hold, whatever is wrong with it."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np


class FileFormatError(ValueError):
    """A file is not what it should be (corrupt, truncated, or another kind of file)."""


def read_npz(path: str | os.PathLike, required: set[str], what: str) -> dict[str, np.ndarray]:
    """All arrays of the ``.npz`` at ``path``, which must hold ``required``; ``what`` names the
    kind of file in the error (e.g. "an aas-gym observation"). Missing files raise
    ``FileNotFoundError``; anything else that is wrong raises :class:`FileFormatError`."""
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise FileFormatError(f"{path}: not {what} (cannot read it: {exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise FileFormatError(f"{path}: not {what} (a single array, not an .npz archive)")
    with data:
        missing = set(required) - set(data.files)
        if missing:
            raise FileFormatError(f"{path}: not {what} (it lacks {sorted(missing)})")
        try:
            return {k: data[k] for k in data.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise FileFormatError(f"{path}: not {what} (damaged: {exc})") from None
