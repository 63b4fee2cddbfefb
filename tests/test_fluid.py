"""sensors.fluid on a small aluminium can (built in seconds): the behaviour a filled container
must have, its API for the scene/env side, and that synthesis takes it unchanged.

The physics is checked against references in test_fluid_analytic.py (series solution) and
test_fluid_coupled.py (fully coupled FEM on the everyday mug).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import sensors
from sensors import Contact, Excitation, ModalBasis, simulate_recording, with_material
from sensors.fluid.cavity import LiquidSpillError
from sensors.modal.damping import modal_damping_parts
from sensors.fluid import Container, FilledModalModel, container, filled
from sensors.materials.liquids import LIQUIDS, Liquid, get_liquid
from sensors.mesh.tets import MeshError
from sensors.materials import scaled_material
from sensors.modal.basis import MaterialView, material_scaling
from sensors.modal.model import ModalModel
from small_can import small_can_container


def tilted(angle_deg, towards=(0.0, 1.0, 0.0)):
    """Free-surface normal of the can (axis +x) tilted by ``angle_deg`` towards ``towards``."""
    a = math.radians(angle_deg)
    return np.array([math.cos(a), 0.0, 0.0]) + math.sin(a) * np.asarray(towards, float)


@pytest.fixture(scope="module")
def small_can(run_cache_dir):
    obj, _, c = small_can_container(run_cache_dir)
    return obj, c, run_cache_dir


def surface_points(obj, n=12, seed=0):
    rng = np.random.default_rng(seed)
    return obj.surface.vertices[rng.choice(len(obj.surface.vertices), n, replace=False)]


def test_empty_container_is_the_dry_model(small_can):
    obj, c, _ = small_can
    dry = c.dry
    for empty in (filled(c, 0.0), filled(c, liquid="honey", volume_m3=0.0)):
        np.testing.assert_allclose(empty.frequencies_hz, dry.frequencies_hz, rtol=1e-9, atol=0)
        p = surface_points(obj)
        scale = np.abs(dry.mode_shapes_at(p)).max()
        np.testing.assert_allclose(empty.mode_shapes_at(p), dry.mode_shapes_at(p), rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(empty.damping_matrix(()), dry.damping_matrix(()), rtol=1e-9, atol=0)
        assert empty.mass_kg == pytest.approx(dry.mass_kg, rel=1e-12)
        assert empty.liquid.mass_kg == 0.0 and empty.liquid.volume_m3 == 0.0


def test_frequencies_decrease_with_fill(small_can):
    _, c, _ = small_can
    n = c.dry.n_modes
    previous = c.dry.frequencies_hz
    for fill in (0.25, 0.5, 0.75, 1.0):
        f = filled(c, fill).frequencies_hz[:n]
        assert np.all(f < previous * (1 - 1e-4)), (fill, f, previous)
        previous = f
    # The full can's lowest ovalling pair drops by more than 10 %.
    assert previous[0] < 0.9 * c.dry.frequencies_hz[0]


def test_frequencies_decrease_with_liquid_density(small_can):
    _, c, _ = small_can
    n = c.dry.n_modes
    by_density = sorted(list(LIQUIDS.values()) + [Liquid("mercury-ish", 3000.0)], key=lambda q: q.density_kg_m3)
    previous = c.dry.frequencies_hz
    for liquid in by_density:
        # The added mass alone (each liquid's own speed of sound adds modes of its own).
        f = filled(c, 0.6, liquid=liquid, compressible=False).frequencies_hz[:n]
        assert np.all(f < previous), (liquid.name, f, previous)
        previous = f
    # A bare density is an inviscid liquid of that density (and water's speed of sound).
    np.testing.assert_allclose(filled(c, 0.6, liquid=998.2).frequencies_hz,
                               filled(c, 0.6).frequencies_hz, rtol=1e-12)


def test_tilted_container_differs_from_upright_at_the_same_volume(small_can):
    _, c, _ = small_can
    upright = filled(c, 0.5)
    tilt_y = filled(c, 0.5, surface_normal=tilted(20))
    tilt_z = filled(c, 0.5, surface_normal=tilted(20, (0.0, 0.0, 1.0)))
    assert tilt_y.liquid_volume_m3 == pytest.approx(upright.liquid_volume_m3, rel=1e-12)
    n = c.dry.n_modes
    assert np.max(np.abs(tilt_y.frequencies_hz[:n] / upright.frequencies_hz[:n] - 1)) > 3e-3
    # The can is axisymmetric: tilting towards y or towards z gives the same frequencies (to the
    # mesh's symmetry, which splits its pairs by 0.1 %).
    np.testing.assert_allclose(tilt_z.frequencies_hz[:n], tilt_y.frequencies_hz[:n], rtol=2e-3)


def test_liquid_body_for_the_physics_engine(small_can):
    obj, c, _ = small_can
    d = obj.dimensions_m
    ri, floor = d["inner_radius_m"], d["floor_m"]
    wet = filled(c, 0.5)
    body = wet.liquid
    volume = 0.5 * math.pi * ri**2 * (d["height_m"] - floor)
    assert body.volume_m3 == pytest.approx(volume, rel=1e-3)
    assert body.mass_kg == pytest.approx(998.2 * body.volume_m3, rel=1e-12)
    h = body.volume_m3 / (math.pi * ri**2)
    np.testing.assert_allclose(body.centre_of_mass_m, [floor + h / 2, 0, 0], atol=1e-4 * h)
    # A solid cylinder's inertia about its centre.
    m = body.mass_kg
    np.testing.assert_allclose(np.diag(body.inertia_kg_m2), [m * ri**2 / 2] + 2 * [m * (3 * ri**2 + h**2) / 12],
                               rtol=5e-3)
    assert wet.mass_kg == pytest.approx(c.dry.mass_kg + m, rel=1e-12)
    # Tilted towards +y (gravity towards -y in the object frame): the liquid moves to -y.
    tilted_body = c.liquid_body("water", fill_fraction=0.5, surface_normal=tilted(20))
    assert tilted_body.centre_of_mass_m[1] < -1e-4 and abs(tilted_body.centre_of_mass_m[2]) < 1e-6
    assert tilted_body.mass_kg == pytest.approx(m, rel=1e-12)
    assert body.to_dict()["mass_kg"] == pytest.approx(m)


def test_spilling_and_an_uncovered_floor_are_refused(small_can):
    _, c, _ = small_can
    assert c.max_fill_fraction() == 1.0
    most = c.max_fill_fraction(tilted(30))
    assert 0.5 < most < 1.0
    filled(c, 0.98 * most, surface_normal=tilted(30))
    with pytest.raises(LiquidSpillError, match="spill"):
        filled(c, min(1.0, 1.02 * most), surface_normal=tilted(30))
    with pytest.raises(MeshError, match="bottom"):
        filled(c, 0.05, surface_normal=tilted(60))
    with pytest.raises(TypeError, match="exactly one"):
        filled(c, 0.5, volume_m3=1e-6)
    with pytest.raises(ValueError):
        filled(c, 1.5)


def test_liquid_damping_is_viscous_and_reaches_synthesis(small_can):
    _, c, _ = small_can
    water, honey = filled(c, 0.6), filled(c, 0.6, liquid="honey")
    inviscid = filled(c, 0.6, liquid=get_liquid(998.2))
    assert np.all(inviscid.added_damping_per_s == 0.0)
    assert np.all(water.added_damping_per_s > 0.0)
    # Stokes layer: sigma ~ sqrt(rho mu); honey's is two orders above water's.
    ratio = honey.viscous_decay_rates_per_s()[:4] / water.viscous_decay_rates_per_s()[:4]
    assert np.all(ratio > 30.0)
    d, _ = modal_damping_parts(honey)
    mat = honey.material
    np.testing.assert_allclose(d, mat.alpha + mat.beta * honey.angular_frequencies_rad_s**2
                               + honey.added_damping_per_s, rtol=1e-12)
    np.testing.assert_allclose(honey.decay_rates_per_s, 0.5 * np.diag(honey.damping_matrix()), rtol=1e-12)


def test_filled_model_is_a_modal_basis_that_synthesis_takes(small_can):
    obj, c, _ = small_can
    ro, x = obj.dimensions_m["outer_radius_m"], 0.6 * obj.dimensions_m["height_m"]
    act = Contact((x, ro, 0.0), (0.0, 1.0, 0.0), 10.0, 0.5)
    mic = Contact((x, -ro, 0.0), (0.0, -1.0, 0.0), 10.0, 0.5)
    exc = Excitation.by_name("impulse")
    spectra = {}
    for fill in (0.0, 0.9):
        model = filled(c, fill)
        assert isinstance(model, ModalBasis)
        obs = simulate_recording(model, exc, 0.5, act, mic)
        assert np.all(np.isfinite(obs.waveform)) and np.abs(obs.waveform).max() > 0
        spec = np.abs(np.fft.rfft(obs.waveform))
        freqs = np.fft.rfftfreq(len(obs.waveform), 1 / obs.sample_rate_hz)
        band = (freqs > 1000) & (freqs < 8000)
        spectra[fill] = freqs[band][np.argmax(spec[band])]
    # The strongest resonance in the band moves down with the liquid.
    assert spectra[0.9] < spectra[0.0]


def test_other_materials_are_exact_and_plain_views_are_refused(small_can):
    obj, c, cache_dir = small_can
    wet = filled(c, 0.7)
    steel = dataclasses.replace(sensors.get_material("steel"), poisson_ratio=c.dry.material.poisson_ratio)
    fast = with_material(wet, steel)
    assert isinstance(fast, FilledModalModel) and fast.material == steel
    # The reference: the container rebuilt on the dry modes rescaled to steel (its own static
    # correction and liquid loading); with_material rescales the wall of the filled model only.
    dry = c.dry
    freq_scale, shape_scale = material_scaling(dry.material, steel)
    band_hz = dry.metadata["max_frequency_hz"] * freq_scale
    steel_dry = ModalModel(dry.nodes_m, dry.elements, dry.frequencies_hz * freq_scale, dry.mode_shapes * shape_scale,
                           steel, metadata=dict(dry.metadata, max_frequency_hz=band_hz))
    rebuilt = filled(Container(steel_dry, obj, cache_dir=cache_dir), 0.7)
    np.testing.assert_allclose(fast.frequencies_hz, rebuilt.frequencies_hz, rtol=1e-9)
    p = surface_points(obj, 4)
    np.testing.assert_allclose(np.abs(fast.mode_shapes_at(p)).sum(axis=(0, 1)),
                               np.abs(rebuilt.mode_shapes_at(p)).sum(axis=(0, 1)), rtol=1e-6)
    assert fast.mass_kg == pytest.approx(rebuilt.mass_kg, rel=1e-9)
    # Damping-only randomization keeps the frequencies and scales the wall's damping.
    damped = with_material(wet, scaled_material(wet.material, damping_scale=2.0))
    np.testing.assert_allclose(damped.frequencies_hz, wet.frequencies_hz, rtol=1e-12)
    with pytest.raises(TypeError, match="with_material"):
        MaterialView(wet, steel)


def test_filled_memoizes_containers_and_fills(small_can, tmp_path):
    obj, c, cache_dir = small_can
    options = dict(resolution=0.5, max_frequency_hz=20000.0, cache_dir=cache_dir, progress=False)
    a = filled(obj, 0.4, **options)
    assert filled(obj, 0.4, **options) is a
    assert container(obj, **options) is container(obj, **options)
    assert container(c) is c
    np.testing.assert_allclose(a.frequencies_hz, filled(c, 0.4).frequencies_hz, rtol=1e-12)
    # The static correction comes from the disk cache the second time (same vectors).
    again = Container(c.dry, obj, cache_dir=cache_dir)
    np.testing.assert_array_equal(again.basis_eigenvalues, c.basis_eigenvalues)
    with pytest.raises(TypeError, match="cavity"):
        container(c.dry)
    with pytest.raises(TypeError, match="not a container"):
        container(c.dry, cavity=sensors.objects.everyday.spoon())
    with pytest.raises(TypeError, match="not a container"):
        filled("steel_bar", 0.5)  # a catalog prism has no cavity


def test_liquids():
    assert {"water", "oil", "honey", "ethanol"} <= set(LIQUIDS)
    assert get_liquid("Water") is LIQUIDS["water"]
    user = get_liquid(1200)
    assert user.density_kg_m3 == 1200.0 and user.viscosity_pa_s == 0.0
    with pytest.raises(ValueError):
        Liquid("bad", -1.0)
    with pytest.raises(KeyError, match="known"):
        get_liquid("lava")


def test_a_static_correction_by_another_solver_gives_the_same_wet_modes(tmp_path, monkeypatch):
    """``added_mass.STATIC_CORRECTION_SOLVER`` (default ``"default"``): the container's one
    factorization of K + s M by the project's direct solver (PARDISO where MKL is installed)
    against SciPy's SuperLU with MMD ordering (None, the reference): another rounding of the same
    static solves, so the wet frequencies of a fill agree to rounding (1e-9; measured 1.6e-12 on
    the mug) and the correction's own eigenvalues, stiff modes far above the band, to 1e-6
    (measured 1.9e-10); its cache entries are its own."""
    from small_can import small_can_container

    from sensors.fem import direct_solver
    from sensors.fluid import Container, added_mass

    monkeypatch.setattr(added_mass, "STATIC_CORRECTION_SOLVER", None)
    obj, dry, reference = small_can_container(tmp_path)
    reference_key, reference_eigenvalues = reference.cache_key, reference.basis_eigenvalues  # built now, by SuperLU
    used = []
    factorize = direct_solver.factorize
    monkeypatch.setattr(direct_solver, "factorize", lambda A, solver=None: used.append(A.shape) or factorize(A, solver))
    monkeypatch.setattr(added_mass, "STATIC_CORRECTION_SOLVER", "default")
    other = Container.of(obj, dry=dry, cache_dir=tmp_path)
    assert used == [(3 * len(dry.nodes_m),) * 2]           # its own correction, not the reference's entry
    assert other.cache_key != reference_key
    np.testing.assert_allclose(other.basis_eigenvalues[6:], reference_eigenvalues[6:], rtol=1e-6)
    for compressible in (True, False):
        a = filled(other, 0.6, compressible=compressible).frequencies_hz
        b = filled(reference, 0.6, compressible=compressible).frequencies_hz
        np.testing.assert_allclose(a, b, rtol=1e-9)
