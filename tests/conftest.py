"""Test-suite wiring shared by every file."""

import os

import pytest

# Each run ends with every test process's peak memory (tests/peak_memory.py).
pytest_plugins = ["peak_memory", "pytester"]

# Headless rendering unless the caller chose a backend (must precede any mujoco import).
os.environ.setdefault("MUJOCO_GL", "egl")

# gmsh (the everyday objects' reference mesher) fails to initialize if CoACD's library was
# loaded first in the process; loading gmsh first makes both work in one test session.
try:
    import gmsh  # noqa: F401
except ImportError:  # the dev extra is not installed: the reference tests will say so
    pass


@pytest.fixture(scope="session")
def audio_loopback(tmp_path_factory):
    """A PulseAudio null-sink loopback of this test process's own, in a fresh runtime folder:
    two runs (or two xdist workers) never share (or stop) each other's sound server; the
    audio test files of one process share it."""
    from real import loopback

    lb = loopback.start_loopback(runtime_dir=tmp_path_factory.mktemp("pulse"))
    yield lb
    loopback.stop_loopback(lb.runtime_dir)


@pytest.fixture(scope="session")
def run_cache_dir(tmp_path_factory):
    """A model cache folder of this test run, shared by its xdist workers: what several files
    build alike (tests/small_can.py's container, its fill tables) is built once per run (a build
    holds a lock, so another worker waits for it and then loads it) and never carried over from
    an earlier run."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the run's folder, above each worker's own
    path = base / "run-cache"
    path.mkdir(exist_ok=True)
    return path


@pytest.fixture
def no_build(monkeypatch, tmp_path):
    """An empty cache folder (returned), and any container modal build fails the test: the
    inputs must be refused before any work."""
    from sensors.objects.everyday import EverydayObject

    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))

    def refuse(*_, **__):
        raise AssertionError("a modal model was built before the inputs were checked")

    monkeypatch.setattr(EverydayObject, "modal_model", refuse)
    return tmp_path / "cache"


@pytest.fixture(scope="module", autouse=True)
def _fresh_caches_per_file():
    """Each test file starts with the process's in-memory caches empty and their memory given
    back: a worker runs about 40 files, and what earlier files left (modal factorizations of
    40-130 MB each, kept unit-load solves) would otherwise add up to the heaviest file's peak."""
    import ctypes
    import gc

    from sensors._infra.lru import clear_all

    clear_all()
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass
    yield


# The test files that take longest from an empty model cache, longest first (summed durations
# of a cold `pytest -n 2 --dist loadfile --durations` run on the project's 2-core machine; last
# measured 2026-11-27 at a load of about 10, so the ranking is rough: test_fluid_compressible
# 1114 s, test_everyday_objects 700 s (its gmsh/skfem references; not listed before, it ran in
# the middle), test_fill_level_env 697 s, ... test_fluid_analytic 159 s; test_synthesis_stability,
# 65 s, left the list). `python3 tasks.py test` hands whole files to its two workers in collection order
# (`--no-loadscope-reorder`; xdist's default sends the files with most tests first, which left
# these few-test cold builds for last, each on one worker while the other idled). Starting them
# first lets the many short files fill in behind. A stale list costs only balance, never a test.
# test_fill_level_env leads since the compressible reference's symmetric factorization and the
# shared liquid flows: alone from an empty cache, side by side, 216 against 142 CPU s.
LONGEST_FILES = (
    "test_fill_level_env.py",
    "test_fluid_compressible.py",
    "test_everyday_objects.py",
    "test_generate.py",
    "test_fluid_fill_table.py",
    "test_env_info.py",
    "test_canonical_settle.py",
    "test_calibration.py",
    "test_modal_accuracy.py",
    "test_closed_form_features.py",
    "test_collision_simplify.py",
    "test_fluid_coupled.py",
    "test_faults.py",
    "test_direct_solver.py",
    "test_fluid_analytic.py",
)

# The environment of the test workers when the run has several (`-n`), set before they start
# (they inherit it; a value the caller set is kept):
# - one BLAS/OpenMP thread each: the workers already fill the cores; a second BLAS thread per
#   worker then only waits for a core, and OpenBLAS's threads spin while they wait: 30 sparse
#   complex solves of tests/test_partner_loads.py took 41 s with two threads against 7 s with
#   one, beside three busy processes;
# - glibc maps allocations of 128 kB and more on their own, so a worker's freed arrays go back to
#   the system instead of fragmenting its heap: from an empty cache, 2.95 against 5.20 GB peak
#   per worker, 11 min 07 s against 10 min 01 s (2026-11-27, quiet, 1316 tests). Results unchanged.
#   At 128 kB, though, every mid-size numpy temporary was mapped, faulted in page by page and
#   unmapped again (52.7 M minor faults, 292 of 1745 CPU s in the kernel); at 4 MB (numpy asks
#   for huge pages from 4 MB up) with the heap's free top kept up to 64 MB, seven files in one
#   process (env_info, canonical_settle, modal_accuracy, closed_form_features, direct_solver,
#   fluid_coupled, collision_mirror; 266 tests, run beside the 128 kB setting): 1.45 M against
#   6.62 M faults, 17 against 36 s system time, 179 against 199 s, peak 2.76 against 2.51 GB.
WORKER_ENVIRONMENT = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                      "MALLOC_MMAP_THRESHOLD_": "4194304", "MALLOC_TRIM_THRESHOLD_": "67108864"}


def pytest_configure(config):
    if getattr(config.option, "numprocesses", None) and "PYTEST_XDIST_WORKER" not in os.environ:
        for name, value in WORKER_ENVIRONMENT.items():
            os.environ.setdefault(name, value)


def pytest_collection_modifyitems(config, items):
    """Run :data:`LONGEST_FILES` first, in that order; every other file keeps its place."""
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
