"""The one bounded in-memory LRU of the project, and every in-memory cache's size in one place.

Each in-memory cache (built systems, steady states, filled containers, scenes, modal models) is
an :class:`LRU` created with ``LRU(CACHE_SIZES["name"])``, so a user who needs more or less
memory finds every bound here and can change them at run time before the caches are built.
"""

from __future__ import annotations

import weakref

from collections import OrderedDict
from typing import Callable, Generic, Hashable, TypeVar

__all__ = ["CACHE_SIZES", "IdentityKey", "LRU", "clear_all"]

V = TypeVar("V")

#: Entries each in-memory cache keeps, by name. Sizes bound memory: a modal system of 200 modes
#: is about 1 MB, a filled container's wet model tens of MB, a MuJoCo scene a few MB.
CACHE_SIZES: dict[str, int] = {
    "synthesis.systems": 8,          # grasp systems of a batch recording (SynthesisCache)
    "synthesis.forces": 8,           # fingertip drive forces of a batch recording
    "synthesis.drive_spectra": 8,    # fingertip drive steady period + transient (closed-form features)
    "synthesis.window_spectra": 8,   # models whose grasps' feature-window spectra are kept (closed form)
    "synthesis.grasp_spectra": 64,   # ... and per model, its grasps' spectra (4.5 kB each)
    "synthesis.exciter_periods": 8,  # exciter force period, its spectrum and blocked sums per excitation: 0.7 MB each
    "synthesis.feature_bins": 8,     # feature frequencies as DFT bins per (rate, excitation period)
    "synthesis.prefilter_taps": 4,   # one-shot band-limited prefilters (passes, length): a few floats each
    "stream.systems": 16,            # streamed contact systems (SystemCache)
    "stream.drive_systems": 4,       # fingertip drive systems per fingertip model
    "stream.drive_periods": 8,       # the drive's (prefiltered) exciter period per excitation: 176 kB each
    "stream.steady_states": 8,       # periodic steady states per (system, drive)
    "stream.transfers": 32,          # state transfers T (r x r) between the modes of two contact sets
    "passive.load_projections": 4,   # one contact read's loads on the modes of the latest contact sets
    "modal.flexibility": 8,          # K, M and factorization of K + sigma M per model (static correction; 8: the
                                     # seven paper objects ObjectRecognition-v0 cycles, 40-130 MB each)
    "modal.unit_loads": 256,         # per model: nodes' projected unit-load solves and M times them (48 n_dof bytes
                                     # each: 0.52 MB on a 10,935-dof bar; 256 hold every node random grasps touch;
                                     # plus their pairwise M-products, 4.7 MB at 256)
    "modal.node_set_blocks": 96,     # per model: the unit-load blocks a node set's attachment basis and Ritz rows read
                                     # (two entries, ~100 kB at 20 nodes and 100 modes; GraspPosition-v0 uses 28 sets)
    "modal.attachment_bases": 16,    # per model: attachment vectors of recent contact sets (the same points again)
    "modal.spring_modes": 32,        # contact-coupled modes per (model, contact springs)
    "modal.coupled_grasps": 16,      # modes of a grasped object with the objects it touches, per contact set
    "modal.node_trees": 8,           # k-d trees of mesh nodes (coupled_basis.SNAP_TO_NODES)
    "fluid.fills": 16,               # wet models per (fill, tilt, liquid) of one container
    "fluid.containers": 8,           # containers (dry model + static correction) per object
    "fluid.liquid_flows": 1,         # potential flow of the latest exact fill's liquid mesh (its factorization and
                                     # wall load: 2 MB for the glass, 270 MB for a full 6 cm cup at 32 elements around),
                                     # shared by the liquids and both liquid models of that fill
    "mesh.point_locations": 64,      # per mesh: located point batches (containing tet, barycentrics; surface)
    "mesh.surface_points": 1024,     # per mesh: closest surface point, face, distance of single points (56 B each)
    "fluid.layer_nodes": 4,          # P2 nodes per layer of the liquid's disc, by elements around
    "fluid.fill_tables": 8,          # fill tables of one container, per liquid (a few MB each)
    "objects.solids": 64,            # surfaces and meshers of the catalog's surface objects
    "objects.rest_heights": 64,      # a solid's height resting on the table (aas_gym.scenario)
    "sim.models": 32,                # modal models shared by the scenes of one process
    "sim.material_views": 16,
    "sim.touching_groups": 16,       # recent coupled groups per (grasped, touching objects) of a sensor
    "sim.grasp_sets": 64,            # antipodal grasps of surface objects the hand can take
    "sim.body_extents": 64,          # a body's colliding-geom half extents, per body and geom arrays' bytes (24 B each)
    "sim.rest_rotations": 256,       # an object's rest rotation per (up, main axis) (72 B each)
    "env.scenes": 8,                 # compiled MuJoCo scenes per env
    "env.containers": 8,             # FillLevel-v0: its targets' fluid containers (sensors.fluid.container)
    "env.rest_states": 1024,         # FillLevel-v0: canonical rest states per container, liquid, grid fill
    "env.physics_runs": 128,         # settled placements and grasps per scene (~0.5 MB each)
    "dataset.scenes": 16,            # compiled MuJoCo scenes of one dataset worker
    "signals.noise_folders": 4,      # folders of background-noise recordings (corruption)
}


_INSTANCES: "weakref.WeakSet[LRU]" = weakref.WeakSet()


def clear_all() -> None:
    """Empty every LRU of the process. Results that reuse what an earlier call left (kept
    unit-load solves, coupled groups within a tolerance) then depend only on the calls since:
    a dataset shard starts from here, so its bytes do not depend on what its worker ran before."""
    for cache in list(_INSTANCES):
        cache.clear()


class IdentityKey:
    """Hashes an object by identity while holding it (so its id cannot be reused while the
    key lives): models are keys by identity, not by their (large) contents."""

    __slots__ = ("obj",)

    def __init__(self, obj) -> None:
        self.obj = obj

    def __hash__(self) -> int:
        return id(self.obj)

    def __eq__(self, other) -> bool:
        return isinstance(other, IdentityKey) and other.obj is self.obj


class LRU(Generic[V]):
    """A dict bounded to ``max_size`` entries that drops the least recently used one.

    ``get_or_build(key, build)`` returns the cached value or builds, stores and returns it;
    ``hits`` and ``misses`` count lookups. Not thread-safe (each env or stream owns its own).
    """

    def __init__(self, max_size: int) -> None:
        if isinstance(max_size, bool) or not isinstance(max_size, int) or max_size < 1:
            raise ValueError(f"an LRU cache needs a whole max_size >= 1, got {max_size!r}")
        self.max_size = max_size
        _INSTANCES.add(self)
        self.hits = 0
        self.misses = 0
        self._entries: OrderedDict[Hashable, V] = OrderedDict()

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def __repr__(self) -> str:
        return f"LRU({len(self)}/{self.max_size}, hits={self.hits}, misses={self.misses})"

    def get(self, key: Hashable, default: V | None = None) -> V | None:
        """The value under ``key`` (now the most recent), or ``default``; counts a hit or miss."""
        if key in self._entries:
            self._entries.move_to_end(key)
            self.hits += 1
            return self._entries[key]
        self.misses += 1
        return default

    def put(self, key: Hashable, value: V) -> V:
        """Store ``value`` as the most recent entry, dropping the oldest beyond ``max_size``."""
        self._entries[key] = value
        self._entries.move_to_end(key)
        while len(self._entries) > self.max_size:
            self._entries.popitem(last=False)
        return value

    def get_or_build(self, key: Hashable, build: Callable[[], V]) -> V:
        """The cached value, or ``build()`` stored under ``key``."""
        if key in self._entries:
            self._entries.move_to_end(key)
            self.hits += 1
            return self._entries[key]
        self.misses += 1
        return self.put(key, build())

    def oldest(self):
        """``(key, value)`` of the least recently used entry (the one the next ``put`` of a new
        key evicts when full), without making it recent; None when empty."""
        return next(iter(self._entries.items()), None)

    def values(self):
        return self._entries.values()

    def clear(self) -> None:
        self._entries.clear()
