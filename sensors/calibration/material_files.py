"""Calibrated materials as JSON files: :func:`save_material` and :func:`load_material`."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._infra.atomic import atomic_write_text
from ..materials.solids import Material

MATERIAL_FILE_FORMAT = "aas-gym material"


def save_material(path: str | os.PathLike, material: Material, *, calibration: dict[str, Any] | None = None) -> Path:
    """Write ``material`` as JSON (atomically), optionally with a calibration report.

    The file holds ``{"format": "aas-gym material", "version": 1, "material": {...},
    "calibration": {...}}``; :func:`load_material` reads it back.
    """
    path = Path(path)
    doc = {"format": MATERIAL_FILE_FORMAT, "version": 1, "material": material.to_dict()}
    if calibration is not None:
        doc["calibration"] = calibration
    atomic_write_text(path, json.dumps(doc, indent=2, default=_json_default) + "\n")
    return path


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    raise TypeError(f"not JSON-serialisable: {type(obj).__name__}")


def load_material(path: str | os.PathLike) -> Material:
    """Read a material file written by :func:`save_material` (or a bare ``Material.to_dict()``
    JSON object) as a :class:`sensors.Material`."""
    with open(path) as fh:
        doc = json.load(fh)
    if isinstance(doc, dict) and doc.get("format") == MATERIAL_FILE_FORMAT:
        if int(doc.get("version", 1)) != 1:
            raise ValueError(f"{path}: unsupported material file version {doc.get('version')!r}")
        doc = doc["material"]
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a material file")
    try:
        return Material.from_dict(doc)
    except KeyError as exc:
        raise ValueError(f"{path}: material lacks field {exc.args[0]!r}") from None
