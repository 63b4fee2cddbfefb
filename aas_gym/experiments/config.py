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
from typing import Any, ClassVar

import numpy as np

from aas_gym.object_names import DEFAULT_OBJECT_NAMES

EXCITATIONS = ("impulse", "linear", "exponential")
SCENES = ("single", "multi", "position")
#: Default of ``DatasetConfig.max_tasks``: the most grasps one dataset may hold (the paper's
#: is 665). A limit on the run's cost, not part of the configuration.
MAX_TASKS = 100_000
#: Simulation time of one grasp with its three recordings on one core [s], for the estimate
#: in the refusal (docs/benchmarks/generation.md: 40.7 grasps/s in one process, warm cache).
SECONDS_PER_GRASP = 0.025


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
        contact_model: how contacts act on the objects' modes: ``"spring_damper"`` (default,
            issue 26) or ``"damping"`` (the paper's model); in the manifest and fingerprint.
        store_waveforms: also store raw waveforms (about 176 kB per row).
        seed: root of every random stream.
        shard_size: tasks per output file.
        robot: who grasps (``aas_gym.robots``): ``"floating_hand"`` (the paper's figures) or
            ``"panda"`` (the Franka Panda arm with the same hand); recorded in the manifest.
        drive: how the excitation reaches the fingertip: ``"bandlimited"`` (the signal a
            sound card plays) or ``"foh"`` (piecewise linear between samples); recorded in
            the manifest's config. A manifest without it was made with ``"foh"``.
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
    contact_model: str = "spring_damper"
    store_waveforms: bool = False
    seed: int = 0
    shard_size: int = 16
    robot: str = "floating_hand"
    drive: str = "bandlimited"

    #: The most grasps a configuration may expand to (:data:`MAX_TASKS`); raise it on the class
    #: (``DatasetConfig.max_tasks = ...``) for a larger dataset. Not a field: not fingerprinted.
    max_tasks: ClassVar[int] = MAX_TASKS

    def __post_init__(self) -> None:
        # Every value checked here, before anything is written: bools are not counts, strings
        # are not numbers, and a negative seed would fail only inside a worker.
        from sensors.task import MAX_SAMPLES, check_flag, check_grip_force, check_integer, check_number

        for name, known in (("objects", None), ("excitations", EXCITATIONS), ("scenes", SCENES)):
            object.__setattr__(self, name, _names(name, getattr(self, name), known))
        for name in ("single_grasps", "multi_grasps", "positions", "position_repeats"):
            object.__setattr__(self, name, check_integer(name, getattr(self, name), 0))
        object.__setattr__(self, "shard_size", check_integer("shard_size", self.shard_size, 1))
        object.__setattr__(self, "seed", check_integer("seed", self.seed, 0))
        object.__setattr__(self, "position_step_m", check_number("position_step_m", self.position_step_m, 0.0,
                                                                 low_open=True, unit="m"))
        object.__setattr__(self, "duration_s", check_number("duration_s", self.duration_s, 0.0, low_open=True,
                                                            unit="s"))
        object.__setattr__(self, "grip_force_n", check_grip_force(self.grip_force_n))
        object.__setattr__(self, "grasp_jitter_m", check_number("grasp_jitter_m", self.grasp_jitter_m, 0.0, unit="m"))
        object.__setattr__(self, "noise_std", check_number("noise_std", self.noise_std, 0.0))
        object.__setattr__(self, "store_waveforms", check_flag("store_waveforms", self.store_waveforms))
        from aas_gym.robots import check_robot

        check_robot(self.robot)
        from sensors.synthesis.modal_system import CONTACT_MODELS

        if self.contact_model not in CONTACT_MODELS:
            raise ValueError(f"contact_model must be one of {CONTACT_MODELS}, got {self.contact_model!r}")
        if self.drive not in ("bandlimited", "foh"):
            raise ValueError(f"drive must be 'bandlimited' or 'foh', got {self.drive!r}")
        samples = self.duration_s * 44_100
        if samples > MAX_SAMPLES:
            raise ValueError(f"duration_s={self.duration_s:g} s would record {samples:,.0f} samples per recording "
                             f"(limit {MAX_SAMPLES:,} = {MAX_SAMPLES / 44_100:g} s at 44.1 kHz): shorten it")
        n = self.n_tasks
        if n > self.max_tasks:
            rows = n * len(self.excitations)
            disk_gb = rows * (140 * 4 + (samples * 4 if self.store_waveforms else 0)) / 1e9
            raise ValueError(f"this configuration expands to {n:,} grasps ({rows:,} recordings, about "
                             f"{n * SECONDS_PER_GRASP / 3600:,.1f} core-hours and {disk_gb:,.1f} GB; limit {self.max_tasks:,}"
                             " grasps): use fewer objects, grasps, positions or repeats, or raise the limit with "
                             "DatasetConfig.max_tasks = ...")
        from sensors.objects import get_object  # imports the sensor stack: `aas --help` does not pay

        for name in self.objects:
            get_object(name)  # a misspelt object fails here, before anything is written

    @property
    def n_tasks(self) -> int:
        """How many grasps :meth:`tasks` yields (computed without building them)."""
        per_object = ((self.single_grasps if "single" in self.scenes else 0)
                      + (self.multi_grasps if "multi" in self.scenes else 0)
                      + (self.positions * self.position_repeats if "position" in self.scenes else 0))
        return len(self.objects) * per_object

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


def _names(field: str, value: Any, known: tuple[str, ...] | None) -> tuple[str, ...]:
    """A tuple of distinct, non-empty names from a sequence (a bare string is refused: its
    letters would be read as names)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise TypeError(f"{field} must be a list or tuple of names, got {value!r}")
    names = tuple(value)
    bad = [v for v in names if not isinstance(v, str) or not v.strip()]
    if bad or not names:
        raise ValueError(f"{field} must name at least one, each a non-empty string, got {list(names)!r}")
    if known is not None:
        unknown = sorted(set(names) - set(known))
        if unknown:
            raise ValueError(f"unknown {field} {unknown}; known: {known}")
    twice = sorted({v for v in names if names.count(v) > 1})
    if twice:
        raise ValueError(f"{field} names {twice} more than once")
    return names


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
    """Hash of every module of ``sensors`` and ``aas_gym`` and of the MJCF assets (the robots,
    objects and scenes): the code a dataset's bytes come from.

    Part of a dataset's fingerprint, so a dataset begun by other code (a changed mesh, damping,
    scene or robot model) is never finished by this one: its shards would mix two physics and
    nothing would tell them apart.
    """
    import sensors
    from aas_gym.assets import ASSETS_DIR

    return source_hash(Path(sensors.__file__).parent, Path(__file__).resolve().parents[1], ASSETS_DIR)


def source_hash(*packages: Path) -> str:
    """Hash of the names and bytes of every ``.py`` and ``.xml`` file under the given folders."""
    h = hashlib.sha256()
    for package in packages:
        for path in sorted([*package.rglob("*.py"), *package.rglob("*.xml")]):
            h.update(f"{package.name}/{path.relative_to(package).as_posix()}".encode() + b"\0")
            h.update(path.read_bytes())
    return h.hexdigest()[:16]
