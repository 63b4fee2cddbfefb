"""Bad user meshes give a MeshError subclass that says what to do, and leave no cache entry."""

import numpy as np
import pytest
import trimesh

from sensors.mesh.tets import MeshError
from sensors.mesh.surface import (
    MeshDegenerateError,
    MeshInvertedError,
    MeshNotWatertightError,
    MeshScaleError,
    MeshSelfIntersectingError,
    MeshTooLargeError,
    MeshTooThinError,
    check_surface,
    estimate_p2_dof,
    min_thickness_m,
    tetrahedralize_tuned,
)


def box(size=(0.04, 0.03, 0.02)):
    return trimesh.creation.box(size)


def open_box():
    m = box()
    m.update_faces(np.arange(len(m.faces)) != 0)
    return m


def inverted_box():
    m = box()
    m.invert()
    return m


def degenerate_box():
    m = box()
    v = np.vstack([m.vertices, m.vertices[0]])  # a duplicate vertex makes a zero-area face
    f = np.vstack([m.faces, [[0, 8, 1]]])
    return trimesh.Trimesh(v, f, process=False)


def overlapping_boxes():
    a, b = box(), box()
    b.apply_translation([0.01, 0.005, 0.003])
    return trimesh.util.concatenate([a, b])


BAD = {
    "open": (open_box, MeshNotWatertightError, "fill_holes"),
    "inverted": (inverted_box, MeshInvertedError, "invert()"),
    "degenerate": (degenerate_box, MeshDegenerateError, "zero-area"),
    "1 mm": (lambda: box((0.001, 0.001, 0.001)), MeshScaleError, "scale="),
    "1 m": (lambda: box((1.0, 0.5, 0.5)), MeshScaleError, "scale="),
    "3 m": (lambda: box((3.0, 0.5, 0.5)), MeshScaleError, "scale="),
    "self-intersecting": (overlapping_boxes, MeshSelfIntersectingError, "union"),
    "too thin": (lambda: box((0.04, 0.03, 0.0002)), MeshTooThinError, "thicken"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_mesh_gives_a_clear_error_and_leaves_no_cache(tmp_path, case):
    make, error, advice = BAD[case]
    with pytest.raises(error) as info:
        tetrahedralize_tuned(make(), element_size_m=0.005, cache_dir=tmp_path)
    assert isinstance(info.value, MeshError)
    assert advice in str(info.value), str(info.value)
    assert list(tmp_path.rglob("*")) == [], "nothing may be left in the cache"


def test_scale_keyword_rescues_a_millimetre_mesh():
    mm = box((40.0, 30.0, 20.0))
    with pytest.raises(MeshScaleError, match="scale=0.001"):
        check_surface(mm)
    s = check_surface(mm, scale=0.001)
    assert np.ptp(s.vertices, axis=0).max() == pytest.approx(0.04)


def test_dof_guard_refuses_before_meshing_and_a_keyword_raises_it(tmp_path):
    m = box((0.1, 0.1, 0.1))
    with pytest.raises(MeshTooLargeError, match="max_dof="):
        tetrahedralize_tuned(m, element_size_m=0.002, cache_dir=tmp_path)
    assert list(tmp_path.rglob("*")) == []
    assert estimate_p2_dof(1e-3, 0.002) > 150_000
    tm = tetrahedralize_tuned(box(), element_size_m=0.01, cache_dir=tmp_path, max_dof=10**6, progress=False)
    assert tm.volume_m3() == pytest.approx(0.04 * 0.03 * 0.02, rel=1e-3)


def test_thickness_probe_measures_a_plate():
    assert min_thickness_m(box((0.04, 0.03, 0.002))) == pytest.approx(0.002, rel=0.02)


def test_a_cached_tet_mesh_loads_without_re_checking_the_surface(tmp_path, monkeypatch):
    """A hit was checked when it was built: loading it skips the check (seconds on a mug)."""
    import sensors.mesh.surface as sm

    built = tetrahedralize_tuned(box(), element_size_m=0.01, cache_dir=tmp_path, progress=False)

    def no_check(*args, **kwargs):
        raise AssertionError("a cache hit must not re-check the surface")

    monkeypatch.setattr(sm, "check_surface", no_check)
    loaded = tetrahedralize_tuned(box(), element_size_m=0.01, cache_dir=tmp_path, progress=False)
    np.testing.assert_array_equal(loaded.tets, built.tets)
    np.testing.assert_array_equal(loaded.vertices_m, built.vertices_m)
    # Another surface is a miss, and a miss is checked.
    with pytest.raises(AssertionError, match="re-check"):
        tetrahedralize_tuned(box((0.05, 0.03, 0.02)), element_size_m=0.01, cache_dir=tmp_path, progress=False)
