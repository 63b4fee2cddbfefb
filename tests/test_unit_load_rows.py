"""UnitLoadStore.rows (KEEP_NODE_ROWS): the kept solves' rows at nodes from the small block
array equal the rows of the n_dof-long columns, bit for bit, through evictions, slot reuse and
an emptied LRU; attachment bases built with and without it are the same bytes."""

from __future__ import annotations

import numpy as np
import pytest

from sensors import ModalModel
from sensors.modal import static_correction
from sensors.modal.static_correction import ContactFlexibility, UnitLoadStore

from test_unit_load_reuse import BAR, grasp_contacts


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


def element_nodes(flex, pts):
    """The mesh nodes of the elements that hold ``pts``."""
    tet, _ = flex.model.locator.locate(np.asarray(pts, float))
    return np.unique(flex.model.elements[tet])


def test_rows_equal_the_columns_rows_through_evictions(bar, monkeypatch):
    flex = ContactFlexibility(bar)
    store = flex.unit_loads = UnitLoadStore(flex, capacity=20)
    rng = np.random.default_rng(8)
    compared = held_rows = 0
    for step in range(14):
        pts, dirs = grasp_contacts(rng, n_table=2)
        flex.attachment_basis(pts, dirs)                       # fills and evicts slots
        if step == 9:
            store.slots.clear()                                # as clear_all: slots come back elsewhere
        nodes = element_nodes(flex, pts)
        own = nodes[: min(len(nodes), 12)]
        cols = store.columns(own)
        for ask in (own, nodes, nodes[::-1], np.concatenate([own[:3], [0, 1]])):   # held, not held, mixed
            fast = store.rows(ask, cols)
            dofs = (3 * np.asarray(ask)[:, None] + np.arange(3)).ravel()
            assert fast.tobytes() == store.Y[np.ix_(dofs, cols)].tobytes()
            compared += 1
            held_rows += int((store.node_slot[np.asarray(ask)] >= 0).sum())
    assert compared == 56 and held_rows > 100 and store.slots.misses > 20


def test_stale_rows_would_be_caught(bar, monkeypatch):
    """Without the invalidation on a slot's reuse the block array serves a former node's rows:
    the comparison above then fails (this test checks that it would)."""
    flex = ContactFlexibility(bar)
    store = flex.unit_loads = UnitLoadStore(flex, capacity=8)
    rng = np.random.default_rng(9)
    pts, dirs = grasp_contacts(rng, n_table=2)
    nodes = element_nodes(flex, pts)[:8]
    cols = store.columns(nodes)
    store.rows(nodes, cols)                                    # rows of these nodes now kept
    store.node_rows[:] = np.nan                                # what stale blocks would serve
    assert not np.array_equal(store.rows(nodes, cols), store.Y[np.ix_((3 * nodes[:, None] + np.arange(3)).ravel(), cols)])


@pytest.mark.parametrize("capacity", [256, 24])
def test_attachment_bases_are_the_same_bytes(bar, monkeypatch, capacity):
    rng = np.random.default_rng(10)
    grasps = [grasp_contacts(rng) for _ in range(8)]
    out = {}
    for keep in (True, False):
        monkeypatch.setattr(static_correction, "KEEP_NODE_ROWS", keep)
        out[keep], _ = attachment_bytes(bar, capacity, grasps)
    assert out[True] == out[False]


def attachment_bytes(bar, capacity, contact_sets):
    """``(bytes, flex)``: the attachment basis of each contact set (stiffness, coupling, rows
    at its elements' nodes) as bytes, from a new store of ``capacity`` nodes, in order."""
    flex = ContactFlexibility(bar)
    flex.unit_loads = UnitLoadStore(flex, capacity=capacity)
    got = []
    for pts, dirs in contact_sets:
        basis = flex.attachment_basis(pts, dirs)
        nodes = element_nodes(flex, pts)      # what the Ritz rows ask for
        got.append((basis.stiffness.tobytes(), basis.coupling.tobytes(), basis.nodal(nodes).tobytes()))
    return got, flex
