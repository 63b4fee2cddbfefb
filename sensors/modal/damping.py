"""Modal damping with contact damping (Zheng & James 2011, as in the paper).

C_m = diag(alpha + beta w^2) + gamma G,
G   = sum_p c_p U_p^T (mu_p I + (1 - mu_p) n_p n_p^T) U_p,

with U the mass-normalised mode shapes (U^T M U = I), so U^T (alpha M + beta K) U is the
diagonal diag(alpha + beta w^2).  c_p is the contact's normal force [N], n_p its normal, mu_p
its friction coefficient and U_p the 3 x r rows of U at the contact point.  The weight
mu I + (1 - mu) n n^T has eigenvalues 1 (normal) and mu (tangential), so G is positive
semi-definite for every mu >= 0 and the damped system stays passive.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .contact import Contact

# A contact farther than this from the object's surface is a bug upstream (wrong frame,
# wrong object), not a modelling choice: refuse it rather than damp with garbage shapes.
MAX_SURFACE_DISTANCE_M = 2e-3


class OffSurfaceError(ValueError):
    """A contact or drive/mic point lies farther from the modal model's surface than allowed
    (a wrong frame, or a collision hull that over-covers the solid where it was touched)."""


#: Whether :func:`check_groups_on_surface` asks the model which points lie within the limit
#: (True, fast: ``within_surface_distance_m``, bounds settle most points, the distance only for
#: the error message) or every point's distance (False, the reference): the same decisions and
#: errors, message included (``tests/test_surface_check.py``).  Read at each check.
ASK_WITHIN = True


def within_surface_distance_m(model, points_m, limit_m: float) -> np.ndarray:
    """Whether each point (n, 3) [m] lies within ``limit_m`` of ``model``'s surface, (n,) bool:
    ``|model.surface_distance_m(points_m)| <= limit_m`` (a NaN distance is not within), asked of
    ``model.within_surface_distance_m`` where the model has one (a ``ModalModel`` settles most
    points by bounds, ``sensors.mesh.locator.CENTROID_BOUNDS``), of its distances otherwise.
    The models that wrap another (material views, filled containers, springs, touching
    objects) delegate their ``within_surface_distance_m`` here with the model they wrap."""
    within = getattr(model, "within_surface_distance_m", None)
    if within is not None:
        return np.asarray(within(points_m, limit_m), dtype=bool).reshape(-1)
    return np.abs(np.asarray(model.surface_distance_m(points_m), dtype=float)).reshape(-1) <= limit_m


def check_on_surface(model, points_m: np.ndarray, what: str = "contact",
                     max_distance_m: float = MAX_SURFACE_DISTANCE_M) -> None:
    """Raise :class:`OffSurfaceError` (a ``ValueError``) if a point is farther than
    ``max_distance_m`` from the surface.

    Only applies when the model offers ``surface_distance_m(points_m)``.
    """
    check_groups_on_surface(model, [(points_m, what)], max_distance_m)


def check_groups_on_surface(model, groups, max_distance_m: float = MAX_SURFACE_DISTANCE_M) -> None:
    """:func:`check_on_surface` of several point groups ``[(points_m, what), ...]`` with one
    query (a point's distance does not depend on the batch it is asked in): the first point
    too far, in the groups' order, raises the error its own check would."""
    surf = getattr(model, "surface_distance_m", None)
    if surf is None:
        return
    pts = [np.atleast_2d(np.asarray(p, dtype=float)).reshape(-1, 3) for p, _ in groups]
    labels = [what for (_, what), p in zip(groups, pts) for _ in range(len(p))]
    if not labels:
        return
    pts = np.concatenate(pts)
    if ASK_WITHIN:
        bad = np.flatnonzero(~within_surface_distance_m(model, pts, max_distance_m))
        if bad.size:    # only the first failing point's distance is needed: for the message
            i = int(bad[0])
            _raise_off_surface(labels[i], pts[i], abs(float(np.asarray(surf(pts[i:i + 1]), dtype=float).reshape(-1)[0])),
                               max_distance_m)
        return
    d = np.abs(np.asarray(surf(pts), dtype=float).reshape(-1))
    bad = np.flatnonzero(~(d <= max_distance_m))
    if bad.size:
        i = int(bad[0])
        _raise_off_surface(labels[i], pts[i], d[i], max_distance_m)


def _raise_off_surface(what: str, point_m: np.ndarray, distance_m: float, max_distance_m: float):
    raise OffSurfaceError(
        f"{what} at {point_m.tolist()} m is {distance_m * 1e3:.3g} mm from the object surface "
        f"(limit {max_distance_m * 1e3:.3g} mm): is it in the object frame?")


def contact_damping_factor(model, contacts: Sequence[Contact], shapes=None) -> np.ndarray:
    """F with G = F^T F, shape (3 P, r), units sqrt(N): per contact p the rows
    sqrt(c_p) W_p^(1/2) U_p, where W_p^(1/2) = sqrt(mu_p) (I - n_p n_p^T) + n_p n_p^T is the
    square root of the weight (it has eigenvalues 1 along the normal and mu_p across it).

    The contact damping has rank at most 3 P: the synthesis uses this factor to find the
    complex modes in O(r^2 P^2) instead of O(r^3) (:mod:`sensors.synthesis.low_rank_modes`).
    ``shapes``: ``model.mode_shapes_at`` at every contact's position (P, 3, r), if the caller
    has them (the same numbers: a point's shapes do not depend on its batch)."""
    r = len(model.angular_frequencies_rad_s)
    contacts = list(contacts)
    touching = [i for i, c in enumerate(contacts) if c.force_n > 0.0]
    contacts = [contacts[i] for i in touching]
    if not contacts:
        return np.zeros((0, r))
    pos = np.array([c.position_m for c in contacts])
    nrm = np.array([c.normal for c in contacts])
    f = np.array([c.force_n for c in contacts])
    mu = np.array([c.friction for c in contacts])
    if shapes is None:
        U = np.asarray(model.mode_shapes_at(pos), dtype=float)   # (P, 3, r)
    else:
        U = np.asarray(shapes, dtype=float)[touching]
    along = np.einsum("pi,pir->pr", nrm, U)                   # n^T U
    normal_part = nrm[:, :, None] * along[:, None, :]         # n n^T U
    F = np.sqrt(f)[:, None, None] * (np.sqrt(mu)[:, None, None] * (U - normal_part) + normal_part)
    return F.reshape(-1, r)


def contact_damping_matrix(model, contacts: Sequence[Contact]) -> np.ndarray:
    """G = sum_p c_p U_p^T (mu_p I + (1 - mu_p) n_p n_p^T) U_p, shape (r, r), units N."""
    F = contact_damping_factor(model, contacts)
    return F.T @ F


def modal_damping_parts(model, contacts: Sequence[Contact] = (), *,
                        max_surface_distance_m: float = MAX_SURFACE_DISTANCE_M,
                        contact_shapes=None) -> tuple[np.ndarray, np.ndarray]:
    """``(d, Q)`` with C_m = diag(d) + Q^T Q: the Rayleigh part d = alpha + beta w^2 [1/s]
    (plus the model's ``added_damping_per_s`` if it has one) and the contact part's factor Q = sqrt(gamma) F (``contact_damping_factor``), shape
    (3 P, r). Validates the contacts as :func:`modal_damping_matrix` does.
    ``contact_shapes``: ``model.mode_shapes_at`` at every contact's position (P, 3, r), given by
    a caller that has them and has checked the contacts on the surface itself
    (``ModalSystem.build``): neither is done again."""
    contacts = list(contacts)
    for c in contacts:
        if not isinstance(c, Contact):
            raise TypeError(f"expected sensors.Contact, got {type(c).__name__}")
    w = np.asarray(model.angular_frequencies_rad_s, dtype=float)
    mat = model.material
    # several bodies of different materials (sensors.modal.touching): their own Rayleigh part
    rayleigh = getattr(model, "rayleigh_damping_per_s", None)
    d = float(mat.alpha) + float(mat.beta) * w ** 2 if rayleigh is None else np.asarray(rayleigh, float)
    extra = getattr(model, "added_damping_per_s", None)  # e.g. a liquid's boundary layer
    if extra is not None:
        d = d + np.asarray(extra, dtype=float)
    # dampers between the object and the bodies it touches (sensors.modal.touching)
    coupling = getattr(model, "coupling_damping_factor", None)
    coupling = np.zeros((0, w.size)) if coupling is None else np.asarray(coupling, float)
    if not contacts:
        return d, coupling
    if contact_shapes is None:
        check_on_surface(model, np.array([c.position_m for c in contacts]), "contact", max_surface_distance_m)
    return d, np.vstack([np.sqrt(float(mat.gamma)) * contact_damping_factor(model, contacts, contact_shapes),
                         coupling])


def modal_damping_matrix(model, contacts: Sequence[Contact] = (), *,
                         max_surface_distance_m: float = MAX_SURFACE_DISTANCE_M) -> np.ndarray:
    """Total modal damping C_m = diag(alpha + beta w^2) + gamma G, shape (r, r), units 1/s.

    ``model`` offers ``angular_frequencies_rad_s``, ``material`` (alpha [1/s], beta [s],
    gamma [s/m]) and ``mode_shapes_at``; contacts farther than ``max_surface_distance_m`` from
    the surface raise ``ValueError`` when the model offers ``surface_distance_m``.
    """
    d, Q = modal_damping_parts(model, contacts, max_surface_distance_m=max_surface_distance_m)
    return np.diag(d) + Q.T @ Q
