"""The closest-surface query's batched settling of uncertain points (``sensors.mesh.locator.
VECTORIZED_UNSURE``) against the per-point reference and against every face."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from sensors.mesh import locator as locator_mod
from sensors.mesh.locator import TetLocator, closest_points_on_triangles


def plate_mesh(nx=30, ny=24, nz=2, size=(0.12, 0.09, 0.004), seed=0):
    """A thin plate of Kuhn tets (six per cell) with jittered interior-plane nodes: long, thin
    and uneven faces, where the 16 nearest centroids often cannot decide."""
    rng = np.random.default_rng(seed)
    axes = [np.linspace(0.0, s, n + 1) for s, n in zip(size, (nx, ny, nz))]
    nodes = np.array(list(itertools.product(*axes)))
    inner_xy = ((nodes[:, 0] > 0) & (nodes[:, 0] < size[0]) & (nodes[:, 1] > 0) & (nodes[:, 1] < size[1]))
    nodes[inner_xy, :2] += rng.uniform(-0.3, 0.3, (inner_xy.sum(), 2)) * np.array(size[:2]) / (nx, ny)

    def idx(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    kuhn = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]
    tets = []
    for i, j, k in itertools.product(range(nx), range(ny), range(nz)):
        corner = [idx(i + a, j + b, k + c) for a, b, c in itertools.product((0, 1), repeat=3)]
        for t in kuhn:
            tet = [corner[v] for v in t]
            a, b, c, d = nodes[tet]
            if np.dot(np.cross(b - a, c - a), d - a) < 0:
                tet[2], tet[3] = tet[3], tet[2]
            tets.append(tet)
    return nodes, np.array(tets)


@pytest.fixture(scope="module")
def plate():
    return plate_mesh()


def query_points(tri, n=150, seed=1):
    rng = np.random.default_rng(seed)
    faces = rng.integers(len(tri), size=n)
    on = np.einsum("pk,pki->pi", rng.dirichlet(np.ones(3), size=n), tri[faces])
    return np.concatenate([on, on + rng.normal(scale=2e-3, size=on.shape), on + rng.normal(scale=2e-2, size=on.shape),
                           on[:10]])      # repeated points: ties settle alike


def test_batched_equals_the_per_point_reference_bit_for_bit(plate, monkeypatch):
    nodes, tets = plate
    tri = TetLocator(nodes, tets).surface_data()["tri"]
    points = query_points(tri)
    answers = {}
    for batched in (True, False):
        monkeypatch.setattr(locator_mod, "VECTORIZED_UNSURE", batched)
        answers[batched] = TetLocator(nodes, tets).closest_surface(points)   # fresh: nothing remembered
    s = TetLocator(nodes, tets).surface_data()
    dc, _ = s["tree"].query(points, k=16)
    assert np.sum(dc[:, -1] - s["radius"] < answers[False][2]) > 50     # the batched branch ran on many points
    for fast, ref in zip(answers[True], answers[False]):
        np.testing.assert_array_equal(fast, ref)


def test_batched_is_the_nearest_face_of_all(plate):
    nodes, tets = plate
    loc = TetLocator(nodes, tets)
    tri = loc.surface_data()["tri"]
    points = query_points(tri, n=60, seed=2)
    closest, face, dist = loc.closest_surface(points)
    for i, p in enumerate(points):
        q = closest_points_on_triangles(np.repeat(p[None], len(tri), axis=0), tri[:, 0], tri[:, 1], tri[:, 2])
        d = np.linalg.norm(q - p, axis=1)
        assert dist[i] == d.min()
        assert d[face[i]] == d.min()
        np.testing.assert_allclose(np.linalg.norm(closest[i] - p), d.min(), rtol=1e-12, atol=1e-15)


def test_answers_kept_per_point_equal_fresh_batches(plate, monkeypatch):
    """Batches that repeat points of earlier ones (in another order, with new points beside them)
    answered from the per-point store (``SURFACE_POINTS_KEPT``) against each batch computed
    afresh by a new locator: the same bits."""
    nodes, tets = plate
    tri = TetLocator(nodes, tets).surface_data()["tri"]
    points = query_points(tri, n=40, seed=4)
    rng = np.random.default_rng(5)
    kept = TetLocator(nodes, tets)
    batches = [points[:50], points[rng.permutation(len(points))[:70]], np.concatenate([points[10:20], points[-5:]]),
               points[[3]]]
    for batch in batches:
        monkeypatch.setattr(locator_mod, "SURFACE_POINTS_KEPT", True)
        fast = kept.closest_surface(batch)
        monkeypatch.setattr(locator_mod, "SURFACE_POINTS_KEPT", False)
        fresh = TetLocator(nodes, tets).closest_surface(batch)
        for a, b in zip(fast, fresh):
            assert a.dtype == b.dtype and a.shape == b.shape
            np.testing.assert_array_equal(a, b)
    assert kept._surface_points.hits > 50          # the later batches were answered from kept points
