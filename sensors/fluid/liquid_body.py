"""The liquid in a container as a rigid body: what a physics engine should carry."""

from __future__ import annotations

import dataclasses

import numpy as np

from .cavity import AxisymmetricCavity, LiquidMesh, p2_mass_properties
from ..materials.liquids import Liquid

__all__ = ["LiquidBody"]


@dataclasses.dataclass(frozen=True)
class LiquidBody:
    """The liquid in a container, as a rigid body for a physics engine (object frame, SI).

    Attributes:
        liquid: What it is.
        volume_m3: Its volume.
        mass_kg: Its mass.
        centre_of_mass_m: (3,) centre of mass in the object frame (the cavity's floor centre
            when empty).
        inertia_kg_m2: (3, 3) inertia tensor about the centre of mass, object axes, of the
            liquid frozen in its shape. A liquid does not spin with its container, so this is an
            upper bound of what it resists in rotation; its mass and centre are exact.
        surface_normal: (3,) unit normal of the free surface, against gravity (object frame).
        surface_offset_m: The free surface is the plane ``surface_normal . p = surface_offset_m``.
    """

    liquid: Liquid
    volume_m3: float
    mass_kg: float
    centre_of_mass_m: np.ndarray
    inertia_kg_m2: np.ndarray
    surface_normal: np.ndarray
    surface_offset_m: float

    def to_dict(self) -> dict:
        """Plain-JSON form."""
        return {"liquid": self.liquid.to_dict(), "volume_m3": self.volume_m3, "mass_kg": self.mass_kg,
                "centre_of_mass_m": np.asarray(self.centre_of_mass_m).tolist(),
                "inertia_kg_m2": np.asarray(self.inertia_kg_m2).tolist(),
                "surface_normal": np.asarray(self.surface_normal).tolist(),
                "surface_offset_m": self.surface_offset_m}

    @classmethod
    def in_cavity(cls, cavity, liquid: Liquid, volume_m3: float, surface_normal: np.ndarray,
                  mesh: LiquidMesh | None) -> "LiquidBody":
        """The body of ``volume_m3`` of ``liquid`` meshed as ``mesh`` (None when empty: a
        massless point on the cavity's floor) under the free surface of unit ``surface_normal``."""
        up, volume = surface_normal, volume_m3
        if mesh is None:
            floor = (cavity.origin_m if isinstance(cavity, AxisymmetricCavity)
                     else np.asarray(cavity.mesh.vertices).min(axis=0))
            return cls(liquid, 0.0, 0.0, np.array(floor, float), np.zeros((3, 3)), up, float(up @ floor))
        mass, centre, inertia = p2_mass_properties(mesh.nodes_m, mesh.tets, liquid.density_kg_m3)
        # The mesh's volume is within its discretization error of the one asked for: scale to it.
        scale = liquid.density_kg_m3 * volume / mass
        return cls(liquid, volume, liquid.density_kg_m3 * volume, centre, inertia * scale, up,
                   mesh.surface_offset_m)
