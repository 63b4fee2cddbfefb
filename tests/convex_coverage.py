"""How well convex pieces cover a solid, for the collision tests: the fraction of sample points
inside the solid that some piece's hull contains, and the pieces' summed hull volume [m^3]."""

import numpy as np
from scipy.spatial import ConvexHull


def coverage(pieces, inside_points) -> tuple[float, float]:
    """(fraction of ``inside_points`` in at least one piece's hull, summed hull volume)."""
    covered = np.zeros(len(inside_points), bool)
    volume = 0.0
    for piece in pieces:
        hull = ConvexHull(piece)
        volume += hull.volume
        covered |= np.all(inside_points @ hull.equations[:, :3].T + hull.equations[:, 3] <= 1e-9, axis=1)
    return float(covered.mean()), volume
