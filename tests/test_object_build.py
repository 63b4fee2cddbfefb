"""build_object: CoACD in a worker thread beside the modal build gives what the two builds give
one after the other, and leaves both in their caches."""

import numpy as np
import pytest

from aas_gym.collision import collision_geometry
from aas_gym.object_build import build_object
from sensors.objects import get_object

BAND_HZ = 10000.0


@pytest.fixture(scope="module")
def concurrent(tmp_path_factory):
    cache = tmp_path_factory.mktemp("together")
    return cache, build_object("l_bracket", cache_dir=cache, max_frequency_hz=BAND_HZ, progress=False)


def test_concurrent_build_equals_the_builds_one_after_the_other(concurrent, tmp_path):
    _, built = concurrent
    spec = get_object("l_bracket")
    solid = spec.solid()
    alone = collision_geometry(solid.surface, solid.material, cache_dir=tmp_path)
    model = spec.modal_model(max_frequency_hz=BAND_HZ, progress=False, cache_dir=tmp_path)
    assert len(built.collision.pieces) == len(alone.pieces)
    assert all(np.array_equal(a, b) for a, b in zip(built.collision.pieces, alone.pieces))
    assert built.collision.mass_kg == alone.mass_kg
    np.testing.assert_array_equal(built.modal_model.frequencies_hz, model.frequencies_hz)
    assert built.wall_s >= max(built.collision_s, built.modal_s) > 0


def test_both_results_are_cached(concurrent):
    cache, built = concurrent
    again = build_object("l_bracket", cache_dir=cache, max_frequency_hz=BAND_HZ, progress=False)
    assert again.modal_model.metadata.get("cache_hit")
    assert again.collision.build_time_s == 0.0
    np.testing.assert_array_equal(again.modal_model.frequencies_hz, built.modal_model.frequencies_hz)


def test_a_prism_has_nothing_to_decompose():
    with pytest.raises(ValueError, match="prism"):
        build_object("aluminium_bar")
