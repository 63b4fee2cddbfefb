"""Self-intersections of a triangle surface: pairs of faces that cross each other."""

from __future__ import annotations

import logging

import numpy as np

__all__ = ["count_self_intersections"]

log = logging.getLogger(__name__)


def _segment_triangle_hits(p0, p1, a, b, c, eps=1e-12):
    """Vectorized test: does segment p0-p1 cross the interior of triangle abc (Moller-Trumbore)."""
    d = p1 - p0
    e1, e2 = b - a, c - a
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    scale = np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(d, axis=1)
    ok = np.abs(det) > eps * scale
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = p0 - a
    u = np.einsum("ij,ij->i", s, pv) * inv
    q = np.cross(s, e1)
    w = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    tol = 1e-9
    return ok & (u > tol) & (w > tol) & (u + w < 1 - tol) & (t > tol) & (t < 1 - tol)


def count_self_intersections(vertices: np.ndarray, faces: np.ndarray, max_pairs: int = 5_000_000) -> int:
    """Count pairs of non-adjacent triangles whose edges cross each other (0 if clean).

    Candidate pairs come from a k-d tree of face centres; beyond ``max_pairs`` candidates the
    check is skipped with a warning and 0 returned.
    """
    from scipy.spatial import cKDTree

    tri = vertices[faces]
    centre = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centre[:, None], axis=2).max(axis=1)
    tree = cKDTree(centre)
    pairs = tree.query_pairs(2.0 * radius.max() + 1e-12, output_type="ndarray")
    if len(pairs) > max_pairs:
        log.warning("self-intersection check skipped: %d candidate triangle pairs", len(pairs))
        return 0
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(centre[i] - centre[j], axis=1) <= radius[i] + radius[j]
    i, j = i[near], j[near]
    shared = (faces[i][:, :, None] == faces[j][:, None, :]).any(axis=(1, 2))
    i, j = i[~shared], j[~shared]
    hit = np.zeros(len(i), dtype=bool)
    for (x, y) in ((i, j), (j, i)):
        for k0, k1 in ((0, 1), (1, 2), (2, 0)):
            hit |= _segment_triangle_hits(vertices[faces[x, k0]], vertices[faces[x, k1]],
                                          vertices[faces[y, 0]], vertices[faces[y, 1]], vertices[faces[y, 2]])
    return int(hit.sum())
