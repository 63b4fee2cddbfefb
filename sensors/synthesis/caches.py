"""What the recording chain reuses across spans and calls: discretised systems and drive runs.

Discretising the modal system of a contact set (damping matrix, complex modes) dominates a
short recording, and the same grasp is usually heard again: in the next physics step of a
stream, or with another excitation in a batch recording.  :class:`SystemCache` keeps the
systems of recent contact sets, matched within a ``ContactTolerance``.  A
:class:`SynthesisCache` adds the fingertip drive's runs from rest (they depend on the
fingertip model, the excitation and the length only); whoever owns one (a
``SimAcousticSensor``, a stream) passes it to every recording it makes.  Both sit on the one
bounded LRU, ``sensors._infra.lru.LRU``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Hashable

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from .grasp_state import ContactTolerance, GraspState

__all__ = ["IdentityKey", "SynthesisCache", "SystemCache"]


@dataclass(frozen=True, eq=False)
class _Entry:
    key: Hashable
    group: tuple                # (model, object key, heard, settings): what must be equal
    table: np.ndarray           # the contact set it was built from (GraspState.contact_table)
    system: object


class SystemCache:
    """Discretised systems of recent contact sets, least recently used dropped first.

    A grasp's system is reused when the model (the same object), its ``object_key``, whether
    it is heard and the settings (sample rate, method, output) are the same and its contact
    table matches a cached one within ``tolerance``; the cached system was built from the
    FIRST contact set seen (see ``ContactTolerance`` for what that costs in accuracy).
    ``size``, ``hits`` and ``misses`` are readable; ``max_size`` bounds it (default
    ``CACHE_SIZES["stream.systems"]``).
    """

    def __init__(self, tolerance: ContactTolerance | None = None, max_size: int | None = None):
        if max_size is None:
            max_size = CACHE_SIZES["stream.systems"]
        if int(max_size) < 1:
            raise ValueError("max_size must be >= 1")
        self.tolerance = ContactTolerance() if tolerance is None else tolerance
        self._lru: LRU[_Entry] = LRU(int(max_size))

    @property
    def max_size(self) -> int:
        return self._lru.max_size

    @property
    def size(self) -> int:
        return len(self._lru)

    @property
    def hits(self) -> int:
        return self._lru.hits

    @property
    def misses(self) -> int:
        return self._lru.misses

    def __repr__(self) -> str:
        return f"SystemCache({self._lru!r}, tolerance={self.tolerance})"

    def clear(self) -> None:
        self._lru.clear()

    def get_or_build(self, grasp: GraspState, heard: bool, settings: tuple, build: Callable[[], object]):
        """The system of ``grasp`` (heard: closed grasp with drive and microphone, or a
        ring-down only) under ``settings``: a cached one within the tolerance, or ``build()``."""
        group = (IdentityKey(grasp.model), grasp.object_key, bool(heard), settings)
        table = grasp.contact_table()
        key = (group, table.shape, table.tobytes())
        if key not in self._lru:
            for entry in reversed(self._lru.values()):      # most recently used first
                if entry.group == group and self.tolerance.tables_match(table, entry.table):
                    key = entry.key
                    break
        return self._lru.get_or_build(key, lambda: _Entry(key, group, table, build())).system


class SynthesisCache:
    """What recordings may reuse across calls, owned by whoever passes it (a
    ``SimAcousticSensor`` owns one): the per-grasp modal systems (:attr:`systems`, exact
    contact sets unless given another ``SystemCache``) and the fingertip drive's runs from
    rest (:attr:`forces`; they depend on the fingertip model, the excitation and the length
    only).  ``maxsize`` bounds each (default ``CACHE_SIZES["synthesis.systems"]`` and
    ``["synthesis.forces"]``); ``len``, ``hits`` and ``misses`` say how well it works.
    """

    def __init__(self, maxsize: int | None = None, *, systems: SystemCache | None = None) -> None:
        if maxsize is not None and int(maxsize) < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize!r}")
        self.maxsize = None if maxsize is None else int(maxsize)
        self.systems = systems if systems is not None else SystemCache(
            ContactTolerance.exact(), CACHE_SIZES["synthesis.systems"] if maxsize is None else int(maxsize))
        self.forces: LRU = LRU(CACHE_SIZES["synthesis.forces"] if maxsize is None else int(maxsize))
        # closed-form features (sensors.synthesis.feature_recording): the drive's steady period and
        # transient per fingertip model, and per model an LRU of its grasps' noiseless window spectra
        self.drive_spectra: LRU = LRU(CACHE_SIZES["synthesis.drive_spectra"] if maxsize is None else int(maxsize))
        self.window_spectra: LRU = LRU(CACHE_SIZES["synthesis.window_spectra"] if maxsize is None else int(maxsize))

    def __len__(self) -> int:
        return self.systems.size + len(self.forces)

    @property
    def hits(self) -> int:
        return self.systems.hits + self.forces.hits

    @property
    def misses(self) -> int:
        return self.systems.misses + self.forces.misses

    def __repr__(self) -> str:
        return (f"SynthesisCache({self.systems.size} systems, {len(self.forces)} forces, "
                f"hits={self.hits}, misses={self.misses})")

    def clear(self) -> None:
        self.systems.clear()
        self.forces.clear()
        self.drive_spectra.clear()
        self.window_spectra.clear()
