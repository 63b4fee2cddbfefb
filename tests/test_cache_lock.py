"""Processes that miss the modal cache together build the model once."""

from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np


def _build(cache_dir):
    from sensors import MATERIALS, ModalModel

    model = ModalModel.bar(0.2, 0.025, 0.025, MATERIALS["wood"], resolution=0.5, max_frequency_hz=8000.0,
                           cache_dir=cache_dir, progress=False)
    return bool(model.metadata.get("cache_hit", False)), model.frequencies_hz


def test_concurrent_builds_solve_once(tmp_path):
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(_build, [str(tmp_path)] * 2))
    hits = sorted(hit for hit, _ in results)
    assert hits == [False, True]  # one process solved, the other waited and loaded its result
    np.testing.assert_array_equal(results[0][1], results[1][1])
    assert len(list(tmp_path.glob("*.npz"))) == 1 and not list(tmp_path.glob("*.tmp"))
