"""``aas_gym.touching_grasp.on_solid``: contacts of collision pieces where the solid is absent
are dropped, every contact on the solid is kept as it is (distances from the box's geometry)."""

import numpy as np

from aas_gym.touching_grasp import on_solid
from sensors.modal.contact import Contact
from sensors.modal.damping import MAX_SURFACE_DISTANCE_M
from synthesis_fakes import BoxModel


def test_only_contacts_beyond_the_surface_tolerance_are_dropped():
    model = BoxModel(np.linspace(900, 12000, 10), "abs")
    half_width_m = model.a / 2
    # below the -z face of the box (table contacts) at 0, 0.95, 1.05 and 3 times the tolerance
    offsets_m = [0.0, 0.95 * MAX_SURFACE_DISTANCE_M, 1.05 * MAX_SURFACE_DISTANCE_M, 3 * MAX_SURFACE_DISTANCE_M]
    contacts = [Contact([0.01 * i, 0.0, -half_width_m - off], [0, 0, 1], 5.0, 0.5) for i, off in enumerate(offsets_m)]
    kept = on_solid(model, contacts)
    assert kept == contacts[:2]
    assert all(k is c for k, c in zip(kept, contacts))       # kept unchanged
    assert on_solid(model, []) == []
    assert on_solid(object(), contacts) == contacts           # a model without a surface: nothing to judge
