"""ModalModel files: ``.npz`` archives of plain arrays and JSON (no pickle), written atomically;
the same arrays are the disk cache's entries."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._infra.atomic import atomic_open
from ..materials.solids import Material
from .._infra.npz import FileFormatError, read_npz

__all__ = ["load", "save", "to_arrays", "from_arrays"]


def to_arrays(model) -> dict:
    """The model as named arrays (what :func:`save` writes and the cache stores)."""
    return {
        "nodes_m": model.nodes_m,
        "elements": model.elements,
        "frequencies_hz": model.frequencies_hz,
        "mode_shapes": model.mode_shapes,
        "element": np.array(model.element),
        "material": np.array(json.dumps(model.material.to_dict())),
        "metadata": np.array(json.dumps(model.metadata, default=repr)),
    }


def from_arrays(cls, data: dict):
    """``cls`` (``ModalModel``) from :func:`to_arrays`' output."""
    return cls(data["nodes_m"], data["elements"], data["frequencies_hz"], data["mode_shapes"],
               Material.from_dict(json.loads(str(data["material"]))), element=str(data["element"]),
               metadata=json.loads(str(data["metadata"])))


def save(model, path) -> Path:
    """Write ``model`` to an ``.npz`` file (no pickle, atomically); returns the path."""
    path = Path(path)
    with atomic_open(path) as f:
        np.savez(f, **to_arrays(model))
    return path


def load(cls, path):
    """Read a model written by :func:`save` (``FileFormatError`` naming the file otherwise,
    including a model whose frequencies or shapes are not finite or not ascending)."""
    data = read_npz(path, {"nodes_m", "elements", "frequencies_hz", "mode_shapes", "material", "metadata"},
                    "an aas-gym modal model")
    try:
        return from_arrays(cls, data)
    except (KeyError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{path}: not a valid aas-gym modal model ({exc})") from None
