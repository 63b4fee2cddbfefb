"""A small aluminium can (40 mm tall) with its dry modes to 20 kHz and its container, built into
the given cache folder (the run's, ``run_cache_dir`` in tests/conftest.py: the fluid files share
one build): the fluid tests' quick container."""

from sensors.fluid import Container
from sensors.objects.everyday import can

SMALL_CAN = dict(outer_radius_m=0.02, wall_m=0.002, height_m=0.04, floor_m=0.003, material="aluminium")


def small_can_container(cache_dir):
    """(the can's solid, its dry modal model, its ``Container``), cached in ``cache_dir``."""
    obj = can(**SMALL_CAN)
    dry = obj.modal_model(resolution=0.5, max_frequency_hz=20000.0, cache_dir=cache_dir, progress=False)
    return obj, dry, Container.of(obj, dry=dry, cache_dir=cache_dir)
