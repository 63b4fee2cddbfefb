"""Liquids for filled containers: density and dynamic viscosity at 20 C, with sources.

Sources:
    water, ethanol: CRC Handbook of Chemistry and Physics, 97th ed. (2016), "Density of
        water" / "Viscosity of liquids" tables (water 998.2 kg/m^3, 1.002 mPa s; ethanol
        789.3 kg/m^3, 1.074 mPa s at 20 C).
    oil (olive oil): Sahasrabudhe et al., "Density, viscosity, and surface tension of five
        vegetable oils at elevated temperatures", Int. J. Food Properties 20 (2017) 1965,
        extrapolated to 20 C: ~912 kg/m^3, ~80 mPa s (CRC lists 84 mPa s for olive oil).
    honey: Yanniotis, Skaltsi & Karaburnioti, "Effect of moisture content on the viscosity of
        honey at different temperatures", J. Food Eng. 72 (2006) 372: ~1420 kg/m^3 and
        2-20 Pa s at 20 C depending on water content (17-18 % water: ~10 Pa s).

Only the density enters the added mass; the viscosity sets the boundary-layer damping
(see :mod:`sensors.fluid.filled_model`).
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["Liquid", "LIQUIDS", "get_liquid"]


@dataclasses.dataclass(frozen=True)
class Liquid:
    """An incompressible Newtonian liquid: density [kg/m^3] and dynamic viscosity [Pa s]."""

    name: str
    density_kg_m3: float
    viscosity_pa_s: float = 0.0

    def __post_init__(self):
        for field in ("density_kg_m3", "viscosity_pa_s"):
            value = float(getattr(self, field))
            if not math.isfinite(value) or value < 0 or (field == "density_kg_m3" and value == 0):
                raise ValueError(f"Liquid {self.name!r}: {field} must be finite and positive, got {value!r}")
            object.__setattr__(self, field, value)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


LIQUIDS: dict[str, Liquid] = {
    "water": Liquid("water", 998.2, 1.002e-3),
    "ethanol": Liquid("ethanol", 789.3, 1.074e-3),
    "oil": Liquid("oil", 912.0, 8.0e-2),
    "honey": Liquid("honey", 1420.0, 10.0),
}


#: The densest liquid a user density may name [kg/m^3] (mercury is 13,534).
MAX_LIQUID_DENSITY_KG_M3 = 25_000.0


def get_liquid(liquid: "str | Liquid | float") -> Liquid:
    """A built-in liquid by name, a :class:`Liquid`, or a user density [kg/m^3] (inviscid)."""
    if isinstance(liquid, Liquid):
        return liquid
    if isinstance(liquid, bool) or not isinstance(liquid, (str, int, float)):
        raise TypeError(f"a liquid is a name, a density in kg/m^3 or a Liquid, got {liquid!r} "
                        f"({type(liquid).__name__})")
    if isinstance(liquid, (int, float)):
        # Liquids range from about 600 kg/m^3 (light hydrocarbons) to 13,534 (mercury).
        if not math.isfinite(liquid) or not 0.0 < liquid <= MAX_LIQUID_DENSITY_KG_M3:
            raise ValueError(f"a liquid's density must be in (0, {MAX_LIQUID_DENSITY_KG_M3:g}] kg/m^3, got {liquid!r}")
        return Liquid(f"user {float(liquid):g} kg/m^3", float(liquid), 0.0)
    key = liquid.strip().lower()
    try:
        return LIQUIDS[key]
    except KeyError:
        raise KeyError(f"unknown liquid {liquid!r}; known: {', '.join(sorted(LIQUIDS))}, or pass a density "
                       "in kg/m^3 or a Liquid") from None
