"""Stage 2, materials: isotropic solids (with the paper's damping) and liquids."""

from .liquids import LIQUIDS, Liquid, get_liquid
from .scaling import scaled_material
from .solids import MATERIALS, Material, get_material

__all__ = ["LIQUIDS", "Liquid", "get_liquid", "MATERIALS", "Material", "get_material", "scaled_material"]
