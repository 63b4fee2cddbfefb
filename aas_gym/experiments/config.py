"""What a dataset holds: the paper's protocols expanded into deterministic work units.

A work unit (``Task``) is one grasp: a scene, a target object, where and how it is grasped.
Every excitation is recorded during that one grasp, so a task yields one row per
excitation. Tasks are ordered and grouped into fixed shards; each task's random stream is
derived from the dataset seed and the task's id alone, so the output does not depend on
which worker ran which shard, nor on the order they finished in.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aas_gym.object_names import DEFAULT_OBJECT_NAMES

EXCITATIONS = ("impulse", "linear", "exponential")
SCENES = ("single", "multi", "position")


@dataclass(frozen=True)
class DatasetConfig:
    """The paper's data-collection protocol, every number overridable.

    Attributes:
        objects: object names (see ``aas_gym.object_names.DEFAULT_OBJECT_NAMES``).
        excitations: excitation names recorded at every grasp.
        scenes: which parts to generate: ``single`` (recognition, one object on the table),
            ``multi`` (recognition with other objects touching the target), ``position``
            (grasp-position sweep).
        single_grasps: grasps per object in single-object scenes (paper: 20).
        multi_grasps: grasps per object in multi-object scenes (paper: 10).
        positions: grasp positions along the main axis (paper: 13).
        position_step_m: spacing of grasp positions from the centre (paper: 5 mm).
        position_repeats: recordings per position (paper: 5).
        duration_s: recording length used for features (paper: first 1 s of 5 s).
        grip_force_n: grip force (paper: 40 N).
        grasp_jitter_m: half-range of the uniform error of each grasp along the main axis.
        noise_std: microphone noise standard deviation (full scale 1; 1e-5 is -100 dBFS,
            a good sound card's floor).
        store_waveforms: also store raw waveforms (about 176 kB per row).
        seed: root of every random stream.
        shard_size: tasks per output file.
    """

    objects: tuple[str, ...] = DEFAULT_OBJECT_NAMES
    excitations: tuple[str, ...] = EXCITATIONS
    scenes: tuple[str, ...] = SCENES
    single_grasps: int = 20
    multi_grasps: int = 10
    positions: int = 13
    position_step_m: float = 0.005
    position_repeats: int = 5
    duration_s: float = 1.0
    grip_force_n: float = 40.0
    grasp_jitter_m: float = 0.0005
    noise_std: float = 1e-5
    store_waveforms: bool = False
    seed: int = 0
    shard_size: int = 16

    def __post_init__(self) -> None:
        for name in ("objects", "excitations", "scenes"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        unknown = set(self.excitations) - set(EXCITATIONS)
        if unknown:
            raise ValueError(f"unknown excitations {sorted(unknown)}; known: {EXCITATIONS}")
        unknown = set(self.scenes) - set(SCENES)
        if unknown:
            raise ValueError(f"unknown scenes {sorted(unknown)}; known: {SCENES}")
        if not self.objects:
            raise ValueError("objects is empty")
        from sensors.objects import get_object  # imports the sensor stack: `aas --help` does not pay

        for name in self.objects:
            get_object(name)  # a misspelt object fails here, before anything is written
        for name in ("single_grasps", "multi_grasps", "positions", "position_repeats", "shard_size"):
            value = getattr(self, name)
            if int(value) != value or value < (1 if name == "shard_size" else 0):
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
        if not self.duration_s > 0 or not self.grip_force_n > 0 or not self.position_step_m > 0:
            raise ValueError("duration_s, grip_force_n and position_step_m must be positive")
        if not self.noise_std >= 0:
            raise ValueError(f"noise_std must be >= 0, got {self.noise_std!r}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> DatasetConfig:
        return cls(**data)

    def fingerprint(self) -> str:
        """Hash of everything that determines the output bytes: this configuration and the
        simulator's source (:func:`code_version`)."""
        text = json.dumps({"config": self.to_dict(), "code": code_version()}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def tasks(self) -> list[Task]:
        """All work units, in a fixed order."""
        out: list[Task] = []
        for obj in self.objects:
            if "single" in self.scenes:
                out += [Task(f"single/{obj}/g{g:03d}", "single", obj, grasp_index=g) for g in range(self.single_grasps)]
            if "multi" in self.scenes:
                out += [Task(f"multi/{obj}/g{g:03d}", "multi", obj, grasp_index=g) for g in range(self.multi_grasps)]
            if "position" in self.scenes:
                for p in range(self.positions):
                    out += [
                        Task(f"position/{obj}/p{p:02d}/r{r}", "position", obj, grasp_index=r,
                             position_m=round(p * self.position_step_m, 9))
                        for r in range(self.position_repeats)
                    ]
        return out

    def shards(self) -> list[list[Task]]:
        """Tasks grouped into shards of ``shard_size``."""
        tasks = self.tasks()
        return [tasks[i:i + self.shard_size] for i in range(0, len(tasks), self.shard_size)]


@dataclass(frozen=True)
class Task:
    """One grasp to simulate; ``position_m`` is the grasp position along the main axis
    from the object's centre (``None``: sampled)."""

    task_id: str
    scene: str
    object_name: str
    grasp_index: int = 0
    position_m: float | None = None

    def rng(self, dataset_seed: int) -> np.random.Generator:
        """The task's own random stream: a function of the dataset seed and the task id only."""
        key = int.from_bytes(hashlib.sha256(self.task_id.encode()).digest()[:8], "little")
        return np.random.default_rng(np.random.SeedSequence([dataset_seed, key]))


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """Hash of every module of ``sensors`` and ``aas_gym``: the code a dataset's bytes come from.

    Part of a dataset's fingerprint, so a dataset begun by other code (a changed mesh, damping
    or scene) is never finished by this one: its shards would mix two physics and nothing would
    tell them apart.
    """
    import sensors

    return source_hash(Path(sensors.__file__).parent, Path(__file__).resolve().parents[1])


def source_hash(*packages: Path) -> str:
    """Hash of the names and bytes of every ``.py`` file under the given package folders."""
    h = hashlib.sha256()
    for package in packages:
        for path in sorted(package.rglob("*.py")):
            h.update(f"{package.name}/{path.relative_to(package).as_posix()}".encode() + b"\0")
            h.update(path.read_bytes())
    return h.hexdigest()[:16]
