"""Stress tests: random shapes and materials give valid modes or a clear error; bad input is named."""

import math

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sensors import Material, MaterialView, ModalModel, with_material
from sensors.fem.eigen import EigenSolveError, mode_residuals
from sensors.mesh.tets import MeshError

materials = st.builds(
    Material,
    name=st.just("random"),
    density_kg_m3=st.floats(50.0, 20000.0),
    youngs_modulus_pa=st.floats(1e6, 5e11),
    poisson_ratio=st.floats(-0.9, 0.49),
    alpha=st.floats(0.0, 100.0),
    beta=st.floats(0.0, 1e-5),
    gamma=st.floats(0.0, 1.0),
)


def check_modes(model: ModalModel):
    K, M = model.assemble_matrices()
    U = model.mode_matrix()
    assert model.n_modes > 0
    assert np.all(np.isfinite(model.frequencies_hz)) and np.all(np.isfinite(U))
    assert np.all(np.diff(model.frequencies_hz) >= 0) and model.frequencies_hz[0] > 0
    orth = np.linalg.norm(U.T @ (M @ U) - np.eye(model.n_modes))
    assert orth < 1e-8, orth
    assert mode_residuals(K, M, model.eigenvalues, U).max() < 1e-6
    assert np.all(model.decay_rates_per_s >= 0)


@pytest.mark.slow
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(["bar", "tube", "rod"]),
    length_m=st.floats(0.02, 0.5),
    aspect=st.floats(1.0, 50.0),
    wall=st.floats(0.05, 0.9),
    flat=st.floats(0.2, 1.0),
    material=materials,
)
def test_random_shapes_and_materials(kind, length_m, aspect, wall, flat, material):
    size = length_m / aspect  # aspect ratio up to 50:1
    # Few modes per object keeps this fast; the band scales with the object's own frequencies.
    c = material.bar_wave_speed_m_s
    band = 1.0 * c / length_m  # both axial-mode families and ~10 bending modes at 50:1
    opts = dict(cache=False, progress=False, max_frequency_hz=band, resolution=0.5)
    try:
        if kind == "bar":
            model = ModalModel.bar(length_m, size, size * flat, material, **opts)
        elif kind == "tube":
            ro = size / 2
            model = ModalModel.tube(length_m, ro, ro * (1 - wall), material, **opts)  # thin walls
        else:
            model = ModalModel.rod(length_m, size / 2, material, **opts)
    except (MeshError, EigenSolveError) as exc:  # allowed, but it must say something
        assert len(str(exc)) > 20
        return
    check_modes(model)


def test_extreme_slender_thin_walled_tube():
    # A 0.3 mm wall (6% of the radius): curved P2 elements must not invert.
    m = ModalModel.tube(0.1, 0.005, 0.0047, "aluminium", cache=False, progress=False, max_frequency_hz=8000,
                        resolution=0.5)
    check_modes(m)


def test_shift_is_scaled_for_soft_and_stiff_materials():
    # 1e6 Pa foam-like and 4e11 Pa ceramics differ by 1e5 in eigenvalue scale.
    for E, rho in ((1e6, 100.0), (4e11, 3900.0)):
        mat = Material("x", rho, E, 0.3)
        m = ModalModel.bar(0.1, 0.01, 0.01, mat, cache=False, progress=False,
                           max_frequency_hz=2 * math.sqrt(E / rho) / 0.1, resolution=0.5)
        check_modes(m)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda b: trimesh.Trimesh(b.vertices, b.faces[:-1], process=False), "not watertight"),
        (lambda b: trimesh.util.concatenate([b, b.copy().apply_translation([0.02, 0.003, 0.001])]), "self-intersecting"),
        (lambda b: trimesh.Trimesh(b.vertices * [1, 1, 0], b.faces, process=False), "zero"),
        (lambda b: trimesh.Trimesh(np.where(np.arange(8)[:, None] == 3, np.inf, b.vertices), b.faces, process=False),
         "non-finite"),
    ],
)
def test_bad_meshes_raise_clear_errors(make, message):
    box = trimesh.creation.box((0.05, 0.01, 0.01))
    with pytest.raises(MeshError, match=message):
        ModalModel.from_mesh(make(box), "abs", cache=False)


def test_bad_options_raise():
    with pytest.raises(ValueError, match="element"):
        ModalModel.bar(0.1, 0.01, 0.01, "abs", element="p3", cache=False)
    with pytest.raises(ValueError, match="max_frequency_hz"):
        ModalModel.bar(0.1, 0.01, 0.01, "abs", max_frequency_hz=-1, cache=False)
    with pytest.raises(TypeError, match="unknown option"):
        ModalModel.bar(0.1, 0.01, 0.01, "abs", resolutoin=2)


# ----------------------------------------------------------------------------- API


def test_cache_save_load_and_queries(tmp_path):
    import time

    opts = dict(cache_dir=tmp_path, progress=False, resolution=0.5, max_frequency_hz=12000)
    m = ModalModel.bar(0.2, 0.025, 0.025, "wood", **opts)
    t0 = time.perf_counter()
    again = ModalModel.bar(0.2, 0.025, 0.025, "wood", **opts)
    assert time.perf_counter() - t0 < 0.5 and again.metadata["cache_hit"]
    np.testing.assert_array_equal(again.frequencies_hz, m.frequencies_hz)
    other = ModalModel.bar(0.2, 0.025, 0.025, "steel", **opts)  # material is part of the key
    assert not other.metadata.get("cache_hit") and other.frequencies_hz[0] != m.frequencies_hz[0]

    path = m.save(tmp_path / "bar.npz")
    loaded = ModalModel.load(path)
    np.testing.assert_array_equal(loaded.mode_shapes, m.mode_shapes)
    assert loaded.material == m.material and loaded.kind == "bar" and loaded.dimensions_m["width_m"] == 0.025
    np.testing.assert_allclose(loaded.decay_rates_per_s, (m.material.alpha + m.material.beta * m.angular_frequencies_rad_s**2) / 2)

    # Interpolation reproduces nodal values and varies smoothly between nodes (5 mm steps).
    nodes = m.nodes_m[:5]
    np.testing.assert_allclose(m.mode_shapes_at(nodes), m.mode_shapes[:5], atol=1e-9 * np.abs(m.mode_shapes).max())
    x = np.arange(-0.06, 0.0601, 0.005)
    top = np.c_[x, np.full_like(x, 0.003), np.full_like(x, 0.0125)]
    u = m.mode_shapes_at(top)[:, :, 0]
    assert np.abs(np.diff(u, 2, axis=0)).max() < 0.2 * np.abs(u).max()
    assert m.mode_shapes_at(top[0]).shape == (1, 3, m.n_modes)

    above = top + [0, 0, 0.01]
    np.testing.assert_allclose(m.surface_distance_m(above), 0.01, rtol=1e-9)
    np.testing.assert_allclose(m.mode_shapes_at(above), m.mode_shapes_at(top), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.surface_normal_at(above), np.tile([0, 0, 1.0], (len(x), 1)), atol=1e-12)


def test_tube_normals_are_radial():
    m = ModalModel.tube(0.2, 0.0125, 0.0095, "abs", cache=False, progress=False, resolution=0.5,
                        max_frequency_hz=4000)
    t = np.linspace(0, 2 * np.pi, 7)
    p = np.c_[np.zeros_like(t), 0.0125 * np.cos(t), 0.0125 * np.sin(t)]
    np.testing.assert_allclose(m.surface_normal_at(p), p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-12)
    inner = p * (0.0095 / 0.0125)
    np.testing.assert_allclose(m.surface_normal_at(inner), -p / 0.0125, atol=1e-12)
    assert m.surface_distance_m(p).max() < 0.0125 * (1 - np.cos(np.pi / 16)) + 1e-9  # facets vs the circle


def test_tiny_model_from_arrays():
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    shapes = np.arange(12, dtype=float).reshape(4, 3, 1)
    m = ModalModel(nodes, [[0, 1, 2, 3]], [100.0], shapes, "abs")
    np.testing.assert_allclose(m.mode_shapes_at([[0.25, 0.25, 0.25]])[0, :, 0], shapes.mean(axis=0)[:, 0])
    with pytest.raises(ValueError, match="mode_shapes"):
        ModalModel(nodes, [[0, 1, 2, 3]], [100.0, 200.0], shapes, "abs")


def test_with_material_is_exact_for_same_poisson_ratio():
    opts = dict(cache=False, progress=False, resolution=0.5, max_frequency_hz=15000)
    base = ModalModel.bar(0.2, 0.025, 0.025, "abs", **opts)
    other = Material("abs-like", 1500.0, 4.0e9, 0.36, alpha=1.0)
    scaled = base.with_material(other)
    assert isinstance(scaled, MaterialView) and with_material(base, other).frequencies_hz == pytest.approx(
        scaled.frequencies_hz, rel=0)
    direct = ModalModel.bar(0.2, 0.025, 0.025, other, **opts)
    n = min(scaled.n_modes, direct.n_modes)
    np.testing.assert_allclose(scaled.frequencies_hz[:n], direct.frequencies_hz[:n], rtol=1e-8)
    K, M = direct.assemble_matrices()
    U = scaled.mode_shapes_at(direct.nodes_m).reshape(-1, scaled.n_modes)  # nodal values: exact
    np.testing.assert_allclose(U.T @ (M @ U), np.eye(scaled.n_modes), atol=1e-8)
    rebuilt = base.with_material("steel", cache=False, progress=False)  # other Poisson ratio: new solve
    assert rebuilt.material.name == "steel" and rebuilt.metadata["resolution"] == 0.5
