"""Antipodal grasps on any closed surface (as Dex-Net samples them) and a grasp path.

:func:`sample_antipodal_grasps`: sample surface points, cast a ray along the inward normal to
the opposite surface, and keep pairs that a parallel-jaw hand can hold:

* both contact normals inside the friction cone of the grasp axis (half-angle atan(mu));
* width between ``min_width_m`` and the hand's opening (:data:`sensors.task.grasp.MAX_OPENING_M`);
* reachable from above: the grasp axis roughly horizontal (within ``max_tilt_rad`` of the
  plane normal to ``up``), nothing of the object above either contact (rays cast along
  +``up`` from just outside each contact hit nothing), room for each finger beside its
  contact (``finger_clearance_m`` free outward along the axis, on the pad's centre line and
  both edges: the finger link runs 12-26 mm behind the pad face) and below it for the pad's
  lower half (``pad_clearance_m``, just outside the contact), and the contacts within
  ``max_depth_m`` of the object's top (the hand's body stays above the object) and at least
  ``min_height_m`` above its bottom (the pads stay off the table).

Every surface point the inward ray leaves the solid at is a candidate second contact, not
only the first: across a hollow can both the wall (a pinch) and the far side (a grasp across
the whole can) are antipodal pairs.

Quality is the Dex-Net friction-cone margin: how far inside the cone the worse contact is
(1 = normals exactly along the axis, 0 = on the cone's edge).

:func:`grasp_path` gives a path along the object (its principal axis through the centroid,
clipped to where grasps exist), so the grasp-position task can measure positions along it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import trimesh

from sensors.task.grasp import MAX_OPENING_M

__all__ = ["AntipodalGrasp", "GraspPath", "sample_antipodal_grasps", "grasp_path"]


@dataclasses.dataclass(frozen=True)
class AntipodalGrasp:
    """A two-finger grasp in the object frame.

    Attributes:
        centre_m: (3,) midpoint between the contacts [m].
        axis: (3,) unit vector from the first contact to the second.
        width_m: distance between the contacts [m].
        quality: friction-cone margin in [0, 1].
    """

    centre_m: np.ndarray
    axis: np.ndarray
    width_m: float
    quality: float

    @property
    def contacts_m(self) -> tuple[np.ndarray, np.ndarray]:
        """The two contact points."""
        half = 0.5 * self.width_m * self.axis
        return self.centre_m - half, self.centre_m + half

    def to_dict(self) -> dict:
        return {"centre_m": self.centre_m.tolist(), "axis": self.axis.tolist(), "width_m": self.width_m,
                "quality": self.quality}


def _offset(surface: trimesh.Trimesh) -> float:
    """Ray origins start this far inside the surface: closer, a ray re-hits its own face."""
    return 1e-4 * float(np.ptp(surface.vertices, axis=0).max())


def sample_antipodal_grasps(surface: trimesh.Trimesh, rng: np.random.Generator, n_grasps: int = 20,
                            friction: float = 0.5, max_width_m: float = MAX_OPENING_M, min_width_m: float = 0.002,
                            up=(0.0, 0.0, 1.0), max_tilt_rad: float = math.radians(20.0),
                            finger_clearance_m: float = 0.028, finger_half_width_m: float = 0.009,
                            pad_clearance_m: float = 0.009,
                            max_depth_m: float | None = None,
                            min_height_m: float = 0.0,
                            n_samples: int = 2000, max_rounds: int = 10) -> list[AntipodalGrasp]:
    """Up to ``n_grasps`` antipodal grasps, best quality first (see the module docstring).

    Reproducible: the same ``rng`` state gives the same grasps.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (e.g. np.random.default_rng(seed))")
    if not friction > 0:
        raise ValueError(f"friction must be > 0, got {friction}")
    up = np.asarray(up, float) / np.linalg.norm(up)
    cos_cone = math.cos(math.atan(friction))
    eps = _offset(surface)
    height = np.asarray(surface.vertices) @ up
    bottom, top = float(height.min()), float(height.max())
    found: list[AntipodalGrasp] = []
    for _ in range(max_rounds):
        seed = int(rng.integers(2**31 - 1))
        points, face = trimesh.sample.sample_surface(surface, n_samples, seed=seed)
        normals = surface.face_normals[face]
        origins = points - eps * normals
        hit_face, ray, hits = surface.ray.intersects_id(origins, -normals, multiple_hits=True, return_locations=True)
        p1, n1 = points[ray], normals[ray]  # the surface point itself, not the ray origin
        p2, n2 = hits, surface.face_normals[hit_face]
        vec = p2 - p1
        width = np.linalg.norm(vec, axis=1)
        ok = (width >= min_width_m) & (width <= max_width_m)
        axis = vec / np.maximum(width, 1e-300)[:, None]
        # Finger 1 pushes along +axis on a surface with normal n1 (outward): -n1 within the cone;
        # finger 2 where the ray leaves the solid (n2 along the axis).
        c1 = -np.einsum("ij,ij->i", n1, axis)
        c2 = np.einsum("ij,ij->i", n2, axis)
        ok &= (c1 >= cos_cone) & (c2 >= cos_cone)
        ok &= np.abs(axis @ up) <= math.sin(max_tilt_rad)
        h1, h2 = p1 @ up, p2 @ up
        ok &= (np.minimum(h1, h2) >= bottom + min_height_m)
        if max_depth_m is not None:
            ok &= np.minimum(h1, h2) >= top - max_depth_m
        idx = np.flatnonzero(ok)
        if len(idx):
            idx = idx[_clear_above(surface, p1[idx], n1[idx], up, eps) & _clear_above(surface, p2[idx], n2[idx], up, eps)]
        if len(idx) and finger_clearance_m > 0:
            # Three rays per finger: its centre line and both edges of the 20 mm wide pad.
            side = np.cross(up, axis[idx])
            side /= np.maximum(np.linalg.norm(side, axis=1), 1e-12)[:, None]
            for offset in (0.0, finger_half_width_m, -finger_half_width_m):
                keep = (_clear_beside(surface, p1[idx] + offset * side, -axis[idx], finger_clearance_m, eps)
                        & _clear_beside(surface, p2[idx] + offset * side, axis[idx], finger_clearance_m, eps))
                idx, side = idx[keep], side[keep]
        if len(idx) and pad_clearance_m > 0:  # the pad's lower half must not land on the object
            down = np.broadcast_to(-up, (len(idx), 3))
            idx = idx[_clear_beside(surface, p1[idx] - 2 * eps * axis[idx], down, pad_clearance_m, eps)
                      & _clear_beside(surface, p2[idx] + 2 * eps * axis[idx], down, pad_clearance_m, eps)]
        margin = (np.minimum(c1, c2) - cos_cone) / (1.0 - cos_cone)
        for i in idx:
            found.append(AntipodalGrasp(0.5 * (p1[i] + p2[i]), axis[i], float(width[i]), float(np.clip(margin[i], 0, 1))))
        if len(found) >= 4 * n_grasps:
            break
    found.sort(key=lambda g: -g.quality)
    return found[:n_grasps]


def _clear_beside(surface, points, outward, distance_m, eps) -> np.ndarray:
    """True where the object leaves ``distance_m`` free outward of the contact (a finger fits)."""
    origins = points + 2 * eps * outward
    hit_face, ray, hits = surface.ray.intersects_id(origins, outward, multiple_hits=False, return_locations=True)
    clear = np.ones(len(points), bool)
    if len(ray) == 0:
        return clear
    hits = np.asarray(hits, float).reshape(-1, 3)
    clear[ray[np.linalg.norm(hits - origins[ray], axis=1) < distance_m]] = False
    return clear


def _clear_above(surface, points, normals, up, eps) -> np.ndarray:
    """True where a ray from just outside the contact toward +up leaves the object untouched."""
    if len(points) == 0:
        return np.zeros(0, bool)
    origins = points + 2 * eps * normals + 2 * eps * up
    blocked = surface.ray.intersects_any(origins, np.broadcast_to(up, origins.shape))
    return ~blocked


@dataclasses.dataclass(frozen=True)
class GraspPath:
    """A straight path along an object: ``point(s) = start_m + s * direction`` for
    ``0 <= s <= length_m``, limited to where antipodal grasps exist."""

    start_m: np.ndarray
    direction: np.ndarray
    length_m: float

    def point(self, s_m) -> np.ndarray:
        """Position(s) at arc length ``s_m`` [m] along the path."""
        s = np.asarray(s_m, float)
        return self.start_m + s[..., None] * self.direction

    def position_of(self, points_m) -> np.ndarray:
        """Arc length [m] of the projection of points onto the path."""
        return (np.asarray(points_m, float) - self.start_m) @ self.direction

    def to_dict(self) -> dict:
        return {"start_m": self.start_m.tolist(), "direction": self.direction.tolist(), "length_m": self.length_m}


def grasp_path(surface: trimesh.Trimesh, grasps: list[AntipodalGrasp], axis=None) -> GraspPath:
    """The principal axis of the solid (or ``axis``) through its centroid, clipped to the span
    of the grasp centres projected on it."""
    if not grasps:
        raise ValueError("no grasps to span a path: sample with more samples or a wider hand")
    centroid = np.asarray(surface.center_mass, float)
    if axis is None:
        axis = surface.principal_inertia_vectors[0]  # smallest moment: the long axis
    d = np.asarray(axis, float)
    d = d / np.linalg.norm(d)
    if d[np.argmax(np.abs(d))] < 0:
        d = -d
    s = np.array([(g.centre_m - centroid) @ d for g in grasps])
    return GraspPath(centroid + s.min() * d, d, float(s.max() - s.min()))
