"""A contact load between the grasped object and a body it is coupled to acts on both.

Newton's third law in the coupled basis of :mod:`sensors.modal.touching`: the force F a
touching partner exerts on the grasped object at a contact point x (grasped object's frame)
is matched by -F on the partner at the same point.  In the assembly's mass-normalised modes
the modal load is then

    p = U_0(x)^T F + U_b(x_b)^T (R_b^T (-F)) = (U_0(x) - R_b U_b(x_b))^T F,

x_b = R_b^T (x - t_b) the point in the partner's frame (R_b, t_b its pose in the grasped
object's frame) and U_0, U_b the coupled shapes of the two bodies.  A load on the grasped
object alone would push the pair's common (rigid, suspension) motion as well as the
contact's squeeze, which a contact force, internal to the pair, cannot do.  Loads from
bodies not in the coupled system (the table, the hand) act on the grasped object alone.
"""

from __future__ import annotations

import numpy as np

from ..modal.touching import CoupledGraspModes

__all__ = ["load_shapes"]


def load_shapes(modes, loads) -> np.ndarray:
    """(n, 3, r): per load point the shapes its force acts through, in the grasped object's
    frame, so that the modal load is sum_c shapes[c]^T F_c: ``modes.mode_shapes_at`` of the
    points, minus the partner's shapes (rotated into the grasped frame) where the load comes
    from a partner of a coupled grasp (``loads.bodies`` naming ``TouchingPartner.name``)."""
    U = np.array(modes.mode_shapes_at(loads.positions_m), dtype=float)
    if not isinstance(modes, CoupledGraspModes) or len(loads) == 0:
        return U
    for body, partner in enumerate(modes.group.partners, start=1):     # body 0: the grasped object
        if partner.name is None:
            continue
        rows = np.flatnonzero(loads.bodies == partner.name)
        if rows.size == 0:
            continue
        R, t = partner.rotation, partner.translation_m
        in_partner = (loads.positions_m[rows] - t) @ R                  # R^T (x - t), row-wise
        U[rows] -= np.einsum("ij,kjr->kir", R, modes.assembly.mode_shapes_at(body, in_partner))
    return U
