"""Touching bodies vibrate together: component mode synthesis of free bodies joined by springs.

Each body keeps its own Ritz basis (:mod:`sensors.modal.static_correction`): the six
rigid-body modes, its elastic modes and attachment modes at its link points (the directions
each link constrains).  In the stacked coordinates of all bodies the mass is the identity and
the stiffness

    K = blockdiag(K_1, ..., K_B) + sum_links D_l^T (k_n n n^T + k_t (I - n n^T)) D_l,
    D_l = R_a Phi_a(p_a) - R_b Phi_b(p_b),

with R the body's orientation (body frame -> world) and Phi its basis at the link point (body
frame): a link pulls the two points together along its normal and across it.  The
eigenvectors give the modes of the assembly (Craig & Kurdila, *Fundamentals of Structural
Dynamics*, 2006, ch. 18, free-interface synthesis with residual flexibility).  A grounded
spring is the limit of a link to an infinitely massive body (a table): a link with
``body_b=None`` (D_l = R_a Phi_a(p_a) alone), as in :mod:`sensors.modal.spring_modes`.

The coupled modes are returned as frequencies and shapes per body, so that a synthesis can
read the motion of any body's point (the microphone on body 0, a contact on body 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import coupled_basis, static_correction
from .spring_modes import (MIN_MODE_FREQUENCY_HZ, SpringModes, flexible_base, merge_close_springs, spring_directions,
                           warn_no_mesh)
from .static_correction import contact_flexibility

__all__ = ["MAX_COUPLED_COORDINATES", "BodyLink", "CoupledBodies", "CoupledSizeError", "check_coupled_size",
           "coupled_bodies"]

#: The most Ritz coordinates (6 rigid + elastic modes + attachment vectors, summed over the
#: bodies) one coupled system may have.  Its dense eigenproblem costs O(n^3) (about 0.1 s at
#: 800 on one core) and every synthesis of the grasp works on its modes; two of the project's
#: bars at their default band hold some 150-300.  Raise it here, or pass ``max_coordinates``,
#: for larger assemblies; lowering the models' ``max_frequency_hz`` shrinks them.
MAX_COUPLED_COORDINATES = 800


class CoupledSizeError(ValueError):
    """A coupled system would exceed its coordinate limit (see ``MAX_COUPLED_COORDINATES``)."""


def check_coupled_size(bodies, springs_per_body, limit: int) -> int:
    """The coupled system's coordinate count (per body 6 + its modes + up to 3 directions per
    spring point); raises :class:`CoupledSizeError` with the estimate per body, the limit and
    how to change it when above ``limit``."""
    per_body = [6 + len(np.asarray(m.angular_frequencies_rad_s)) + 3 * len(springs)
                for (m, _, _), springs in zip(bodies, springs_per_body)]
    total = int(sum(per_body))
    if total > limit:
        raise CoupledSizeError(
            f"the coupled system of {len(per_body)} bodies would have about {total} coordinates "
            f"(per body: {per_body}), above the limit of {limit}: raise "
            "sensors.modal.coupled_bodies.MAX_COUPLED_COORDINATES (or pass max_coordinates), or build the "
            "objects' modal models with a lower max_frequency_hz")
    return total


@dataclass(frozen=True)
class BodyLink:
    """A spring between two bodies at a contact (world frame).

    ``body_a``, ``body_b``: indices into the bodies (``body_b=None``: the ground, a massive
    support such as the table); ``point_m``: the contact point [m];
    ``normal``: unit normal of the contact (outward from body a); ``normal_stiffness_n_per_m``
    and ``tangential_stiffness_n_per_m`` [N/m] (see ``sensors.modal.contact_stiffness`` for
    Hertz/Mindlin values).
    """

    body_a: int
    body_b: int | None
    point_m: tuple
    normal: tuple
    normal_stiffness_n_per_m: float
    tangential_stiffness_n_per_m: float = 0.0


class CoupledBodies:
    """The modes of free bodies joined by :class:`BodyLink` springs.

    ``frequencies_hz`` (ascending, rigid-body motion of the whole assembly left out) and
    ``mode_shapes_at(body, points_m)`` ((n, 3, r) in that body's frame, mass-normalised over
    the assembly).
    """

    def __init__(self, bodies, links, max_coordinates: int | None = None) -> None:
        self.bodies = [(m, np.asarray(R, float), np.asarray(t, float)) for m, R, t in bodies]
        self.links = list(links)
        springs_per_body = [[] for _ in self.bodies]
        own_points = [[] for _ in self.bodies]     # kept at its point by SNAP_TO_NODES: body 0's (see coupled_basis)
        for ln in self.links:
            n = np.asarray(ln.normal, float) / np.linalg.norm(ln.normal)
            for side in (ln.body_a, ln.body_b):
                if side is None:
                    continue
                model, R, t = self.bodies[side]
                p_body = R.T @ (np.asarray(ln.point_m, float) - t)
                springs_per_body[side].append((p_body, R.T @ n, ln.normal_stiffness_n_per_m,
                                               ln.tangential_stiffness_n_per_m))
                own_points[side].append(side == 0 and (ln.body_b is None or not coupled_basis.SNAP_GRASPED))
        check_coupled_size(self.bodies, springs_per_body,
                           MAX_COUPLED_COORDINATES if max_coordinates is None else max_coordinates)
        # each body's Ritz basis with attachment modes at its link points (a SpringModes of
        # the link springs, grounded: only its basis and free stiffness are used here), or, for
        # the partners, at the mesh nodes nearest them (coupled_basis.SNAP_TO_NODES: the links
        # still act at their own points)
        self._parts = []
        blocks = []
        for body, ((model, R, t), springs) in enumerate(zip(self.bodies, springs_per_body)):
            flex = flexible_base(model)
            if flex is None:     # a filled container: its (wet) modes without static correction
                warn_no_mesh(model)
                part = SpringModes(model, springs)
            else:
                base, fs, ss = flex
                keep = own_points[body]
                if spring_directions(springs) > static_correction.MAX_ATTACHMENT_VECTORS:
                    # many links on one body (a bar lying along another, a partner on several of
                    # a mug's collision pieces): its attachment modes at merged points. They are
                    # a Ritz basis only; every link still acts at its own point and stiffness.
                    springs = merge_close_springs(springs)
                    keep = [body == 0 and not coupled_basis.SNAP_GRASPED] * len(springs)
                if coupled_basis.SNAP_TO_NODES and springs:
                    snapped = coupled_basis.basis_points(base, [sp[0] for sp in springs])
                    springs = [sp if kept else (q, *sp[1:]) for sp, q, kept in zip(springs, snapped, keep)]
                part = SpringModes(model, springs, fs, ss, contact_flexibility(base))
            self._parts.append(part)
            blocks.append(part.free_stiffness)
        sizes = [b.shape[0] for b in blocks]
        offs = np.concatenate([[0], np.cumsum(sizes)])
        self._offs = offs
        K = np.zeros((offs[-1], offs[-1]))
        for i, b in enumerate(blocks):
            K[offs[i]:offs[i + 1], offs[i]:offs[i + 1]] = b
        self._differences = self.link_differences()      # kept: the dampers of a coupled grasp use them too
        for ln, D in zip(self.links, self._differences):
            n = np.asarray(ln.normal, float) / np.linalg.norm(ln.normal)
            W = (ln.normal_stiffness_n_per_m * np.outer(n, n)
                 + ln.tangential_stiffness_n_per_m * (np.eye(3) - np.outer(n, n)))
            K += D.T @ W @ D
        lam, V = np.linalg.eigh(0.5 * (K + K.T))
        keep = lam > (2 * np.pi * MIN_MODE_FREQUENCY_HZ) ** 2
        self.V = V[:, keep]
        self.angular_frequencies_rad_s = np.sqrt(lam[keep])
        self.frequencies_hz = self.angular_frequencies_rad_s / (2 * np.pi)

    @property
    def parts(self) -> list:
        """Each body's Ritz basis (a :class:`SpringModes`: ``ritz_at``, ``free_stiffness``, ``split``)."""
        return list(self._parts)

    def rows(self, body: int) -> slice:
        """The rows of ``body``'s Ritz coordinates in the stacked coordinates (and in ``V``)."""
        return slice(int(self._offs[body]), int(self._offs[body + 1]))

    def link_difference(self, link: BodyLink) -> np.ndarray:
        """D (3, n): the world-frame motion of the link's point on body a minus that on body b
        (nothing for the ground) per stacked Ritz coordinate (read-only, kept for the
        assembly's own links)."""
        for kept, D in zip(self.links, self._differences):
            if kept is link:
                return D
        D = np.zeros((3, int(self._offs[-1])))
        for side, sign in ((link.body_a, 1.0), (link.body_b, -1.0)):
            if side is None:
                continue
            model, R, t = self.bodies[side]
            p_body = R.T @ (np.asarray(link.point_m, float) - t)
            D[:, self.rows(side)] += sign * R @ self._parts[side].ritz_at(p_body[None])[0]
        return D

    def link_differences(self) -> list[np.ndarray]:
        """:meth:`link_difference` of every link, each body's Ritz basis evaluated at all its
        link points in one call (a point's rows do not depend on the others evaluated with it:
        the same numbers, one point location per body instead of one per link end)."""
        ends: list[list] = [[] for _ in self.bodies]          # per body: (link, sign, point in its frame)
        for i, link in enumerate(self.links):
            for side, sign in ((link.body_a, 1.0), (link.body_b, -1.0)):
                if side is not None:
                    _, R, t = self.bodies[side]
                    ends[side].append((i, sign, R.T @ (np.asarray(link.point_m, float) - t)))
        out = [np.zeros((3, int(self._offs[-1]))) for _ in self.links]
        for body, items in enumerate(ends):
            if not items:
                continue
            R = self.bodies[body][1]
            rows = self._parts[body].ritz_at(np.array([p for _, _, p in items]))
            for (i, sign, _), S in zip(items, rows):
                out[i][:, self.rows(body)] += sign * R @ S
        for D in out:
            D.flags.writeable = False
        return out

    def mode_shapes_at(self, body: int, points_m) -> np.ndarray:
        """Coupled mode shapes at points of ``body`` (its frame): (n, 3, r)."""
        o = self._offs
        return self._parts[body].ritz_at(points_m) @ self.V[o[body]:o[body + 1]]


def coupled_bodies(bodies, links, max_coordinates: int | None = None) -> CoupledBodies:
    """The modes of ``bodies`` (``[(model, rotation (3, 3), translation_m (3,)), ...]``, body
    frame -> world) joined by ``links`` (:class:`BodyLink`; ``body_b=None``: to the ground).
    ``max_coordinates``: the size bound (default :data:`MAX_COUPLED_COORDINATES`)."""
    return CoupledBodies(bodies, links, max_coordinates)
