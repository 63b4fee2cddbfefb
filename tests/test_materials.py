"""Material table and validation."""

import math

import pytest

from sensors import MATERIALS, Material, get_material


def test_paper_table_values():
    assert MATERIALS["abs"] == Material("abs", 1100, 2.6e9, 0.36, 4, 3e-7, 4e-2)
    assert MATERIALS["aluminium"] == Material("aluminium", 2700, 6.9e10, 0.33, 0, 5e-7, 2e-1)
    assert MATERIALS["steel"] == Material("steel", 7850, 2e11, 0.29, 5, 3e-8, 3e-1)
    assert MATERIALS["wood"] == Material("wood", 750, 1.1e10, 0.25, 60, 4e-6, 5e-2)


def test_extra_materials_present_and_sensible():
    for name in ("pla", "glass", "ceramic"):
        m = MATERIALS[name]
        assert 500 < m.density_kg_m3 < 5000 and 1e9 < m.youngs_modulus_pa < 5e11
        # Loss factor at 5 kHz between 1e-4 and 5e-2 (plastics ~1e-2, glass ~1e-3).
        w = 2 * math.pi * 5000
        eta = 2 * m.decay_rate(w) / w
        assert 1e-4 < eta < 5e-2


def test_keys_are_lower_case_names():
    for key, m in MATERIALS.items():
        assert key == key.lower() == m.name


def test_get_material_aliases_and_errors():
    assert get_material("Aluminum") is MATERIALS["aluminium"]
    assert get_material("STEEL") is MATERIALS["steel"]
    m = Material("custom", 1000, 1e9, 0.3)
    assert get_material(m) is m
    with pytest.raises(KeyError, match="known materials: .*abs.*steel"):
        get_material("unobtainium")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(density_kg_m3=0), "density"),
        (dict(density_kg_m3=-1), "density"),
        (dict(youngs_modulus_pa=0), "youngs_modulus"),
        (dict(poisson_ratio=0.5), "poisson"),
        (dict(poisson_ratio=-1.0), "poisson"),
        (dict(alpha=-1e-3), "alpha"),
        (dict(beta=-1e-9), "beta"),
        (dict(gamma=-1), "gamma"),
        (dict(youngs_modulus_pa=float("nan")), "finite"),
        (dict(density_kg_m3="heavy"), "number"),
    ],
)
def test_invalid_materials_rejected(kwargs, message):
    base = dict(name="x", density_kg_m3=1000.0, youngs_modulus_pa=1e9, poisson_ratio=0.3)
    with pytest.raises(ValueError, match=message):
        Material(**{**base, **kwargs})


def test_derived_quantities_and_round_trip():
    m = MATERIALS["steel"]
    assert m.shear_modulus_pa == pytest.approx(2e11 / 2.58)
    assert m.decay_rate(1000.0) == pytest.approx(0.5 * (5 + 3e-8 * 1e6))
    assert Material.from_dict(m.to_dict()) == m
