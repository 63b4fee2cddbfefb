"""The dataset card (``README.md``) of a generated dataset, in Hugging Face's format.

YAML front matter (licence, task categories, tags, the Parquet shards as the ``train`` split
under ``configs``, every column's dtype under ``dataset_info``), then what each column means
with its unit, how the dataset was made (command, package and code version, seed,
configuration) and its licence. ``datasets.load_dataset(folder)`` reads the folder through it.
"""

from __future__ import annotations

import json
from importlib import metadata
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from aas_gym.experiments.config import DatasetConfig
from sensors._infra.atomic import atomic_write_text

__all__ = ["CARD", "COLUMNS", "LICENSE", "card_text", "write_card"]

CARD = "README.md"
#: The project's licence (pyproject.toml), as a Hugging Face licence id.
LICENSE = "apache-2.0"
SHARDS_GLOB = "shard-*.parquet"

#: What each column of a dataset holds: ``(unit, meaning)``; unit "" for labels and counts.
COLUMNS: dict[str, tuple[str, str]] = {
    "task_id": ("", "the grasp this row comes from: `<scene>/<object>/g<grasp>` or "
                    "`position/<object>/p<position>/r<repeat>`"),
    "scene": ("", "`single`: the object alone on the table; `multi`: other objects lean on it; "
                  "`position`: the grasp-position sweep"),
    "object": ("", "the object's label (`<material>_<shape>`, an everyday object's name, or a user mesh's)"),
    "material": ("", "the object's material (`sensors.materials`)"),
    "shape": ("", "the object's shape (`bar`, `tube`, `rod`, an everyday shape, ...)"),
    "excitation": ("", "what the actuator played: `impulse`, `linear` or `exponential` sweep"),
    "grasp_index": ("", "the grasp's index within its object and scene (the repeat at a position in `position`)"),
    "position_m": ("m", "commanded grasp position along the object's main axis from its centre (prisms), "
                        "or along its grasp path from the first grasp (other shapes)"),
    "grip_force_n": ("N", "the gripper actuator's force during the recording"),
    "n_other_contacts": ("", "contacts of the object besides the two fingertips (table, other objects)"),
    "other_contact_force_n": ("N", "total normal force of those contacts"),
    "features": ("microphone full scale (linear amplitude)",
                 "the paper's 140 spectral amplitudes of the first `duration_s` of the recording, "
                 "at 3000, 3050, ..., 9950 Hz (`sensors.feature_frequencies_hz`)"),
    "waveform": ("microphone full scale, 44.1 kHz", "the raw microphone samples (with `store_waveforms`)"),
}


def _yaml_dtype(name: str, arrow_type: pa.DataType) -> dict[str, Any]:
    """A column's entry of ``dataset_info.features`` (Hugging Face ``datasets`` YAML)."""
    if pa.types.is_fixed_size_list(arrow_type) or pa.types.is_list(arrow_type):
        entry: dict[str, Any] = {"name": name, "sequence": _value_dtype(arrow_type.value_type)}
        if pa.types.is_fixed_size_list(arrow_type):
            entry["length"] = arrow_type.list_size
        return entry
    return {"name": name, "dtype": _value_dtype(arrow_type)}


#: Arrow type names that ``datasets`` spells otherwise (the rest, int64, bool, string, agree).
_DTYPES = {"halffloat": "float16", "float": "float32", "double": "float64", "large_string": "large_string"}


def _value_dtype(arrow_type: pa.DataType) -> str:
    return _DTYPES.get(str(arrow_type), str(arrow_type))


def _size_category(n: int) -> str:
    for limit, name in ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"), (1_000_000, "100K<n<1M")):
        if n < limit:
            return name
    return "n>1M"


def _yaml(value: Any, indent: int = 0) -> list[str]:
    """A small YAML emitter for the front matter (dicts, lists, scalars; strings JSON-quoted,
    which YAML reads as double-quoted scalars)."""
    pad = " " * indent
    lines: list[str] = []
    if isinstance(value, dict):
        for key, item in value.items():
            if isinstance(item, (dict, list)) and item:
                lines.append(f"{pad}{key}:")
                lines += _yaml(item, indent + (0 if isinstance(item, list) else 2))
            else:
                lines.append(f"{pad}{key}: {_scalar(item)}")
    elif isinstance(value, list):
        for item in value:
            sub = _yaml(item, indent + 2)
            lines.append(f"{pad}- {sub[0].lstrip()}")
            lines += sub[1:]
    else:
        lines.append(pad + _scalar(value))
    return lines


def _scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return json.dumps(str(value))


def card_text(folder: Path, config: DatasetConfig, manifest: dict[str, Any], command: str | None = None) -> str:
    """The card of the finished dataset in ``folder`` (its shards' schema and row counts)."""
    shards = sorted(folder.glob(SHARDS_GLOB))
    if not shards:
        raise FileNotFoundError(f"{folder} has no {SHARDS_GLOB}: nothing to describe")
    schema = pq.read_schema(shards[0])
    n_rows = sum(pq.ParquetFile(p).metadata.num_rows for p in shards)
    n_bytes = sum(p.stat().st_size for p in shards)
    front = {
        "license": LICENSE,
        "pretty_name": "aas-gym simulated active acoustic sensing",
        "task_categories": ["audio-classification", "tabular-classification", "tabular-regression"],
        "tags": ["robotics", "active-acoustic-sensing", "manipulation", "simulation", "modal-synthesis", "aas-gym"],
        "size_categories": [_size_category(n_rows)],
        "configs": [{"config_name": "default", "data_files": [{"split": "train", "path": SHARDS_GLOB}]}],
        "dataset_info": {"features": [_yaml_dtype(f.name, f.type) for f in schema],
                         "splits": [{"name": "train", "num_bytes": n_bytes, "num_examples": n_rows}]},
    }
    try:
        version = metadata.version("aas-gym")
    except metadata.PackageNotFoundError:
        version = "unknown (not installed)"
    if command is None:
        command = f"aas_gym.experiments.generate_dataset(DatasetConfig(**config), {str(folder)!r})"
    lines = ["---", *_yaml(front), "---", "",
             "# aas-gym simulated active acoustic sensing",
             "",
             f"{n_rows} recordings ({len(shards)} Parquet shards) of a simulated robot gripper that vibrates "
             "the object it holds and listens through its other fingertip (FEM modal synthesis of the object, "
             "MuJoCo grasps), for object, material and grasp-position recognition. One row per grasp and "
             "excitation.",
             "",
             "## Columns",
             "",
             "| column | type | unit | meaning |",
             "|---|---|---|---|"]
    for field in schema:
        unit, meaning = COLUMNS.get(field.name, ("", "(undocumented column)"))
        lines.append(f"| `{field.name}` | {field.type} | {unit} | {meaning} |")
    cfg = config.to_dict()
    lines += ["",
              "## How it was made",
              "",
              f"- Command: `{command}`",
              f"- aas-gym {version}, code version `{manifest.get('code_version', 'unrecorded')}` (hash of every "
              "module of `sensors` and `aas_gym`), configuration fingerprint "
              f"`{manifest.get('fingerprint', 'unrecorded')}`",
              f"- Seed {config.seed}: every random draw (placement, grasp jitter, microphone noise) comes from it, "
              "so the same command and code give the same bytes.",
              f"- Recordings of {config.duration_s:g} s at 44.1 kHz, grip force {config.grip_force_n:g} N, "
              f"microphone noise std {config.noise_std:g} (full scale 1).",
              "- Full configuration (also in `.dataset.json`, with each shard's checksum in its Parquet footer):",
              "",
              "```json",
              json.dumps(cfg, indent=1, sort_keys=True),
              "```",
              "",
              "## Loading",
              "",
              "```python",
              "import datasets",
              f"ds = datasets.load_dataset({str(folder)!r}, split='train')",
              "# or, every shard verified against its checksum:",
              "from aas_gym.experiments.generate import load_dataset",
              f"df = load_dataset({str(folder)!r})",
              "```",
              "",
              "## Licence",
              "",
              "Apache License 2.0, as aas-gym, the code that simulated it. Simulated data: no people, "
              "no recordings of real rooms.",
              ""]
    return "\n".join(lines)


def write_card(folder: str | Path, config: DatasetConfig, manifest: dict[str, Any], command: str | None = None) -> Path:
    """Write ``README.md`` into the dataset ``folder`` atomically; returns its path."""
    path = Path(folder) / CARD
    atomic_write_text(path, card_text(Path(folder), config, manifest, command))
    return path
