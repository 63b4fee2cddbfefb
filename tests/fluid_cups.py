"""The cylindrical test cups shared by the fluid-loading tests and benchmark (one place for them)."""

from __future__ import annotations

from sensors.cavity import cup_cavity
from sensors.container_mesh import cup_mesh
from sensors.fluid import Container
from sensors.modal_model import ModalModel

#: Aluminium cup: 30 mm outer radius, 2 mm wall, 4 mm bottom, 80 mm tall (axis x, rim at +x).
CUP = dict(height_m=0.08, outer_radius_m=0.03, wall_thickness_m=0.002, bottom_thickness_m=0.004)
CUP_MATERIAL = "aluminium"
#: Axial element size of the wall: the partially wetted wall needs several elements per fill.
CUP_ELEMENT_HEIGHT_M = 0.006
#: Dry modes kept as the basis: up to 20 kHz, about 4 times the highest wet mode checked.
CUP_MAX_FREQUENCY_HZ = 20000.0


def cup_mesh_for_tests(extra_levels_m=()):
    return cup_mesh(**CUP, element_height_m=CUP_ELEMENT_HEIGHT_M, extra_levels_m=extra_levels_m)


def cup_dry_model(cache_dir, extra_levels_m=(), **options) -> ModalModel:
    """The cup's dry modal model (disk-cached in ``cache_dir``)."""
    options.setdefault("max_frequency_hz", CUP_MAX_FREQUENCY_HZ)
    return ModalModel.from_tet_mesh(cup_mesh_for_tests(extra_levels_m).wall, CUP_MATERIAL, cache_dir=cache_dir,
                                    progress=False, **options)


def cup_container(dry: ModalModel, **options) -> Container:
    return Container(dry, cup_cavity(**CUP), **options)
