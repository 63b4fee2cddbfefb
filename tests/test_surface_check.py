"""The synthesis's surface check asks the model ``within_surface_distance_m`` (bounds settle most
points, ``sensors.modal.damping.ASK_WITHIN``) and computes a distance only for the error message:
the same decisions and errors, message included, as every point's full distance (the reference),
the distance in the message that of the nearest of all faces; every model that wraps another
answers through the model it wraps."""

from __future__ import annotations

import numpy as np
import pytest

from sensors.mesh import locator as locator_mod
from sensors.mesh.locator import TetLocator
from sensors.modal import MaterialView, damping
from sensors.modal.damping import MAX_SURFACE_DISTANCE_M, OffSurfaceError, check_groups_on_surface
from sensors.objects.catalog import get_object

LIMIT_M = MAX_SURFACE_DISTANCE_M


@pytest.fixture(scope="module")
def mug():
    return get_object("mug").modal_model()


def _nearest_face_distance_m(tri: np.ndarray, point: np.ndarray) -> float:
    """Distance from a point to the nearest of all triangles (m, 3, 3), independent of the locator:
    each triangle sampled on a barycentric grid of step 1/100, the nearest sample: an upper bound
    of the distance, above it by about e^2 / 2d for a sample spacing e."""
    t = np.linspace(0.0, 1.0, 101)
    u, v = np.meshgrid(t, t, indexing="ij")
    keep = u + v <= 1.0
    u, v = u[keep], v[keep]
    best = np.inf
    for a, b, c in tri:
        pts = a + u[:, None] * (b - a) + v[:, None] * (c - a)
        best = min(best, float(np.linalg.norm(pts - point, axis=1).min()))
    return best


def _groups(mug, rng):
    """Drive/mic points on the surface, then contacts: on it, 1 mm off it, then one 1e-10 m
    beyond the limit (the first too far), then one 5 mm off."""
    loc = TetLocator(mug.nodes_m, mug.elements)
    s = loc.surface_data()
    face = rng.integers(len(s["tri"]), size=6)
    on = s["tri"][face].mean(axis=1)
    off = lambda i, d: on[i] + d * s["normal"][face[i]]  # noqa: E731  (outward along the face normal)
    q, _, dq = loc.closest_surface(off(4, 2.5e-3)[None])
    limit_plus = q[0] + (off(4, 2.5e-3) - q[0]) * ((LIMIT_M + 1e-10) / dq[0])
    ends = np.array([on[0], on[1]])
    contacts = np.array([on[2], off(3, 1e-3), limit_plus, off(5, 5e-3)])
    return ends, contacts


def _error(model, groups):
    try:
        check_groups_on_surface(model, groups)
    except OffSurfaceError as e:
        return str(e)
    return None


@pytest.mark.parametrize("wrap", ["plain", "material view"])
def test_the_same_error_as_every_points_distance(mug, wrap, monkeypatch):
    model = mug if wrap == "plain" else MaterialView(mug, "porcelain")
    ends, contacts = _groups(mug, np.random.default_rng(3))
    cases = [[(ends, "drive/mic point"), (contacts[:2], "contact")],                 # no error
             [(ends, "drive/mic point"), (contacts, "contact")],                     # the 1e-10 m one
             [(contacts[3:], "drive/mic point"), (contacts, "contact")]]             # the first group's
    fast = [_error(model, g) for g in cases]
    monkeypatch.setattr(damping, "ASK_WITHIN", False)
    monkeypatch.setattr(locator_mod, "CENTROID_BOUNDS", False)
    reference = [_error(model, g) for g in cases]
    assert fast == reference
    assert fast[0] is None and fast[1].startswith("contact at") and fast[2].startswith("drive/mic point at")
    assert f"{contacts[2].tolist()} m is 2 mm" in fast[1]
    # the 5 mm point's distance against the nearest of all faces (within the sampling's 0.5 %)
    shown_mm = float(fast[2].split(" m is ")[1].split(" mm")[0])
    tri = mug.locator.surface_data()["tri"]
    near = np.linalg.norm(tri.mean(axis=1) - contacts[3], axis=1) < 0.01
    assert shown_mm == pytest.approx(_nearest_face_distance_m(tri[near], contacts[3]) * 1e3, rel=5e-3)


class _DistanceOnly:
    """A user model with distances only (no ``within_surface_distance_m``)."""

    def __init__(self, d):
        self.d = np.asarray(d, dtype=float)

    def surface_distance_m(self, points_m):
        return self.d[: len(np.atleast_2d(points_m))]


def test_wrappers_answer_through_the_model_they_wrap(mug):
    from sensors.fluid import filled

    points = _groups(mug, np.random.default_rng(4))[1]
    truth = mug.surface_distance_m(points) <= LIMIT_M
    assert list(truth) == [True, True, False, False]
    wet = filled("mug", 0.5, interpolated=True)
    for model in (mug, MaterialView(mug, "porcelain"), wet, MaterialView(wet.dry, "porcelain")):
        np.testing.assert_array_equal(model.within_surface_distance_m(points, LIMIT_M), truth)
    # a wrapped user model without the method: its distances decide (a NaN distance is not within)
    view = MaterialView.__new__(MaterialView)
    view.base = _DistanceOnly([1e-3, -1e-3, 3e-3, np.nan])
    np.testing.assert_array_equal(view.within_surface_distance_m(points, LIMIT_M), [True, True, False, False])
