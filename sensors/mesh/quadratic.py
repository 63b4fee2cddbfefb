"""10-node (P2) tetrahedra from a linear mesh, with mid-edge nodes on exact cylinders.

For the structured cylinders the mid-edge nodes of boundary edges are moved onto the exact
circle (isoparametric geometry), which removes the O(h^2) polygon error of the cross-section.
"""

from __future__ import annotations

import numpy as np

from .tets import P2_EDGES, TetMesh

__all__ = ["quadratic_mesh"]


def quadratic_mesh(mesh: TetMesh) -> tuple[np.ndarray, np.ndarray]:
    """10-node tets (VTK order: 4 corners, then mid-edge nodes of :data:`~sensors.mesh.tets.P2_EDGES`).

    Returns (nodes (n, 3), tets10 (m, 10)); the first ``len(mesh.vertices_m)`` nodes are the
    corner vertices. Mid-edge nodes of edges lying on one of ``mesh.cylinder_radii_m`` are
    projected radially onto that cylinder.
    """
    v, t = mesh.vertices_m, mesh.tets
    edges = np.sort(t[:, P2_EDGES].reshape(-1, 2), axis=1).astype(np.int64)
    # Unique edges by one integer key per vertex pair (the same lexicographic order as
    # np.unique(axis=0), which sorts rows as structured records: 5x slower).
    keys, inverse = np.unique(edges[:, 0] * len(v) + edges[:, 1], return_inverse=True)
    unique = np.stack(np.divmod(keys, len(v)), axis=1)
    mid = 0.5 * (v[unique[:, 0]] + v[unique[:, 1]])
    if mesh.cylinder_radii_m:
        r_v = np.hypot(v[:, 1], v[:, 2])
        for radius in mesh.cylinder_radii_m:
            on = np.abs(r_v - radius) <= 1e-9 * radius
            both = on[unique[:, 0]] & on[unique[:, 1]]
            r_mid = np.hypot(mid[both, 1], mid[both, 2])
            mid[both, 1:] *= (radius / r_mid)[:, None]
    nodes = np.concatenate([v, mid])
    tets10 = np.concatenate([t, len(v) + inverse.reshape(-1, 6)], axis=1)
    return nodes, tets10
