"""Structured meshes, pytetwild path, quality and input validation."""

import numpy as np
import pytest
import trimesh

from sensors.mesh.prisms import bar_mesh, rod_mesh, tube_mesh
from sensors.mesh.quadratic import quadratic_mesh
from sensors.mesh.tets import MeshError, boundary_faces, check_tet_quality, tet_volumes
from sensors.mesh.tetwild import tetrahedralize_surface, validate_surface


@pytest.mark.parametrize(
    "mesh, volume",
    [
        (bar_mesh(0.2, 0.025, 0.02), 0.2 * 0.025 * 0.02),
        (tube_mesh(0.2, 0.0125, 0.0095), np.pi * (0.0125**2 - 0.0095**2) * 0.2),
        (rod_mesh(0.1, 0.01), np.pi * 0.01**2 * 0.1),
    ],
)
def test_structured_meshes_valid_centred_and_deterministic(mesh, volume):
    v, t = mesh.vertices_m, mesh.tets
    check_tet_quality(v, t)
    assert np.all(tet_volumes(v, t) > 0)
    np.testing.assert_allclose(0.5 * (v.min(0) + v.max(0)), 0, atol=1e-12)
    assert np.ptp(v[:, 0]) == pytest.approx(mesh.dimensions_m["length_m"])
    # Straight-sided facets under-fill a cylinder by O(h^2); P2 curving fixes that (below).
    assert mesh.volume_m3() == pytest.approx(volume, rel=0.03)
    again = {"bar": bar_mesh, "tube": tube_mesh, "rod": rod_mesh}[mesh.kind](**mesh.dimensions_m)
    assert again.digest() == mesh.digest()
    # Conforming: every interior face shared by exactly two tets, boundary closed.
    faces, _ = boundary_faces(t)
    surf = trimesh.Trimesh(v, faces, process=True)
    assert surf.is_watertight and surf.is_winding_consistent and surf.volume > 0


def test_p2_nodes_on_the_cylinder():
    mesh = tube_mesh(0.1, 0.0125, 0.0095)
    nodes, t10 = quadratic_mesh(mesh)
    r = np.hypot(nodes[:, 1], nodes[:, 2])
    on_outer = np.abs(r - 0.0125) < 1e-12
    on_inner = np.abs(r - 0.0095) < 1e-12
    assert on_outer.sum() > 2 * (np.abs(np.hypot(*mesh.vertices_m[:, 1:].T) - 0.0125) < 1e-12).sum() - 10
    assert np.all((r > 0.0095 - 1e-12) & (r < 0.0125 + 1e-12))
    assert on_inner.any()
    # Mid-edge nodes of interior edges stay at the midpoint.
    assert t10.shape[1] == 10 and t10[:, :4].max() < len(mesh.vertices_m)


def test_resolution_knob_refines():
    assert bar_mesh(0.2, 0.025, 0.025, resolution=2).n_tets > 4 * bar_mesh(0.2, 0.025, 0.025).n_tets
    assert tube_mesh(0.2, 0.0125, 0.0095, element_size_m=0.002).n_tets > tube_mesh(0.2, 0.0125, 0.0095).n_tets


@pytest.mark.parametrize("bad", [dict(length_m=0), dict(width_m=-1), dict(height_m=float("nan"))])
def test_bad_dimensions(bad):
    with pytest.raises(MeshError):
        bar_mesh(**{**dict(length_m=0.1, width_m=0.01, height_m=0.01), **bad})


def test_tube_inner_radius_must_be_smaller():
    with pytest.raises(MeshError, match="inner_radius"):
        tube_mesh(0.1, 0.01, 0.01)


def test_quality_check_names_the_problem():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    with pytest.raises(MeshError, match="inverted"):
        check_tet_quality(v, np.array([[0, 2, 1, 3]]))
    flat = v.copy()
    flat[3] = [0.3, 0.3, 0]
    with pytest.raises(MeshError, match="zero-volume"):
        check_tet_quality(flat, np.array([[0, 1, 2, 3]]))
    with pytest.raises(MeshError, match="non-finite"):
        check_tet_quality(np.where(v == 1, np.nan, v), np.array([[0, 1, 2, 3]]))
    two = np.vstack([v, v + 5])
    with pytest.raises(MeshError, match="disconnected"):
        check_tet_quality(two, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]))


def test_surface_validation_errors():
    box = trimesh.creation.box((0.1, 0.02, 0.02))
    validate_surface(box)
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2], process=False)
    with pytest.raises(MeshError, match="not watertight"):
        validate_surface(open_box)
    nan_box = trimesh.Trimesh(np.where(np.arange(8)[:, None] == 0, np.nan, box.vertices), box.faces, process=False)
    with pytest.raises(MeshError, match="non-finite"):
        validate_surface(nan_box)
    flat = trimesh.Trimesh(box.vertices * [1, 1, 0], box.faces, process=False)
    with pytest.raises(MeshError):
        validate_surface(flat)
    two = trimesh.util.concatenate([box, box.copy().apply_translation([0.03, 0.005, 0])])
    with pytest.raises(MeshError, match="self-intersecting"):
        validate_surface(two)
    inverted = box.copy()
    inverted.invert()
    assert validate_surface(inverted).volume > 0  # orientation fixed


@pytest.mark.slow
def test_pytetwild_path_tight_and_cached(tmp_path):
    surface = trimesh.creation.box((0.06, 0.02, 0.01))
    tm = tetrahedralize_surface(surface, element_size_m=0.005, cache_dir=tmp_path)
    check_tet_quality(tm.vertices_m, tm.tets)
    np.testing.assert_allclose(tm.vertices_m.min(0), surface.bounds[0], atol=1e-3 * 0.01)
    np.testing.assert_allclose(tm.vertices_m.max(0), surface.bounds[1], atol=1e-3 * 0.01)
    assert tm.volume_m3() == pytest.approx(surface.volume, rel=1e-3)
    again = tetrahedralize_surface(surface, element_size_m=0.005, cache_dir=tmp_path)
    assert again.digest() == tm.digest()  # served from the cache: identical

    # End to end (tet mesh from the cache above): same modes as the structured bar.
    from sensors import ModalModel

    opts = dict(cache_dir=tmp_path, progress=False, max_frequency_hz=30000)
    general = ModalModel.from_mesh(surface, "aluminium", element_size_m=0.005, **opts)
    bar = ModalModel.bar(0.06, 0.02, 0.01, "aluminium", **opts)
    n = min(4, bar.n_modes)
    np.testing.assert_allclose(general.frequencies_hz[:n], bar.frequencies_hz[:n], rtol=0.01)
    assert general.kind == "mesh" and general.dimensions_m["extent_x_m"] == pytest.approx(0.06)


def test_row_codes_are_equal_exactly_for_equal_rows_and_refuse_overflow():
    from sensors.mesh.tets import row_codes

    rows = np.random.default_rng(0).integers(0, 7, size=(500, 3))
    codes = row_codes(rows)
    same_code = codes[:, None] == codes[None, :]
    same_row = (rows[:, None, :] == rows[None, :, :]).all(axis=2)
    np.testing.assert_array_equal(same_code, same_row)
    assert row_codes(np.array([[3_000_000, 0, 0]])) is None  # (n)^3 would overflow int64
