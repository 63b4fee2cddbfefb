"""The procedural everyday objects: closed surfaces, cavities, materials, sizes, tet meshes,
and their modes against an independent gmsh + scikit-fem reference."""

import math

import numpy as np
import pytest

from everyday_reference import reference_frequencies_hz
from sensors.objects import EVERYDAY_OBJECTS, get_object
from sensors.task.grasp import MAX_OPENING_M
from sensors.mesh.layered import p2_dof_count
from sensors.mesh.quadratic import quadratic_mesh
from sensors.mesh.tets import check_tet_quality
from sensors.mesh.surface import DEFAULT_MAX_DOF

CONTAINERS = ("mug", "bottle", "can", "glass", "box")
MATERIAL_OF = {"mug": "ceramic", "bottle": "glass", "can": "steel", "glass": "glass", "box": "abs", "spoon": "wood",
               "l_bracket": "aluminium"}


@pytest.fixture(scope="module")
def objects():
    return {name: get_object(name).solid() for name in EVERYDAY_OBJECTS}


@pytest.mark.parametrize("name", list(EVERYDAY_OBJECTS))
def test_surface_is_a_closed_outward_solid_of_graspable_size(objects, name):
    obj = objects[name]
    s = obj.surface
    assert s.is_watertight and s.is_winding_consistent
    assert s.volume > 0
    assert obj.material.name == MATERIAL_OF[name]
    extents = np.ptp(s.vertices, axis=0)
    assert 0.002 < extents.max() < 0.5, "metres, hand-sized"
    assert extents.min() < MAX_OPENING_M, "the hand must fit around it somewhere"
    assert np.allclose(obj.main_axis, [1, 0, 0])
    assert obj.to_dict()["name"] == name


@pytest.mark.parametrize("name", list(EVERYDAY_OBJECTS))
def test_tet_mesh_is_valid_and_fills_the_surface(objects, name):
    obj = objects[name]
    tm = obj.tet_mesh()
    check_tet_quality(tm.vertices_m, tm.tets)
    # Revolved surfaces are finer than the mesh (faceting): within 1%; grids are exact.
    assert tm.volume_m3() == pytest.approx(obj.surface.volume, rel=1e-2)
    assert tm.digest() == obj.tet_mesh().digest(), "structured meshing is deterministic"
    dof = p2_dof_count(tm)
    assert dof == 3 * len(quadratic_mesh(tm)[0]), "the dof count must equal the P2 mesh's nodes"
    assert dof < DEFAULT_MAX_DOF


@pytest.mark.parametrize("name", CONTAINERS)
def test_containers_expose_a_closed_cavity_inside_the_solid(objects, name):
    obj = objects[name]
    cav = obj.cavity
    assert cav is not None and cav.is_watertight and cav.volume > 0
    # The cavity does not overlap the solid: points inside it are outside the solid.
    pts = cav.sample(300, return_index=False)
    inner = 0.98 * (pts - cav.centroid) + cav.centroid
    assert not obj.surface.contains(inner).any()
    if name != "box":
        prof = obj.inner_profile_m
        assert prof[0, 1] == 0.0 and np.all(np.diff(prof[:, 0]) >= 0)
        x = 0.5 * (prof[1, 0] + prof[-1, 0])
        r = np.interp(x, prof[1:, 0], prof[1:, 1])
        assert obj.surface.contains([[x, 0.0, r * 1.05]])[0] and not obj.surface.contains([[x, 0.0, r * 0.95]])[0]


def test_non_containers_have_no_cavity(objects):
    assert objects["spoon"].cavity is None and objects["l_bracket"].cavity is None


@pytest.mark.parametrize("name, mesh_size_m", [("l_bracket", 0.002), ("can", 0.004)])
def test_modes_below_10_khz_within_1_percent_of_independent_reference(tmp_path, name, mesh_size_m):
    obj = get_object(name).solid()
    model = obj.modal_model(max_frequency_hz=10000.0, cache_dir=tmp_path, progress=False)
    n = int((model.frequencies_hz <= 10000.0).sum())
    assert n >= 3
    ref, _ = reference_frequencies_hz(obj, n, mesh_size_m)
    err = model.frequencies_hz[:n] / ref - 1
    assert np.max(np.abs(err)) < 0.01, f"{name}: errors {np.round(100 * err, 2)} %"


def test_a_cached_model_loads_without_meshing_and_an_edit_misses(tmp_path, monkeypatch):
    """The alias entry names the model's own cache entry: a cached load skips the mesher, and
    another geometry or material is a miss that builds its own model."""
    import dataclasses

    obj = get_object("l_bracket").solid()
    built = obj.modal_model(max_frequency_hz=6000.0, cache_dir=tmp_path, progress=False)
    assert not built.metadata.get("cache_hit")

    def no_mesh(resolution=1.0):
        raise AssertionError("a cached load must not mesh")

    no_mesher = dataclasses.replace(obj, tet_mesher=no_mesh)
    no_mesh.__module__ = obj.tet_mesher.__module__
    loaded = no_mesher.modal_model(max_frequency_hz=6000.0, cache_dir=tmp_path, progress=False)
    assert loaded.metadata.get("cache_hit")
    np.testing.assert_array_equal(loaded.frequencies_hz, built.frequencies_hz)
    # Another material, band or resolution is not served the bracket's model.
    with pytest.raises(AssertionError, match="must not mesh"):
        dataclasses.replace(no_mesher, material=get_object("can").solid().material).modal_model(
            max_frequency_hz=6000.0, cache_dir=tmp_path, progress=False)
    with pytest.raises(AssertionError, match="must not mesh"):
        no_mesher.modal_model(max_frequency_hz=5000.0, cache_dir=tmp_path, progress=False)
    # An edited mesher (its source is in the key) is a miss.
    import sensors.objects.everyday

    with monkeypatch.context() as m:
        m.setattr(sensors.objects.everyday, "_MESHER_VERSION", "edited")
        with pytest.raises(AssertionError, match="must not mesh"):
            no_mesher.modal_model(max_frequency_hz=6000.0, cache_dir=tmp_path, progress=False)
    # A corrupt alias is a miss, rebuilt from the mesh (which hits the model's own entry).
    for alias in tmp_path.glob("*.npz"):
        if "modal_key" in np.load(alias).files:
            alias.write_bytes(b"not an npz")
    again = obj.modal_model(max_frequency_hz=6000.0, cache_dir=tmp_path, progress=False)
    np.testing.assert_array_equal(again.frequencies_hz, built.frequencies_hz)
