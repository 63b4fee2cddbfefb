"""A material made from another by scaling its properties (domain randomization of the sensor).

This makes a :class:`~sensors.Material`; seeing a modal model in it is
:func:`sensors.with_material`.
"""

from __future__ import annotations

import dataclasses
import math

from .solids import Material

__all__ = ["scaled_material"]


def scaled_material(material: Material, *, damping_scale: float = 1.0, modulus_scale: float = 1.0,
                    density_scale: float = 1.0) -> Material:
    """A new :class:`~sensors.Material`: ``material`` with its damping (alpha, beta, gamma),
    Young's modulus and density multiplied by the scales; every scale must be > 0."""
    for name, v in (("damping_scale", damping_scale), ("modulus_scale", modulus_scale),
                    ("density_scale", density_scale)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be > 0, got {v!r}")
    m = material
    return dataclasses.replace(
        m, alpha=m.alpha * damping_scale, beta=m.beta * damping_scale, gamma=m.gamma * damping_scale,
        youngs_modulus_pa=m.youngs_modulus_pa * modulus_scale, density_kg_m3=m.density_kg_m3 * density_scale)
