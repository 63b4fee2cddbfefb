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
