"""A table's fill with its wall matrices made when first read (``sensors.fluid.fill_table.
LAZY_WET_MATRICES``) against the fill made at once (the reference): the liquid's body at once, the
same bits in every modal quantity once read, and FillLevel-v0's observations and infos the same
bits with sensing on and off."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from sensors._infra.lru import clear_all
from sensors.fluid import fill_table as ft
from sensors.fluid.fill_table import fill_table
from sensors.materials import scaled_material
from sensors.materials.liquids import get_liquid
from small_can import small_can_container


@pytest.fixture(scope="module")
def small_can(run_cache_dir):
    return small_can_container(run_cache_dir)[2]


def fill(container, liquid, fraction, compressible, lazy, monkeypatch):
    monkeypatch.setattr(ft, "LAZY_WET_MATRICES", lazy)
    table = fill_table(container, liquid)
    return table.filled(container, liquid, fraction * container.volume_m3, compressible=compressible)


def modal_quantities(wet, points):
    return {
        "frequencies": wet.frequencies_hz, "coefficients": wet.modal_coefficients,
        "decay": wet.decay_rates_per_s, "rigid": wet.rigid_coefficients,
        "shapes": wet.mode_shapes_at(points), "rigid_shapes": wet.rigid_mode_shapes_at(points),
        "liquid_modes": wet.liquid_modes_hz, "stiffer": wet.with_material(scaled_material(wet.material, modulus_scale=1.3, density_scale=0.9)).frequencies_hz,
    }


@pytest.mark.parametrize("liquid", ["water", "honey"])
@pytest.mark.parametrize("compressible", [True, False])
def test_a_lazy_fill_is_the_fill_made_at_once(small_can, liquid, compressible, monkeypatch):
    liquid = get_liquid(liquid)
    points = small_can.dry.nodes_m[::997][:6]
    for fraction in (0.13, 0.5, 0.87):
        lazy = fill(small_can, liquid, fraction, compressible, True, monkeypatch)
        eager = fill(small_can, liquid, fraction, compressible, False, monkeypatch)
        # the body at once, nothing of the wall's matrices yet
        assert "_wall" not in lazy.__dict__ and "_wall" in eager.__dict__
        for field in ("volume_m3", "mass_kg", "centre_of_mass_m", "inertia_kg_m2", "surface_normal",
                      "surface_offset_m"):
            assert np.array_equal(getattr(lazy.liquid, field), getattr(eager.liquid, field)), field
        assert lazy.metadata == eager.metadata
        copied = pickle.loads(pickle.dumps(lazy))        # the pending build travels (a process pool)
        got, want = modal_quantities(lazy, points), modal_quantities(eager, points)
        assert "_wall" in lazy.__dict__
        assert np.array_equal(modal_quantities(copied, points)["frequencies"], want["frequencies"])
        for name in want:
            assert got[name].shape == want[name].shape and np.array_equal(got[name], want[name]), name
        assert lazy.n_liquid_modes == eager.n_liquid_modes and lazy.n_modes == eager.n_modes


def test_a_lazy_fill_refuses_unknown_attributes(small_can, monkeypatch):
    lazy = fill(small_can, get_liquid("water"), 0.4, True, True, monkeypatch)
    with pytest.raises(AttributeError):
        lazy.nodes_m                                # noqa: B018 (a model without mesh: no nodes)
    assert "_wall" not in lazy.__dict__            # an unknown attribute does not build


def test_a_material_view_of_a_lazy_fill_stays_lazy_and_shares_its_build(small_can, monkeypatch):
    lazy = fill(small_can, get_liquid("water"), 0.4, True, True, monkeypatch)
    built, build = [], lazy._build
    lazy._build = lambda: built.append(1) or build()
    view = lazy.with_material(scaled_material(lazy.material, modulus_scale=1.3, density_scale=0.9))
    assert "_wall" not in view.__dict__ and "_wall" not in lazy.__dict__     # nothing read yet
    view.frequencies_hz, lazy.frequencies_hz                                 # noqa: B018
    assert built == [1]                                                      # one build for both


def episodes(enabled: bool, lazy: bool, monkeypatch, seeds=(0, 1, 2)):
    monkeypatch.setattr(ft, "LAZY_WET_MATRICES", lazy)
    clear_all()      # the container's fills are memoized: each side makes its own
    env = gym.make("aas_gym/FillLevel-v0", disable_env_checker=True, acoustic={"enabled": enabled}).unwrapped
    try:
        return [env.reset(seed=s) for s in seeds]
    finally:
        env.close()


def same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    return a == b


@pytest.mark.parametrize("enabled", [True, False])
def test_fill_level_episodes_are_the_same_bits(enabled, monkeypatch):
    fast, ref = episodes(enabled, True, monkeypatch), episodes(enabled, False, monkeypatch)
    for (obs, info), (obs_ref, info_ref) in zip(fast, ref):
        assert same(obs, obs_ref)
        assert same(info, info_ref)
    if enabled:
        assert np.any(fast[0][0]["acoustic"] != 0)


@pytest.mark.parametrize("compressible", [True, False])
def test_a_lazy_exact_fill_is_the_exact_fill_made_at_once(small_can, compressible, monkeypatch):
    """The exact solve (``sensors.fluid.filling.LAZY_EXACT_MATRICES``): the bottle's neck takes it."""
    from sensors.fluid import filled, filling

    points = small_can.dry.nodes_m[::997][:6]
    models = {}
    for lazy in (True, False):
        monkeypatch.setattr(filling, "LAZY_EXACT_MATRICES", lazy)
        small_can.fills.clear()                     # each side solves its own
        models[lazy] = filled(small_can, 0.45, liquid="honey", compressible=compressible, interpolated=False)
    lazy, eager = models[True], models[False]
    assert "_wall" not in lazy.__dict__ and "_wall" in eager.__dict__
    for field in ("volume_m3", "mass_kg", "centre_of_mass_m", "inertia_kg_m2", "surface_normal", "surface_offset_m"):
        assert np.array_equal(getattr(lazy.liquid, field), getattr(eager.liquid, field)), field
    got, want = modal_quantities(lazy, points), modal_quantities(eager, points)
    for name in want:
        assert got[name].shape == want[name].shape and np.array_equal(got[name], want[name]), name


def test_exact_fills_sharing_a_liquid_meshs_potential_flow_are_the_fills_solved_alone(small_can):
    """``sensors.fluid.filling.LIQUID_FLOWS``: the exact fills of one liquid mesh (other liquids,
    both liquid models) share its potential flow; each is the same bits as the fill solved with
    nothing kept (the reference), at two fills one after the other."""
    import math

    from sensors.fluid import filled, filling
    from sensors.materials.liquids import Liquid

    water = get_liquid("water")
    stiffer = Liquid("water, c x2", water.density_kg_m3, water.viscosity_pa_s, 2 * water.speed_of_sound_m_per_s)
    cases = [(liquid, compressible) for liquid in (water, get_liquid("honey"), stiffer) for compressible in (True, False)]

    def solve(fraction, liquid, compressible):
        small_can.fills.clear()
        wet = filled(small_can, fraction, liquid=liquid, compressible=compressible)
        return {"frequencies": wet.frequencies_hz, "coefficients": wet.modal_coefficients,
                "decay": wet.decay_rates_per_s, "liquid_modes": wet.liquid_modes_hz, "mass": wet.liquid.mass_kg}

    filling.LIQUID_FLOWS.clear()
    for fraction in (0.3, 0.6):
        hits = filling.LIQUID_FLOWS.hits
        shared = [solve(fraction, *case) for case in cases]
        assert filling.LIQUID_FLOWS.hits - hits == len(cases) - 1   # one solve of the flow per fill
        for case, got in zip(cases, shared):
            filling.LIQUID_FLOWS.clear()
            want = solve(fraction, *case)
            for name in want:
                assert np.array_equal(got[name], want[name]), (fraction, case, name)
        assert not math.isclose(shared[0]["frequencies"][0], shared[2]["frequencies"][0])  # the liquids differ
