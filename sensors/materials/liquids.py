"""Liquids for filled containers: density, dynamic viscosity and speed of sound at 20 C, with sources.

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

Speed of sound at 20 C:
    water: Del Grosso & Mader, "Speed of sound in pure water", J. Acoust. Soc. Am. 52 (1972)
        1442: 1482.3 m/s.
    ethanol: CRC Handbook of Chemistry and Physics, "Speed of sound in liquids" (about 1143 m/s
        at 25 C, falling by about 3.5 m/s per K): about 1160 m/s at 20 C.
    oil (olive oil): McClements & Povey, "Ultrasonic velocity measurements in some liquid
        triglycerides and vegetable oils", J. Am. Oil Chem. Soc. 65 (1988) 1787: vegetable oils
        1440-1470 m/s near 20 C; 1450 m/s taken.
    honey: about 2000 m/s, an estimate (not a measurement of honey) from concentrated sugar
        solutions of honey's 80 % solids, uncertain by about 5 %.
    A liquid given only by its density takes water's speed of sound.

The density enters the added mass, the speed of sound the compressible liquid's acoustic modes,
the viscosity the boundary-layer damping (see :mod:`sensors.fluid.filled_model`).
"""

from __future__ import annotations

import dataclasses
import math
import numbers

__all__ = ["Liquid", "LIQUIDS", "get_liquid", "WATER_SPEED_OF_SOUND_M_PER_S"]

#: Water's speed of sound at 20 C [m/s] (Del Grosso & Mader 1972).
WATER_SPEED_OF_SOUND_M_PER_S = 1482.3


@dataclasses.dataclass(frozen=True)
class Liquid:
    """A Newtonian liquid: density [kg/m^3], dynamic viscosity [Pa s] and speed of sound [m/s]
    (default water's; ``math.inf`` makes it incompressible)."""

    name: str
    density_kg_m3: float
    viscosity_pa_s: float = 0.0
    speed_of_sound_m_per_s: float = WATER_SPEED_OF_SOUND_M_PER_S

    def __post_init__(self):
        for field in ("density_kg_m3", "viscosity_pa_s", "speed_of_sound_m_per_s"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise TypeError(f"Liquid {self.name!r}: {field} must be a number, got {value!r} "
                                f"({type(value).__name__})")
            value = float(value)
            bad = (math.isnan(value) or value < 0 or (field != "speed_of_sound_m_per_s" and not math.isfinite(value))
                   or (field != "viscosity_pa_s" and value == 0))
            if bad:
                raise ValueError(f"Liquid {self.name!r}: {field} must be positive (and finite, except a speed of "
                                 f"sound), got {value!r}")
            object.__setattr__(self, field, value)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


LIQUIDS: dict[str, Liquid] = {
    "water": Liquid("water", 998.2, 1.002e-3, 1482.3),
    "ethanol": Liquid("ethanol", 789.3, 1.074e-3, 1160.0),
    "oil": Liquid("oil", 912.0, 8.0e-2, 1450.0),
    "honey": Liquid("honey", 1420.0, 10.0, 2000.0),
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
