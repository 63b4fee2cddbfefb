"""Stage 8, liquids in containers: the added mass of a liquid on the wetted wall and (by default)
its own acoustic modes coupled to the wall (:mod:`.acoustic`), per fill and tilt.

``filled(obj, fill_fraction, liquid=...)`` is the entry point (:mod:`.filling`); a
:class:`Container` (:mod:`.container`) holds the per-container work, a
:class:`FilledModalModel` (:mod:`.filled_model`) the wet modes, a :class:`LiquidBody`
(:mod:`.liquid_body`) what a physics engine carries, a :class:`FillTable` (:mod:`.fill_table`)
an upright fill in milliseconds (``filled(..., interpolated=True)``).
"""

from .cavity import LiquidSpillError
from .container import Container
from .fill_table import FillTable, FillTableCostError  # (the module's fill_table() keeps the module name free)
from .filled_model import FilledModalModel
from .filling import container, filled
from .liquid_body import LiquidBody

__all__ = ["LiquidSpillError", "Container", "FilledModalModel", "FillTable", "FillTableCostError", "LiquidBody",
           "container", "filled"]
