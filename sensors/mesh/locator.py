"""Where a point is in a tet mesh: its containing tet and barycentric coordinates, the closest
surface point, face and outward (faceted) normal. Spatial indexes are built on first use."""

from __future__ import annotations

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from .tets import boundary_faces

__all__ = ["TetLocator", "CENTROID_BOUNDS", "SURFACE_POINTS_KEPT", "VECTORIZED_UNSURE", "closest_points_on_triangles"]

#: Whether the points whose 16 nearest face centroids may miss the closest face are settled in
#: one batch (True, fast) or one at a time (False, the reference): the same faces, distances and
#: points bit for bit (``tests/test_locator_batch.py``).  Read at each query.
VECTORIZED_UNSURE = True
#: Whether closest-surface answers are also kept per point (True, fast: a batch computes only
#: the points no earlier batch asked) or per batch only (False, the reference): the same bits.
SURFACE_POINTS_KEPT = True
#: Whether :meth:`TetLocator.within_surface_distance` settles points by bounds from their
#: nearest surface points first (True, fast: no search beyond 16 faces) or asks
#: :meth:`TetLocator.closest_surface` for every point (False, the reference): the same
#: decisions (``tests/test_locator_bounds.py``).  Read at each query.
CENTROID_BOUNDS = True
#: A bound within this of the limit [m] does not settle its point (the full query does): far
#: above the round-off of distances between points of an object (1e-17 m on a 0.1 m mug).
_BOUND_MARGIN_M = 1e-9


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point to each p on triangle (a, b, c), all arrays (n, 3) (Ericson, RTCD 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c

    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4

    def div(x, y):
        return x / np.where(y == 0, 1.0, y)

    v_ab = div(d1, d1 - d3)[:, None]
    w_ac = div(d2, d2 - d6)[:, None]
    w_bc = div(d4 - d3, (d4 - d3) + (d5 - d6))[:, None]
    denom = va + vb + vc
    v_in, w_in = div(vb, denom)[:, None], div(vc, denom)[:, None]
    conditions = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
    ]
    choices = [a, b, a + v_ab * ab, c, a + w_ac * ac, b + w_bc * (c - b)]
    out = a + v_in * ab + w_in * ac
    for cond, choice in zip(reversed(conditions), reversed(choices)):
        out = np.where(cond[:, None], choice, out)
    return out


def _settle_unsure(s: dict, points, unsure, face, dist, closest) -> None:
    """For each point in ``unsure``: the closest of every face whose centroid lies within its
    current distance plus the face radius (written into ``face``, ``dist``, ``closest``).  All
    points' candidates in one batch; per point, the first of the nearest in ascending face order
    (the per-point loop's ``argmin`` choice among ties)."""
    radii = (dist[unsure] + s["radius"]) * (1 + 1e-9)
    lists = s["tree"].query_ball_point(points[unsure], radii)
    near = [np.sort(np.asarray(c, dtype=np.intp)) for c in lists]
    counts = np.array([len(c) for c in near])
    cand = np.concatenate(near)
    owner = np.repeat(np.arange(len(unsure)), counts)
    p = points[unsure][owner]
    q = closest_points_on_triangles(p, s["tri"][cand, 0], s["tri"][cand, 1], s["tri"][cand, 2])
    dd = np.linalg.norm(q - p, axis=1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    best = np.minimum.reduceat(dd, starts)
    # first candidate of each point at its minimum: positions are ascending within a point
    at_min = np.flatnonzero(dd == best[owner])
    first = at_min[np.concatenate([[True], owner[at_min][1:] != owner[at_min][:-1]])]
    face[unsure], dist[unsure], closest[unsure] = cand[first], dd[first], q[first]


class TetLocator:
    """Point queries on the linear corners of a tet mesh (``elements[:, :4]``)."""

    def __init__(self, nodes_m: np.ndarray, elements: np.ndarray) -> None:
        self.nodes_m = nodes_m
        self.elements = elements
        self._surface = None
        self._tet_tree = None
        self._sample_tree = None
        self._tinv = None
        # the same points are asked again and again (a contact set's points for its springs,
        # damping, mode shapes and loads): answers kept by the points' bytes, exact
        self._answers: LRU = LRU(CACHE_SIZES["mesh.point_locations"])
        self._surface_points: LRU = LRU(CACHE_SIZES["mesh.surface_points"])

    def surface_data(self):
        if self._surface is None:
            faces, owner = boundary_faces(self.elements[:, :4])
            tri = self.nodes_m[faces]
            centre = tri.mean(axis=1)
            normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            radius = float(np.linalg.norm(tri - centre[:, None], axis=2).max())
            from scipy.spatial import cKDTree  # ~0.05 s to import: only models that are queried pay

            self._surface = dict(faces=faces, owner=owner, tri=tri, normal=normal, radius=radius,
                                 tree=cKDTree(centre))
        return self._surface

    def closest_surface(self, points: np.ndarray):
        """Closest surface point, face index and distance for each point (read-only arrays,
        kept for the same points)."""
        if not SURFACE_POINTS_KEPT:
            return self._remembered("surface", points, self._closest_surface)
        return self._remembered("surface", points, self._closest_surface_by_point)

    def within_surface_distance(self, points: np.ndarray, limit_m: float) -> np.ndarray:
        """Whether each point (n, 3) [m] lies within ``limit_m`` of the surface, (n,) bool: the
        same as ``~(closest_surface(points)[2] > limit_m)``.

        Most points settle by bounds (with :data:`CENTROID_BOUNDS`), cheapest first: the
        nearest of points on the surface (face centroids, corners, edge midpoints) is at least
        as far as the surface (within); every face point lies within the largest face radius
        ``r`` of its centroid, so the surface is at least ``c - r`` away from a point whose
        nearest centroid is ``c`` away (beyond); the nearest of the faces with the 16 nearest
        centroids is at least as far as the nearest face (within).  Points whose bounds fall
        within ``_BOUND_MARGIN_M`` of the limit, or leave it between them, ask
        :meth:`closest_surface`."""
        points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
        if not CENTROID_BOUNDS or len(points) == 0:
            return ~(self.closest_surface(points)[2] > limit_m)
        within = self._surface_samples().query(points, k=1)[0] < limit_m - _BOUND_MARGIN_M
        rest = np.flatnonzero(~within)
        if len(rest):
            dc, _, _, dist = self._nearest_candidates(points[rest])
            within[rest] = dist.min(axis=1) < limit_m - _BOUND_MARGIN_M
            beyond = dc[:, 0] - self.surface_data()["radius"] > limit_m + _BOUND_MARGIN_M
            unsure = rest[~within[rest] & ~beyond]
            if len(unsure):
                within[unsure] = ~(self.closest_surface(points[unsure])[2] > limit_m)
        return within

    def _surface_samples(self):
        """A k-d tree of points on the surface: each face's centroid, corners and edge midpoints."""
        if self._sample_tree is None:
            from scipy.spatial import cKDTree

            tri = self.surface_data()["tri"]
            mids = [(tri[:, i] + tri[:, (i + 1) % 3]) / 2 for i in range(3)]
            self._sample_tree = cKDTree(np.concatenate([tri.mean(axis=1), np.unique(tri.reshape(-1, 3), axis=0), *mids]))
        return self._sample_tree

    def _closest_surface_by_point(self, points: np.ndarray):
        """``_closest_surface`` with each point's answer kept: a batch that repeats points of
        earlier batches (a contact read checked, then the same contacts with the fingertips)
        computes only its new points.  A point's answer does not depend on its batch."""
        keys = [p.tobytes() for p in points]
        known = [self._surface_points.get(k) for k in keys]
        new = [i for i, hit in enumerate(known) if hit is None]
        if new:
            closest, face, dist = self._closest_surface(points[new])
            for j, i in enumerate(new):
                known[i] = self._surface_points.put(keys[i], (closest[j].copy(), int(face[j]), float(dist[j])))
        closest = np.array([hit[0] for hit in known], dtype=float).reshape(len(points), 3)
        face = np.array([hit[1] for hit in known], dtype=np.intp)
        dist = np.array([hit[2] for hit in known], dtype=float)
        return closest, face, dist

    def _remembered(self, kind: str, points: np.ndarray, compute):
        points = np.ascontiguousarray(points, dtype=float)
        key = (kind, points.shape, points.tobytes())
        hit = self._answers.get(key)
        if hit is None:
            hit = tuple(compute(points))
            for a in hit:
                a.flags.writeable = False
            self._answers.put(key, hit)
        return hit

    def _nearest_candidates(self, points: np.ndarray):
        """The faces with the k = 16 nearest centroids of each point: centroid distances and
        faces (n, k), ascending; the closest point on each (n, k, 3) and its distance (n, k)."""
        s = self.surface_data()
        k = min(16, len(s["faces"]))
        dc, cand = s["tree"].query(points, k=k)
        dc, cand = dc.reshape(len(points), k), cand.reshape(len(points), k)
        tri = s["tri"][cand]  # (n, k, 3, 3)
        p = np.repeat(points, k, axis=0)
        q = closest_points_on_triangles(p, tri[:, :, 0].reshape(-1, 3), tri[:, :, 1].reshape(-1, 3),
                                        tri[:, :, 2].reshape(-1, 3)).reshape(len(points), k, 3)
        return dc, cand, q, np.linalg.norm(q - points[:, None], axis=2)

    def _closest_surface(self, points: np.ndarray):
        s = self.surface_data()
        n_faces = len(s["faces"])
        dc, cand, q, d = self._nearest_candidates(points)
        k = cand.shape[1]
        best = np.argmin(d, axis=1)
        rows = np.arange(len(points))
        face, dist, closest = cand[rows, best], d[rows, best], q[rows, best]
        # Exact: a face not among the k nearest centroids is farther than dc_k - radius.
        unsure = np.flatnonzero((k < n_faces) & (dc[:, -1] - s["radius"] < dist))
        if len(unsure) and VECTORIZED_UNSURE:
            _settle_unsure(s, points, unsure, face, dist, closest)
            return closest, face, dist
        for i in unsure:  # a point off the surface or uneven triangles: every face that can be closer
            # A face with a point within dist has its centroid within dist + radius (the margin
            # covers the tree's round-off); ascending order keeps argmin's choice among ties.
            near = np.sort(np.asarray(s["tree"].query_ball_point(points[i], (dist[i] + s["radius"]) * (1 + 1e-9)),
                                      dtype=np.intp))
            allq = closest_points_on_triangles(np.repeat(points[i:i + 1], len(near), axis=0),
                                               s["tri"][near, 0], s["tri"][near, 1], s["tri"][near, 2])
            dd = np.linalg.norm(allq - points[i], axis=1)
            j = int(np.argmin(dd))
            face[i], dist[i], closest[i] = near[j], dd[j], allq[j]
        return closest, face, dist

    def _barycentric(self, tet_idx: np.ndarray, points: np.ndarray) -> np.ndarray:
        if self._tinv is None:
            c = self.nodes_m[self.elements[:, :4]]
            self._tinv = np.linalg.inv(np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], c[:, 3] - c[:, 0]], axis=2))
        x0 = self.nodes_m[self.elements[tet_idx, 0]]
        lam = np.einsum("...ij,...j->...i", self._tinv[tet_idx], points - x0)
        return np.concatenate([1.0 - lam.sum(axis=-1, keepdims=True), lam], axis=-1)

    def locate(self, points: np.ndarray):
        """Containing tet and barycentric coordinates; outside points go to the nearest surface
        point (read-only arrays, kept for the same points)."""
        return self._remembered("locate", points, self._locate)

    def _locate(self, points: np.ndarray):
        if self._tet_tree is None:
            from scipy.spatial import cKDTree  # ~0.05 s to import: only models that are queried pay

            self._tet_tree = cKDTree(self.nodes_m[self.elements[:, :4]].mean(axis=1))
        k = min(16, len(self.elements))
        _, cand = self._tet_tree.query(points, k=k)
        cand = cand.reshape(len(points), k)
        bary = self._barycentric(cand, np.repeat(points[:, None], k, axis=1))  # (n, k, 4)
        score = bary.min(axis=2)
        best = np.argmax(score, axis=1)
        rows = np.arange(len(points))
        tet = cand[rows, best]
        bary = bary[rows, best]
        outside = score[rows, best] < -1e-9
        if np.any(outside):
            q, face, _ = self.closest_surface(points[outside])
            t = self.surface_data()["owner"][face]
            b = np.clip(self._barycentric(t, q), 0.0, None)
            tet[outside] = t
            bary[outside] = b / b.sum(axis=1, keepdims=True)
        return tet, bary
