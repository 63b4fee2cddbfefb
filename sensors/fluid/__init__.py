"""Stage 8, liquids in containers: the added mass of a liquid on the wetted wall, per fill and tilt."""

from .cavity import LiquidSpillError
from .model import Container, FilledModalModel, LiquidBody, container, filled

__all__ = ["LiquidSpillError", "Container", "FilledModalModel", "LiquidBody", "container", "filled"]
