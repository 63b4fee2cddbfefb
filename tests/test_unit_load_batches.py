"""A node's kept unit-load solve is the same bytes whichever batch it was solved in.

``UnitLoadStore.columns`` solves the missing nodes of a contact set in one call, so how many
nodes a call solves depends on what the store already held.  MKL's PARDISO takes another
path for 3 right-hand sides (one node) than for 4 or more, and BLAS another for a projection
of 1-2 nodes than of 3 or more: both round differently (a kept solve 1.5e-12 apart, measured
on the paper's aluminium tube).  A probe's features would then depend on the probes before it, and a
dataset shard on what ran before in its process.  The store pads every call to a width where
each column's result is that column's alone (``static_correction.MIN_SOLVE_COLUMNS``, ``MIN_PROJECTED_COLUMNS``) and solves
whole blocks of right-hand sides (``SOLVE_COLUMN_BLOCK``: on AVX2 machines PARDISO rounds a last,
partial block of 4 otherwise).

Tolerances: bit for bit between batches; each column within 1e-9 of SciPy's independent sparse
LU solve, projected (as ``tests/test_unit_load_projection.py``).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg

from sensors import ModalModel
from sensors.modal.static_correction import ContactFlexibility


@pytest.fixture(autouse=True)
def _solve_every_node(monkeypatch):
    """Solved, never read from disk (sensors.modal.unit_load_files): the batches are the point."""
    from sensors.modal import unit_load_files

    monkeypatch.setattr(unit_load_files, "ENABLED", False)


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(length_m=0.2, width_m=0.025, height_m=0.025, material="aluminium", resolution=0.008,
                          cache=False, max_frequency_hz=12000.0)


def kept(flex, order):
    """Each node's store entries (Y, M Y, Y^T K U rows) after ``columns`` calls on the node
    lists in ``order``, in a fresh store."""
    store = flex.unit_loads = type(flex.unit_loads)(flex)
    for nodes in order:
        store.columns(np.asarray(nodes))
    out = {}
    for n in sorted({n for nodes in order for n in nodes}):
        c = store.columns(np.array([n]))           # kept: no solve
        out[n] = (store.Y[:, c].copy(), store.MY[:, c].copy(), store.KU[c].copy(), store.relief_gram[c].copy())
    return out


def test_a_nodes_solve_does_not_depend_on_its_batch(bar):
    flex = ContactFlexibility(bar)
    nodes = [3, 57, 120, 150, 190, 211]
    alone = kept(flex, [[n] for n in nodes])                       # one node per call
    pairs = kept(flex, [nodes[:2], nodes[2:4], nodes[4:]])         # two per call
    together = kept(flex, [nodes])                                 # all in one call
    for n in nodes:
        for other in (pairs, together):
            assert all(np.array_equal(a, b) for a, b in zip(alone[n], other[n])), n
    # and each is the projected solve of its unit loads (SciPy's LU, independent of PARDISO)
    rows = (3 * np.asarray(nodes)[:, None] + np.arange(3)).ravel()
    F = np.zeros((flex.n_dof, rows.size))
    F[rows, np.arange(rows.size)] = 1.0
    raw = scipy.sparse.linalg.spsolve((flex.K + flex.sigma * flex.M).tocsc(), F)
    independent = flex.unit_load_projected(raw)
    Y = np.hstack([together[n][0] for n in nodes])
    assert np.abs(Y - independent).max() < 1e-9 * np.abs(independent).max()
