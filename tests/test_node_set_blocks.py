"""UnitLoadStore.node_set_blocks / row_blocks (NODE_SET_BLOCKS): the blocks a contact set's
attachment basis gathers by its nodes alone, kept per node set, give the same bytes as gathered
anew, for contact sets that move within the same elements (randomized episodes) and through
evictions; an entry whose slots took new solves is not served."""

from __future__ import annotations

import numpy as np
import pytest

from sensors import ModalModel
from sensors.modal import static_correction
from sensors.modal.static_correction import ContactFlexibility, UnitLoadStore

from test_unit_load_reuse import BAR, with_tangents
from test_unit_load_rows import attachment_bytes, element_nodes


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


def _episodes(rng, n):
    """Grasp-like contact sets as randomized episodes make them: pads at one of three positions
    along the bar plus 0.5 mm noise, table corners moved by ~1e-8 m (the same elements)."""
    out = []
    for _ in range(n):
        x = rng.choice([-0.03, 0.0, 0.035]) + rng.normal(0, 5e-4)
        z = rng.normal(0, 5e-4)
        pts = [[x, 0.0125, z], [x, -0.0125, z]]
        normals = [[0, 1.0, 0], [0, -1.0, 0]]
        for sx, sy in [(1, 1), (1, -1), (-1, 1), (-1, -1)]:
            pts.append([0.1 * sx - sx * abs(rng.normal(0, 1e-8)), 0.0125 * sy, -0.0125 + abs(rng.normal(0, 1e-8))])
            normals.append([0, 0, -1.0])
        out.append(with_tangents(pts, normals))
    return out


@pytest.mark.parametrize("capacity", [256, 40])
def test_attachment_bases_are_the_same_bytes(bar, monkeypatch, capacity):
    episodes = _episodes(np.random.default_rng(11), 30)
    out, hits = {}, {}
    for keep in (True, False):
        monkeypatch.setattr(static_correction, "NODE_SET_BLOCKS", keep)
        out[keep], flex = attachment_bytes(bar, capacity, episodes)
        hits[keep] = flex.unit_loads._blocks.hits
    assert out[True] == out[False]
    assert hits[False] == 0 and hits[True] >= 20          # the kept blocks were used
    if capacity == 40:                                     # and evictions happened on the way
        assert flex.unit_loads.slots.misses > flex.unit_loads.capacity


class _Perturbed:
    """A factorization whose solves come out 1e-9 larger: a node solved again is then not the
    same solve, so serving blocks gathered before would show."""

    def __init__(self, factor):
        self.factor = factor

    def solve(self, b):
        return np.asarray(self.factor.solve(b)) * (1 + 1e-9)


def test_blocks_of_slots_solved_again_are_not_served(bar):
    flex = ContactFlexibility(bar)
    (pts, dirs), = _episodes(np.random.default_rng(12), 1)
    a = element_nodes(flex, pts[:1])                          # one pad's element nodes
    store = flex.unit_loads = UnitLoadStore(flex, capacity=len(a))
    cols = store.columns(a)
    before = store.node_set_blocks(a, cols)
    assert store.node_set_blocks(a, store.columns(a)) is before                # kept
    others = np.setdiff1d(np.arange(len(bar.nodes_m)), a)[: len(a)]
    store.columns(others)                                      # evicts every node of a
    flex.factor = _Perturbed(flex.factor)
    cols_again = store.columns(a)                              # solved again, into the same slots
    assert np.array_equal(cols_again, cols) and np.array_equal(store.slot_node[cols[::3] // 3], a)
    after = store.node_set_blocks(a, cols_again)
    fresh = (store.relief_gram[cols], store.products(cols, cols), store.rows(a, cols),
             flex.relief[(3 * a[:, None] + np.arange(3)).ravel()], store.KU[cols])
    for got, want, old in zip(after, fresh, before):
        assert got.tobytes() == want.tobytes()
    assert any(g.tobytes() != o.tobytes() for g, o in zip(after, before))     # the stale ones differ


def test_load_patterns_give_the_same_loads(bar, monkeypatch):
    """C, B and the nodes of a contact set from its kept load pattern are np.add.at's bytes,
    signed zeros included (directions along the axes times negative P2 weights give -0.0)."""
    from sensors.fem.assembly import shape_functions
    from sensors.modal.static_correction import located_once

    flex = ContactFlexibility(bar)
    episodes = _episodes(np.random.default_rng(13), 12)
    episodes.append((np.array([[0.0, 0.0125, 0.0]] * 3), np.eye(3)))         # a point on a node: one weight
    out, negative_zeros = {}, 0
    for keep in (True, False):
        monkeypatch.setattr(static_correction, "NODE_SET_BLOCKS", keep)
        got = []
        for pts, dirs in episodes * 2:                         # the second pass finds the patterns kept
            tet, bary = located_once(bar.locator, pts)
            N = shape_functions(bary, bar.element)
            negative_zeros += int(np.signbit(N[:, :, None] * dirs[:, None, :]).sum())
            distinct, C, B, dofs = flex._combination(N, bar.elements[tet], dirs)
            got.append((distinct.tobytes(), C.tobytes(), B.tobytes(), dofs.tobytes()))
        out[keep] = got
    assert out[True] == out[False]
    assert negative_zeros > 0 and flex._patterns.hits >= len(episodes)
