"""The cold build of a surface object: its collision pieces and its modal model at once.

An everyday object or a user's mesh needs two independent builds before it can be simulated
and heard: CoACD's convex decomposition (:mod:`aas_gym.collision`, single-threaded C++) and
the modal model (P2 assembly and eigen-solve, :mod:`sensors.modal`). Neither holds the GIL in
its long parts (CoACD and MKL PARDISO are called through ctypes, SuperLU and NumPy release it),
so the decomposition runs in a worker thread while the modes are solved in the caller's: on two
free cores the first build waits for the longer of the two instead of their sum (issue 30).
Both results land in their disk caches as when built one after the other.
"""

from __future__ import annotations

import contextlib
import dataclasses
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from aas_gym.collision import CollisionGeometry, collision_geometry
from sensors.fem.mirror import CORE_SLOTS
from sensors.objects.catalog import ObjectSpec, get_object

__all__ = ["BUILD_CORES", "ObjectBuild", "build_object"]

#: Cores the collision and the modal build share (None: no sharing, every thread runs at once).
BUILD_CORES = 2


@dataclasses.dataclass(frozen=True)
class ObjectBuild:
    """What :func:`build_object` made.

    Attributes:
        collision: Convex pieces and mass properties (cached CoACD).
        modal_model: The object's ``sensors.ModalModel``.
        wall_s: Wall-clock time of the whole build [s].
        collision_s: Wall-clock time of the collision build in its thread [s] (a cache hit's load).
        modal_s: Wall-clock time of the modal build [s].
        collision_cpu_s, modal_cpu_s: CPU time of each build's threads [s] (what each costs
            whatever else runs on the machine; the modes' include their symmetry classes' threads).
    """

    collision: CollisionGeometry
    modal_model: object
    wall_s: float
    collision_s: float
    modal_s: float
    collision_cpu_s: float
    modal_cpu_s: float


def build_object(obj: str | ObjectSpec, cache_dir=None, **modal_options) -> ObjectBuild:
    """Collision pieces and modal model of a surface object (everyday shape or user mesh),
    built concurrently (each loads from its disk cache when built before).

    Args:
        obj: Object name or :class:`~sensors.objects.catalog.ObjectSpec` (not a prism: prisms
            collide through primitives and need no decomposition).
        cache_dir: Cache folder of both builds (default: the project cache).
        modal_options: Options of :meth:`ObjectSpec.modal_model` (``max_frequency_hz``,
            ``resolution``, ``progress``, ...).
    """
    spec = get_object(obj)
    solid = spec.solid()
    if solid is None:
        raise ValueError(f"{spec.label} is a prism: it has no surface to decompose (use spec.modal_model())")

    # Two cores: CoACD holds one while it runs; a two-mirror model's four class solves take the
    # other in turn, then both; a one-mirror model's two start at once (sensors.fem.mirror.CORE_SLOTS).
    cores = threading.BoundedSemaphore(BUILD_CORES) if BUILD_CORES else None

    def collide():
        t0, c0 = time.perf_counter(), time.thread_time()
        with cores if cores is not None else contextlib.nullcontext():
            geometry = collision_geometry(solid.surface, solid.material, cache_dir=cache_dir)
        return geometry, time.perf_counter() - t0, time.thread_time() - c0

    start, cpu = time.perf_counter(), time.thread_time()
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="coacd") as pool:
        pending = pool.submit(collide)
        token = CORE_SLOTS.set(cores)
        try:
            model = spec.modal_model(cache_dir=cache_dir, **modal_options)
        finally:
            CORE_SLOTS.reset(token)
        modal_s, modal_cpu_s = time.perf_counter() - start, time.thread_time() - cpu
        if not model.metadata.get("cache_hit"):  # a mirrored model's classes ran in threads of their own
            modal_cpu_s += model.metadata.get("eigensolve", {}).get("cpu_s", 0.0)
        geometry, collision_s, collision_cpu_s = pending.result()
    return ObjectBuild(geometry, model, time.perf_counter() - start, collision_s, modal_s, collision_cpu_s,
                       modal_cpu_s)
