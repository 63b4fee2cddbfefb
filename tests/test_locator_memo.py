"""Point queries kept per point (``sensors.mesh.locator.TetLocator``): a grasp asks for the same
contact points several times; the kept rows equal a fresh computation of the points alone, bit
for bit, in any batch, and a copy of a locator starts with memos of its own."""

import copy

import numpy as np

from sensors import ModalModel
from sensors._infra.lru import clear_all
from sensors.mesh.locator import TetLocator


def test_kept_rows_equal_fresh_queries_in_any_batch():
    model = ModalModel.bar(0.1, 0.02, 0.01, "aluminium", element="p1", element_size_m=0.005, cache=False,
                           progress=False, max_frequency_hz=5000.0)
    rng = np.random.default_rng(3)
    # inside, on and outside the surface
    points = rng.uniform(-1.08, 1.08, (120, 3)) * np.array([0.05, 0.01, 0.005])
    kept = model.locator
    for _ in range(25):
        batch = points[rng.choice(len(points), size=int(rng.integers(1, 40)))]
        fresh = TetLocator(model.nodes_m, model.elements)      # nothing kept: computed now
        tet, bary = kept.locate(batch)
        closest, face, dist = kept.closest_surface(batch)
        want_tet, want_bary = fresh.locate(batch)
        want = fresh.closest_surface(batch)
        assert np.array_equal(tet, want_tet) and np.array_equal(bary, want_bary)
        for got, w in zip((closest, face, dist), want):
            assert np.array_equal(got, w)
        assert tet.dtype == want_tet.dtype and face.dtype == want[1].dtype
    assert kept._located.hits > 0 and kept._closest.hits > 0
    twin = copy.deepcopy(kept)
    assert len(twin._located) == 0 and twin._located is not kept._located
    clear_all()
    assert len(kept._located) == len(kept._closest) == 0
