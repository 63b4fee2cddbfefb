"""Isotropic linear-elastic materials with Rayleigh and contact damping.

The first four entries of :data:`MATERIALS` are the paper's Table I (ABS, aluminium, steel,
wood). PLA, glass and ceramic are added with handbook elastic constants and damping chosen to
match their typical loss factors (eta ~ beta * omega + alpha / omega in the 3-10 kHz band):
plastics ~1e-2, glass and porcelain ~1e-3.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["Material", "MATERIALS", "get_material"]


@dataclasses.dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material.

    Attributes:
        name: Human-readable name (the key in :data:`MATERIALS` for built-in ones).
        density_kg_m3: Mass density [kg/m^3], > 0.
        youngs_modulus_pa: Young's modulus [Pa], > 0.
        poisson_ratio: Poisson's ratio, -1 < nu < 0.5 (0.5 would be incompressible and makes
            the stiffness matrix singular).
        alpha: Rayleigh mass-proportional damping [1/s] (C = alpha M + beta K), >= 0.
        beta: Rayleigh stiffness-proportional damping [s], >= 0.
        gamma: Scale of the viscous contact damping [s/m] (Zheng & James 2011), >= 0.
    """

    name: str
    density_kg_m3: float
    youngs_modulus_pa: float
    poisson_ratio: float
    alpha: float = 0.0
    beta: float = 0.0
    gamma: float = 0.0

    def __post_init__(self) -> None:
        for field in ("density_kg_m3", "youngs_modulus_pa", "poisson_ratio", "alpha", "beta", "gamma"):
            value = getattr(self, field)
            # float(True) is 1.0 and float("7800") 7800: a typo must not become 1 Pa, nor a string pass
            if isinstance(value, (bool, np.bool_, str, bytes)):
                raise ValueError(f"Material {self.name!r}: {field} must be a number, got {value!r}")
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"Material {self.name!r}: {field} must be a number, got {value!r}") from None
            if not math.isfinite(value):
                raise ValueError(f"Material {self.name!r}: {field} must be finite, got {value!r}")
            object.__setattr__(self, field, value)
        if self.density_kg_m3 <= 0:
            raise ValueError(f"Material {self.name!r}: density_kg_m3 must be > 0, got {self.density_kg_m3}")
        if self.youngs_modulus_pa <= 0:
            raise ValueError(f"Material {self.name!r}: youngs_modulus_pa must be > 0, got {self.youngs_modulus_pa}")
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ValueError(
                f"Material {self.name!r}: poisson_ratio must satisfy -1 < nu < 0.5, got {self.poisson_ratio}"
            )
        for field in ("alpha", "beta", "gamma"):
            if getattr(self, field) < 0:
                raise ValueError(f"Material {self.name!r}: damping {field} must be >= 0, got {getattr(self, field)}")

    @property
    def shear_modulus_pa(self) -> float:
        """Shear modulus G = E / (2 (1 + nu)) [Pa]."""
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def lame_lambda_pa(self) -> float:
        """First Lame parameter [Pa]."""
        e, nu = self.youngs_modulus_pa, self.poisson_ratio
        return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    @property
    def bar_wave_speed_m_s(self) -> float:
        """Longitudinal wave speed in a thin bar, sqrt(E / rho) [m/s]."""
        return math.sqrt(self.youngs_modulus_pa / self.density_kg_m3)

    def decay_rate(self, angular_frequency_rad_s):
        """Modal decay rate (alpha + beta w^2) / 2 [1/s] of Rayleigh damping at w [rad/s]."""
        return 0.5 * (self.alpha + self.beta * angular_frequency_rad_s**2)

    def to_dict(self) -> dict:
        """Plain-dict form (JSON-friendly); inverse of :meth:`from_dict`."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Material":
        """Rebuild a material from :meth:`to_dict` output."""
        return cls(**{f.name: data[f.name] for f in dataclasses.fields(cls)})


MATERIALS: dict[str, Material] = {
    # Paper, Table I.
    "abs": Material("abs", 1100.0, 2.6e9, 0.36, alpha=4.0, beta=3e-7, gamma=4e-2),
    "aluminium": Material("aluminium", 2700.0, 6.9e10, 0.33, alpha=0.0, beta=5e-7, gamma=2e-1),
    "steel": Material("steel", 7850.0, 2.0e11, 0.29, alpha=5.0, beta=3e-8, gamma=3e-1),
    "wood": Material("wood", 750.0, 1.1e10, 0.25, alpha=60.0, beta=4e-6, gamma=5e-2),
    # Additions. PLA: printed-part values (E 3.5 GPa, loss factor ~1-2%), damping like ABS.
    "pla": Material("pla", 1240.0, 3.5e9, 0.36, alpha=5.0, beta=4e-7, gamma=4e-2),
    # Soda-lime glass: very low loss (eta ~ 1e-3). Elastic constants: Callister & Rethwisch,
    # Materials Science and Engineering, App. B (soda-lime glass: 2.5 g/cm3, 69 GPa, nu 0.23);
    # 72 GPa is the value glass makers quote for container glass.
    "glass": Material("glass", 2500.0, 7.2e10, 0.23, alpha=1.0, beta=3e-8, gamma=1e-1),
    # Porcelain (household ceramic): eta ~ 1e-3 like glass, stiffer and a little lighter.
    # Elastic constants: the range for porcelain in Ashby's property charts (Materials Selection
    # in Mechanical Design): E 70-110 GPa, nu ~0.2, 2.3-2.5 g/cm3.
    "ceramic": Material("ceramic", 2400.0, 1.0e11, 0.22, alpha=1.0, beta=3e-8, gamma=1e-1),
}

_ALIASES = {"aluminum": "aluminium", "al": "aluminium", "ceramics": "ceramic", "porcelain": "ceramic"}


def get_material(name: "str | Material") -> Material:
    """Return a built-in material by (case-insensitive) name; a Material is passed through.

    Accepts the aliases ``aluminum`` and ``porcelain``. Raises ``KeyError`` listing the known
    names otherwise.
    """
    if isinstance(name, Material):
        return name
    if not isinstance(name, str):
        raise TypeError(f"a material is a name (a string) or a sensors.Material, got {name!r} ({type(name).__name__})")
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    try:
        return MATERIALS[key]
    except KeyError:
        known = ", ".join(sorted(MATERIALS)) + " (aliases: " + ", ".join(sorted(_ALIASES)) + ")"
        raise KeyError(f"unknown material {name!r}; known materials: {known}") from None
