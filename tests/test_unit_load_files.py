"""Kept unit-load solves read back from disk (``sensors.modal.unit_load_files``) are the solve's bytes.

A store that reads a node's file must hold exactly what a store that solved it holds (Y, M Y,
Y^T K U rows, Y^T M relief), or a probe's features would depend on what an earlier process
left in the cache.  The reference is a store with the files off, in a fresh model (its own
factorization); each column is also checked against SciPy's independent sparse LU solve.
Then the fault model: a corrupt file, a file of another node, a full budget and an unwritable
cache folder all fall back to solving, with the same bytes.
"""

from __future__ import annotations

import logging
import os
import stat

import numpy as np
import pytest
import scipy.sparse.linalg

from sensors import ModalModel
from sensors.modal import unit_load_files
from sensors.modal.static_correction import ContactFlexibility, UnitLoadStore

NODES = [[3, 57, 120], [57, 150, 190, 211], [4, 5, 6, 7, 8, 9, 10], [211, 3]]


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(length_m=0.2, width_m=0.025, height_m=0.025, material="aluminium", resolution=0.008,
                          cache=False, max_frequency_hz=12000.0)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(unit_load_files, "ENABLED", True)
    return tmp_path / "cache"


class Counting:
    """A factorization that counts the right-hand sides it solves."""

    def __init__(self, factor):
        self.factor, self.name, self.columns = factor, factor.name, 0
        self._f = getattr(factor, "_f", None)

    def solve(self, b):
        self.columns += np.asarray(b).reshape(len(b), -1).shape[1]
        return self.factor.solve(b)


def run(bar, order=NODES, capacity=None):
    """A fresh model's store after ``columns`` on each node list: every node's entries and the
    right-hand sides solved."""
    flex = ContactFlexibility(bar)
    flex.factor = Counting(flex.factor)
    store = flex.unit_loads = UnitLoadStore(flex, capacity)
    for nodes in order:
        store.columns(np.asarray(nodes))
    assert unit_load_files.flush(60.0)                          # the background writes are done
    out = {}
    for n in sorted({n for nodes in order for n in nodes}):
        c = store.columns(np.array([n]))
        out[n] = tuple(a.tobytes() for a in (store.Y[:, c], store.MY[:, c], store.KU[c], store.relief_gram[c]))
    return out, flex, store


def files_of(cache):
    return sorted((cache / unit_load_files.FOLDER).glob("*/node-*.bin"))


def test_read_back_solves_are_the_solved_bytes(bar, cache, monkeypatch):
    monkeypatch.setattr(unit_load_files, "ENABLED", False)
    reference, _, _ = run(bar)
    monkeypatch.setattr(unit_load_files, "ENABLED", True)
    written, flex_w, _ = run(bar)                               # solves and writes
    n_nodes = len(reference)
    assert len(files_of(cache)) == n_nodes and flex_w.factor.columns > 0
    read, flex_r, store = run(bar)                              # a new process's model: reads
    assert flex_r.factor.columns == 0                           # nothing solved
    assert written == reference and read == reference
    # mixed: some nodes on disk, some new, in one call
    mixed, flex_m, _ = run(bar, NODES + [[3, 200, 57, 201]])
    assert flex_m.factor.columns == 8 and mixed[3] == reference[3]   # 2 new nodes: one block of 8
    monkeypatch.setattr(unit_load_files, "ENABLED", False)
    fresh, _, _ = run(bar, NODES + [[3, 200, 57, 201]])
    assert mixed == fresh
    # and each kept column is the projected solve of its unit loads (SciPy's LU, not PARDISO)
    nodes = np.array(sorted(reference))
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    F = np.zeros((flex_r.n_dof, rows.size))
    F[rows, np.arange(rows.size)] = 1.0
    independent = flex_r.unit_load_projected(scipy.sparse.linalg.spsolve((flex_r.K + flex_r.sigma * flex_r.M).tocsc(), F))
    Y = store.Y[:, store.columns(nodes)]
    assert np.abs(Y - independent).max() < 1e-9 * np.abs(independent).max()


def test_a_setting_that_changes_the_bytes_changes_the_folder(bar, cache, monkeypatch):
    from sensors.modal import static_correction

    run(bar)
    monkeypatch.setattr(static_correction, "SINGLE_ELASTIC_PROJECTION", False)
    _, flex, _ = run(bar)
    assert flex.factor.columns > 0                               # not read from the other setting's files
    assert len({p.parent for p in files_of(cache)}) == 2


def test_corrupt_and_foreign_files_are_solved_again(bar, cache, caplog):
    reference, _, _ = run(bar)
    paths = {p.name: p for p in files_of(cache)}
    damaged = paths["node-57.bin"]
    data = bytearray(damaged.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged.write_bytes(bytes(data))
    paths["node-150.bin"].write_bytes(paths["node-120.bin"].read_bytes())    # another node's entry
    paths["node-190.bin"].write_bytes(b"not a unit-load file")
    with caplog.at_level(logging.WARNING):
        again, flex, _ = run(bar)
    assert again == reference
    assert flex.factor.columns == 16                             # node 57 alone, then 150 and 190: two blocks of 8
    assert "node 150" in caplog.text and caplog.text.count("ignoring corrupt") == 2
    _, flex, _ = run(bar)                                        # rewritten: read again
    assert flex.factor.columns == 0


def test_the_budget_bounds_the_files(bar, cache, monkeypatch, caplog):
    node_mb = ContactFlexibility(bar).n_dof * 3 * 8 / 1e6
    monkeypatch.setattr(unit_load_files, "MAX_MB_PER_MODEL", 5.5 * node_mb)
    with caplog.at_level(logging.INFO):
        reference, _, _ = run(bar)
    assert len(files_of(cache)) == 5
    assert caplog.text.count("limit reached") == 1 and "MAX_MB_PER_MODEL" in caplog.text
    again, flex, _ = run(bar)
    assert again == reference and 0 < flex.factor.columns


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes into read-only folders")
def test_an_unwritable_cache_solves_on(bar, cache):
    cache.mkdir(parents=True)
    cache.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        reference, _, _ = run(bar)
    finally:
        cache.chmod(stat.S_IRWXU)
    assert files_of(cache) == []
    assert run(bar)[0] == reference


def test_a_full_disk_solves_on(bar, cache, monkeypatch, caplog):
    """A write that fails (here every write: ENOSPC) is tried once per model, then the store
    solves on in memory with the same bytes."""
    calls = []

    def full(*args, **kwargs):
        calls.append(1)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(unit_load_files, "atomic_open", full)
    with caplog.at_level(logging.WARNING):
        reference, _, _ = run(bar)
    assert len(calls) == 1 and "No space left" in caplog.text
    monkeypatch.undo()
    monkeypatch.setattr(unit_load_files, "ENABLED", False)
    assert run(bar)[0] == reference


def test_old_model_folders_go_first_beyond_the_total(bar, cache, monkeypatch, caplog):
    """Folders a code or settings change left behind are removed, least recently written first,
    once all folders together hold more than MAX_MB_TOTAL; the model in use keeps its files."""
    root = cache / unit_load_files.FOLDER
    for i, age_s in enumerate((3000, 2000, 1000)):
        d = root / f"old{i}"
        d.mkdir(parents=True)
        (d / "node-1.bin").write_bytes(b"\0" * 400_000)
        os.utime(d, (d.stat().st_atime - age_s,) * 2)
    monkeypatch.setattr(unit_load_files, "MAX_MB_TOTAL", 0.5)     # 1.2 MB of old folders; this model has none yet
    with caplog.at_level(logging.INFO):
        reference, _, _ = run(bar)
    left = sorted(p.name for p in root.iterdir())
    assert "old0" not in left and "old1" not in left and "old2" in left, left   # down to 0.4 MB
    assert caplog.text.count("least recently written") == 2
    assert run(bar)[0] == reference and len([p for p in files_of(cache) if p.parent.name != "old2"]) == 13


def test_an_env_observes_the_same_bytes_with_files_off_written_and_read(cache, monkeypatch):
    """GraspPosition-v0 (a new grasp of the wood bar each episode, so new unit loads): the same
    observations and rewards with the files off, being written, and read back by a process whose
    in-memory caches are empty (``clear_all``)."""
    import hashlib

    import gymnasium as gym

    import aas_gym  # noqa: F401
    from sensors._infra.lru import clear_all

    def episode_bytes():
        clear_all()
        env = gym.make("aas_gym/GraspPosition-v0", disable_env_checker=True)
        obs, _ = env.reset(seed=5)
        env.action_space.seed(5)
        h, heard = hashlib.sha256(), set()
        for _ in range(25):                                       # one-step episodes: a grasp heard per reset
            assert np.abs(obs["acoustic"]).max() > 0
            heard.add(obs["acoustic"].tobytes())
            h.update(b"".join(np.ascontiguousarray(obs[k]).tobytes() for k in sorted(obs)))
            obs, reward, term, trunc, _ = env.step(env.action_space.sample())
            h.update(np.float64(reward).tobytes())
            if term or trunc:
                obs, _ = env.reset()
        env.close()
        assert unit_load_files.flush(60.0)
        return h.hexdigest(), len(heard)

    monkeypatch.setattr(unit_load_files, "ENABLED", False)
    off, distinct = episode_bytes()
    assert distinct > 20                                          # the grasps differ: not vacuous
    monkeypatch.setattr(unit_load_files, "ENABLED", True)
    written = episode_bytes()[0]
    n_files = len(files_of(cache))
    assert n_files > 20
    read = episode_bytes()[0]
    assert written == off and read == off
    assert len(files_of(cache)) == n_files                        # all read back: nothing new solved


_WRITER = """
import sys, numpy as np
from sensors import ModalModel
from sensors.modal.static_correction import ContactFlexibility, UnitLoadStore
bar = ModalModel.bar(length_m=0.2, width_m=0.025, height_m=0.025, material="aluminium", resolution=0.008,
                     cache=False, max_frequency_hz=12000.0)
flex = ContactFlexibility(bar)
store = flex.unit_loads = UnitLoadStore(flex)
print("ready", flush=True)
for start in range(0, 10**6, 3):
    store.columns(np.arange(start, start + 3) % 225)
"""


def test_a_writer_killed_mid_run_leaves_nothing_that_loads(bar, cache, monkeypatch):
    """kill -9 of a process while its writer thread writes: every file left is whole (or ignored),
    the next process reads the same bytes a solve gives, and the killed writer's temporary files
    are removed when the next process writes into the folder."""
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-c", _WRITER], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "AAS_GYM_CACHE": str(cache)})
    try:
        assert proc.stdout.readline().strip() == "ready"
        deadline = time.monotonic() + 60
        while len(files_of(cache)) < 40 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    left = files_of(cache)
    kept = sorted(int(p.stem.split("-")[1]) for p in left)
    assert len(kept) >= 40 and max(kept) < 220                 # the child writes nodes in order, from 0
    dead = left[0].parent / f".node-7.bin.{proc.pid}.abc123.tmp"   # what a write cut short leaves
    dead.write_bytes(b"\0" * 1000)
    order = [kept[:30], [220, 221, 222, 223, 224]]
    read, flex, _ = run(bar, order)
    assert flex.factor.columns == 16 and not dead.exists()      # only the 5 new nodes solved; the temp removed
    monkeypatch.setattr(unit_load_files, "ENABLED", False)
    assert run(bar, order)[0] == read
