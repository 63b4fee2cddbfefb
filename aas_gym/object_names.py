"""The paper's seven object names, without the scene builder (which imports MuJoCo): the
``aas`` CLI and ``aas_gym.experiments.config`` need only the names to list defaults."""

from __future__ import annotations

#: The paper's seven objects (200 mm long; bars 25 x 25 mm, tubes 25 mm OD / 19 mm ID), as
#: ``<material>_<shape>`` names (see ``aas_gym.scene.get_object``).
DEFAULT_OBJECT_NAMES = (
    "aluminium_bar",
    "aluminium_tube",
    "pla_bar",
    "pla_tube",
    "abs_bar",
    "steel_bar",
    "wood_bar",
)
