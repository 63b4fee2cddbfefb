"""An object's modes with its contacts' springs: Rayleigh-Ritz on [rigid, elastic, attachment].

Each contact with a stiffness (``sensors.Contact``, :mod:`sensors.modal.contact_stiffness`)
is a grounded spring k_n n n^T + k_t (I - n n^T) at its point.  On the basis
Phi = [R, U, Psi] of :mod:`sensors.modal.static_correction` (mass matrix I) the stiffness is

    K_red = blockdiag(0, diag(w^2), Psi^T K Psi) + sum_p Phi_p^T (k_n n n^T + k_t (I - n n^T)) Phi_p,

and its eigenvectors V (K_red V = V diag(w_c^2), V^T V = I) give the coupled modes Phi V,
mass-normalised.  :class:`SpringModes` is a ``ModalBasis`` of them: the synthesis uses it in
place of the free model (``contact_model="spring_damper"``), damping included (Rayleigh
alpha + beta w_c^2 on the coupled modes, i.e. the springs carry the object's beta, negligible
against the contact damping; the contact damping on the coupled shapes).  Coupled modes below
:data:`MIN_MODE_FREQUENCY_HZ` are rigid-body motions that no spring holds: they are not sound
and are left out.

The state of one contact set passes to the next through the M-orthogonal projection
:func:`modal_transfer` (``sensors.synthesis.modal_system.transfer_state``: no switch adds
energy).
"""

from __future__ import annotations

import logging

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from .contact import Contact
from .contact_stiffness import contact_stiffnesses_n_per_m
from .damping import within_surface_distance_m
from . import static_correction
from ..fem.assembly import shape_functions
from .basis import check_points_m
from .static_correction import contact_flexibility

__all__ = ["MERGE_RADIUS_M", "merge_close_springs", "spring_directions", "MIN_MODE_FREQUENCY_HZ", "SpringModes", "cross3", "contact_springs", "flexible_base", "spring_modes",
           "modal_transfer"]

log = logging.getLogger(__name__)

#: Coupled modes below this frequency [Hz] are unconstrained rigid-body motion (numerically
#: zero eigenvalues), not vibration: left out of the coupled model.
MIN_MODE_FREQUENCY_HZ = 1.0
# Springs weaker than this [N/m] count as none (a basis vector for them would only add cost).
_NEGLIGIBLE_STIFFNESS_N_PER_M = 1e-9

_CACHE: LRU = LRU(CACHE_SIZES["modal.spring_modes"])
_WARNED: set = set()

#: Whether a :class:`SpringModes` answers ``ritz_at`` at its own spring points from the rows it
#: built its stiffness with (True, fast: a grasp's damping contacts, drive and microphone points
#: are mostly those points, so a new contact set locates its points once), or evaluates the
#: basis anew at every call (False, the reference).  A point's rows do not depend on the other
#: points of a batch (locations and interpolation are per point), except for the attachment
#: rows of nodes an implicit basis had not made yet (their product rounds with its row count,
#: ~1e-16).  The contacts' own points (those merged into a spring) are evaluated with the
#: springs' in one call.  Kept: (P + merged) x 3 x (6 + r + a) floats per SpringModes (5.6 kB
#: for GraspPosition-v0's six springs, at most 40 kB for FillLevel-v0's 25 contacts), which
#: lives in the spring-mode LRU (32 entries: at most 1.3 MB).  Read at each call.
REUSE_SPRING_ROWS = True
#: Whether the springs' stiffness sum_p S_p^T W_p S_p is one product Z^T Z of the stacked
#: rows Z_p = W_p^(1/2) S_p (True, fast: one BLAS call instead of two per spring), or summed
#: spring by spring (False, the reference).  The same matrix to rounding: eigenvalues within
#: 1e-13 of the largest (``tests/test_spring_stiffness_sum.py``; the lowest suspension modes'
#: frequencies within 1e-11 relative, as between any two summation orders).  Read at each call.
ONE_PRODUCT_STIFFNESS = True
#: The merged contacts' extra points (usually none or one: 0.08 ms of ``np.unique(axis=0)``
#: per contact set, most of it its fixed cost) are taken as they are when there are fewer than
#: two: ``np.unique`` of zero or one row is that row, so the same bytes.  False: ``np.unique``
#: always (the reference; ``tests/test_episode_glue.py``).  Read at each call.
FEW_EXTRA_POINTS = True
#: Whether :func:`merge_close_springs` rules out far pairs in one vectorized pass before its
#: exact per-pair test (True, fast) or tests every pair (False, the reference).  The same
#: groups: the exact test decides every pair the pass keeps, and its 1e-9 margin keeps every
#: pair that test could accept.  Read at each call.
VECTORIZED_MERGE = True


def contact_springs(model, contacts) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """``[(position_m, normal, k_n, k_t), ...]`` [N/m] of the contacts that are springs on
    ``model`` (its material for Hertz/Mindlin where a stiffness is ``None``)."""
    out = []
    for c in contacts:
        if not isinstance(c, Contact):
            raise TypeError(f"expected sensors.Contact, got {type(c).__name__}")
        kn, kt = contact_stiffnesses_n_per_m(c, model.material)
        if kn > _NEGLIGIBLE_STIFFNESS_N_PER_M or kt > _NEGLIGIBLE_STIFFNESS_N_PER_M:
            out.append((c.position_m, c.normal, kn, kt))
    return merge_close_springs(out)


#: Contact springs closer than this (and facing alike) act as one: MuJoCo gives a face contact
#: several points a few mm apart, whose attachment vectors are nearly the same.
MERGE_RADIUS_M = 2e-3


def spring_directions(springs) -> int:
    """How many directions ``springs`` (point, normal, k_n, k_t) constrain: their attachment
    vectors (the normal where k_n > 0, two tangents where k_t > 0)."""
    return sum((kn > _NEGLIGIBLE_STIFFNESS_N_PER_M) + 2 * (kt > _NEGLIGIBLE_STIFFNESS_N_PER_M)
               for _, _, kn, kt in springs)


def _maybe_close(springs, radius_m: float):
    """Per pair of springs (a list of lists of bools), whether they may merge: within
    ``radius_m`` and normals above 0.9, with a 1e-9 margin (the exact test of
    :func:`merge_close_springs` decides the pairs kept; None: test every pair).  Pairs are
    ruled out at once instead of one norm and one dot per pair in Python (0.9 ms for
    FillLevel-v0's 25 contacts)."""
    if not VECTORIZED_MERGE or len(springs) < 2:
        return None
    pts = np.array([p for p, _, _, _ in springs], dtype=float)
    nrm = np.array([n for _, n, _, _ in springs], dtype=float)
    diff = pts[:, None, :] - pts[None, :, :]
    d2 = np.einsum("ijk,ijk->ij", diff, diff)
    return ((d2 <= (radius_m * (1.0 + 1e-9)) ** 2) & (nrm @ nrm.T > 0.9 - 1e-9)).tolist()


def _pair_bounds(springs, radius_m: float):
    """``(maybe, surely)`` (n, n) bools: pairs that may pass the exact test of
    :func:`merge_close_springs` (within ``radius_m``, normals above 0.9, with a 1e-9 margin) and
    pairs that surely pass it (by the same margin inside); the vectorized sums round within a
    few 1e-16 of the exact test's, far inside the margin."""
    pts = np.array([p for p, _, _, _ in springs], dtype=float)
    nrm = np.array([n for _, n, _, _ in springs], dtype=float)
    diff = pts[:, None, :] - pts[None, :, :]
    d2 = np.einsum("ijk,ijk->ij", diff, diff)
    dots = nrm @ nrm.T
    r2 = radius_m * radius_m
    maybe = (d2 <= r2 * (1.0 + 1e-9) ** 2) & (dots > 0.9 - 1e-9)
    surely = (d2 <= r2 * (1.0 - 1e-9) ** 2) & (dots > 0.9 + 1e-9)
    return maybe, surely


def _groups(springs, radius_m: float) -> list[list[int]]:
    """The groups of :func:`merge_close_springs` (indices): each spring joins the first group
    whose first member passes the exact test with it."""
    near = _maybe_close(springs, radius_m)
    groups: list[list[int]] = []
    for i, (p, n, kn, kt) in enumerate(springs):
        for g in groups:
            # the exact test on the pairs the vectorized one cannot rule out
            q, m = springs[g[0]][0], springs[g[0]][1]
            if (near is None or near[g[0]][i]) and np.linalg.norm(q - p) <= radius_m and float(np.dot(m, n)) > 0.9:
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def _groups_bounded(springs, radius_m: float) -> list[list[int]]:
    """:func:`_groups` with the pairs settled by :func:`_pair_bounds` (the exact test only for
    pairs in the 1e-9 margin between them): the same groups (:data:`FAST_MERGE`)."""
    maybe, surely = _pair_bounds(springs, radius_m)
    maybe, surely = maybe.tolist(), surely.tolist()
    groups: list[list[int]] = []
    leaders: list[int] = []
    for i in range(len(springs)):
        for g, lead in zip(groups, leaders):
            if maybe[lead][i] and (surely[lead][i] or _exact_close(springs[lead], springs[i], radius_m)):
                g.append(i)
                break
        else:
            groups.append([i])
            leaders.append(i)
    return groups


def _exact_close(leader, other, radius_m: float) -> bool:
    return bool(np.linalg.norm(leader[0] - other[0]) <= radius_m and float(np.dot(leader[1], other[1])) > 0.9)


def _merged(g):
    """One spring of a group of parallel springs: :func:`merge_close_springs`'s reference sums."""
    w = np.array([kn + kt for _, _, kn, kt in g])
    p = np.average([q for q, _, _, _ in g], axis=0, weights=w)
    n = np.sum([wi * m for wi, (_, m, _, _) in zip(w, g)], axis=0)
    return (p, n / np.linalg.norm(n), sum(x[2] for x in g), sum(x[3] for x in g))


def _merged_lean(g):
    """:func:`_merged` by the same numpy operations without ``np.average``'s and ``np.sum``'s
    argument handling: ``average(a, axis=0, weights=w)`` is ``multiply(a, wgt).sum(0) /
    wgt.sum(0)`` on the weights as a column, and ``sum(list, axis=0)`` is ``add.reduce`` of the
    stacked products: the same products and sums, the same bits (:data:`FAST_MERGE`)."""
    w = np.array([kn + kt for _, _, kn, kt in g])
    wc = w[:, None]
    p = np.multiply(np.array([q for q, _, _, _ in g]), wc).sum(axis=0) / wc.sum(axis=0)
    n = np.add.reduce(wc * np.array([m for _, m, _, _ in g]), axis=0)
    return (p, n / np.linalg.norm(n), sum(x[2] for x in g), sum(x[3] for x in g))


#: Whether :func:`merge_close_springs` settles pairs by vectorized bounds, with the exact
#: per-pair test only inside their 1e-9 margin, and merges a group without ``np.average``'s
#: argument handling (True, fast: 0.54 -> 0.2 ms for FillLevel-v0's ~20 contacts) or runs the
#: per-pair tests and numpy's functions (False, the reference).  The same groups and the same
#: bits (``tests/test_merge_springs.py``).  Read at each call.
FAST_MERGE = True


def merge_close_springs(springs, radius_m: float = MERGE_RADIUS_M):
    """Springs within ``radius_m`` of each other with normals within 25 degrees merged into one
    (parallel springs: stiffnesses summed, at their stiffness-weighted centre); the radius is
    doubled until the constrained directions fit :data:`static_correction.MAX_ATTACHMENT_VECTORS`,
    so a cluttered contact set (a grasp on an edge: tens of points) stays bounded instead of
    failing mid-episode."""
    while True:
        fast = FAST_MERGE and len(springs) >= 2
        groups = _groups_bounded(springs, radius_m) if fast else _groups(springs, radius_m)
        merge = _merged_lean if fast else _merged
        merged = [springs[g[0]] if len(g) == 1 else merge([springs[i] for i in g]) for g in groups]
        if spring_directions(merged) <= static_correction.MAX_ATTACHMENT_VECTORS or len(merged) <= 1:
            return merged
        springs, radius_m = merged, 2.0 * radius_m


class SpringModes:
    """The modes of ``base`` (a modal model) held by grounded contact springs.

    A ``ModalBasis``: ``frequencies_hz``, ``angular_frequencies_rad_s``, ``material``,
    ``mode_shapes_at``, ``surface_distance_m``, ``mass_kg``, ``n_modes``.  ``coordinates``
    names the Ritz basis (``basis``: the free model, ``psi``: its attachment vectors, ``V``:
    the eigenvectors) for :func:`modal_transfer`.  ``also_at``: points (m, 3) whose Ritz rows
    to evaluate with the springs' and keep (the contacts merged into springs, which the system's
    damping asks for; :data:`REUSE_SPRING_ROWS`).
    """

    def __init__(self, base, springs, frequency_scale: float = 1.0, shape_scale: float = 1.0,
                 flexible=None, also_at=None) -> None:
        self.base = base
        self.material = base.material
        self.springs = springs
        self._shape_scale = shape_scale
        w = np.asarray(base.angular_frequencies_rad_s, float)
        r = w.size
        # a model without a mesh may give its rigid-body modes (M-orthogonal to its elastic ones)
        self._rigid_at = None if flexible is not None else getattr(base, "rigid_mode_shapes_at", None)
        if flexible is not None:                       # ModalModel (or a view of one): [R, U, Psi]
            self.geometry = flexible.geometry()           # not the factorization (see its LRU)
            dirs, pts = _directions(springs)
            self.attachment = flexible.attachment_basis(pts, dirs)
            Kpsi, Kpsi_u = self.attachment.stiffness, self.attachment.coupling
            a = self.attachment.size
            n = 6 + r + a
            K = np.zeros((n, n))
            K[6:6 + r, 6:6 + r] = np.diag(w ** 2)
            K[6 + r:, 6 + r:] = Kpsi * frequency_scale ** 2
            K[6 + r:, 6:6 + r] = Kpsi_u * frequency_scale ** 2
            K[6:6 + r, 6 + r:] = K[6 + r:, 6:6 + r].T
            self.split = (6, r, a)
        else:                  # no mesh: the elastic modes, and the rigid ones if the model gives them
            self.geometry, self.attachment = None, None
            n_rigid = 0 if self._rigid_at is None else 6
            K = np.zeros((n_rigid + r, n_rigid + r))
            K[n_rigid:, n_rigid:] = np.diag(w ** 2)
            self.split = (n_rigid, r, 0)
        self.free_stiffness = K.copy()   # of the Ritz basis, before the springs
        self._spring_rows = None
        points = np.array([p for p, _, _, _ in springs]).reshape(-1, 3)
        if also_at is not None and REUSE_SPRING_ROWS:
            # the points a system of these contacts asks for next (the contacts that merged
            # into a spring), evaluated with the springs' in one call
            extra = np.asarray(also_at, dtype=float).reshape(-1, 3)
            bits = _point_bits(extra)
            new = ~np.all(bits[:, None, :] == _point_bits(points)[None, :, :], axis=2).any(axis=1)
            extra = extra[new]          # a copy already (a boolean index)
            if not FEW_EXTRA_POINTS or len(extra) >= 2:
                extra = np.unique(extra, axis=0)
            rows = self.ritz_at(np.concatenate([points, extra]))
            S = rows[:len(points)]      # (P, 3, n)
            self._spring_rows = (_point_bits(np.concatenate([points, extra])), rows)
        else:
            S = self.ritz_at(points)      # (P, 3, n)
            self._spring_rows = (_point_bits(points), S)
        if ONE_PRODUCT_STIFFNESS and len(springs):
            K += _spring_stiffness(springs, S)
        else:
            for (p, nrm, kn, kt), Sp in zip(springs, S):
                W = kn * np.outer(nrm, nrm) + kt * (np.eye(3) - np.outer(nrm, nrm))
                K += Sp.T @ W @ Sp
        self.stiffness = K      # of the Ritz basis with the springs
        self._eigen = None

    def _solve(self):
        # on first use: a coupled assembly (CoupledBodies) takes only each body's Ritz basis
        # and free stiffness, never its grounded modes
        if self._eigen is None:
            K = self.stiffness
            lam, V = np.linalg.eigh(0.5 * (K + K.T))
            keep = lam > (2 * np.pi * MIN_MODE_FREQUENCY_HZ) ** 2
            w = np.sqrt(lam[keep])
            self._eigen = (V[:, keep], w, w / (2 * np.pi))
        return self._eigen

    @property
    def V(self) -> np.ndarray:
        """The eigenvectors in the Ritz basis (n, r_c), mass-normalised."""
        return self._solve()[0]

    @property
    def angular_frequencies_rad_s(self) -> np.ndarray:
        return self._solve()[1]

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self._solve()[2]

    @property
    def psi(self) -> np.ndarray | None:
        """The attachment vectors Psi (n_dof, a) (formed on first use: nothing here needs them)."""
        return None if self.attachment is None else self.attachment.psi

    def mass_psi(self) -> np.ndarray | None:
        """M Psi (n_dof, a), the attachment vectors times the mesh's mass matrix: what every
        state transfer from these modes needs (:func:`modal_transfer`), made once."""
        return None if self.attachment is None else self.attachment.mass_psi()

    # -- ModalBasis ----------------------------------------------------------------------
    def ritz_at(self, points_m) -> np.ndarray:
        """The Ritz basis [R, U, Psi] at points: (n, 3, 6 + r + a) (without a mesh: [R, U] if the
        model gives its rigid modes, ``rigid_mode_shapes_at``, else U alone);
        ``split`` holds the three column counts, ``free_stiffness`` its stiffness without springs.
        Rows at its own spring points are those it was built with (:data:`REUSE_SPRING_ROWS`)."""
        known = self._spring_rows
        if known is not None and REUSE_SPRING_ROWS:
            p = np.asarray(points_m, dtype=float)
            if p.ndim == 2 and p.shape[1] == 3 and len(p):
                bits, rows = known
                same = np.all(_point_bits(p)[:, None, :] == bits[None, :, :], axis=2)   # (n, P)
                hit = same.any(axis=1)
                if hit.all():
                    return rows[same.argmax(axis=1)]
                if hit.any():
                    out = np.empty((len(p), 3, rows.shape[2]))
                    out[hit] = rows[same.argmax(axis=1)[hit]]
                    out[~hit] = self._ritz_rows(p[~hit])
                    return out
        return self._ritz_rows(points_m)

    def _ritz_rows(self, points_m) -> np.ndarray:
        """:meth:`ritz_at` evaluated anew."""
        U = np.asarray(self.base.mode_shapes_at(points_m), float)
        if self.geometry is None:
            return U if self._rigid_at is None else np.concatenate([self._rigid_at(points_m), U], axis=2)
        s = self._shape_scale
        R = self.geometry.rigid_at(points_m) * s
        P = attachment_at(self.geometry.model, self.attachment, points_m) * s
        return np.concatenate([R, U, P], axis=2)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Mass-normalised coupled mode shapes at points (n, 3): (n, 3, r_c)."""
        return self.ritz_at(points_m) @ self.V

    def surface_distance_m(self, points_m) -> np.ndarray:
        return self.base.surface_distance_m(points_m)

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        return within_surface_distance_m(self.base, points_m, limit_m)

    @property
    def n_modes(self) -> int:
        return int(self.angular_frequencies_rad_s.size)

    @property
    def mass_kg(self) -> float:
        return float(self.base.mass_kg)

    @property
    def decay_rates_per_s(self) -> np.ndarray:
        return self.material.decay_rate(self.angular_frequencies_rad_s)

    def __repr__(self) -> str:
        return f"SpringModes({len(self.springs)} springs on {self.base!r}, {self.n_modes} modes)"


def _point_bits(points: np.ndarray) -> np.ndarray:
    """Points (n, 3) as their float64 bit patterns: equal only when bit for bit the same."""
    return np.ascontiguousarray(points, dtype=float).view(np.int64).reshape(-1, 3)


def _spring_stiffness(springs, S: np.ndarray) -> np.ndarray:
    """sum_p S_p^T (k_n n n^T + k_t (I - n n^T)) S_p (n, n) for the springs' Ritz rows S (P, 3,
    n), as Z^T Z with Z_p = (sqrt(k_n) n n^T + sqrt(k_t) (I - n n^T)) S_p (the weight's square
    root: eigenvalues k_n along n, k_t across it)."""
    nrm = np.array([n for _, n, _, _ in springs], dtype=float)                       # (P, 3)
    kn = np.array([k for _, _, k, _ in springs], dtype=float)
    kt = np.array([k for _, _, _, k in springs], dtype=float)
    nn = nrm[:, :, None] * nrm[:, None, :]                                          # (P, 3, 3)
    root = (np.sqrt(kn)[:, None, None] * nn + np.sqrt(kt)[:, None, None] * (np.eye(3) - nn))
    Z = (root @ S).reshape(-1, S.shape[2])
    return Z.T @ Z


def cross3(a, b) -> np.ndarray:
    """The cross product of two 3-vectors: ``np.cross(a, b)`` bit for bit (the same products
    and differences), without its array-dispatch overhead (~15x slower on one pair, which
    every grasp's tangent directions paid per spring)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _directions(springs):
    """Points and unit directions of the constrained directions (normal where k_n > 0, two
    tangents where k_t > 0)."""
    pts, dirs = [], []
    for p, n, kn, kt in springs:
        if kn > _NEGLIGIBLE_STIFFNESS_N_PER_M:
            pts.append(p)
            dirs.append(n)
        if kt > _NEGLIGIBLE_STIFFNESS_N_PER_M:
            t1 = cross3(n, (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0))
            t1 /= np.linalg.norm(t1)
            pts += [p, p]
            dirs += [t1, cross3(n, t1)]
    return np.array(dirs).reshape(-1, 3), np.array(pts).reshape(-1, 3)


def flexible_base(model):
    """``(mesh model, frequency_scale, shape_scale)`` of a ``ModalModel`` or a
    ``MaterialView`` of one; ``None`` for a model without a mesh."""
    from .basis import MaterialView  # basis imports damping -> contact: import here, no cycle

    fs = ss = 1.0
    base = model
    if isinstance(model, MaterialView):
        base, fs, ss = model.base, model.frequency_scale, model.shape_scale
    if all(hasattr(base, k) for k in ("nodes_m", "elements", "assemble_matrices", "mode_matrix", "locator")):
        return base, fs, ss
    return None


def warn_no_mesh(model) -> None:
    """Say once per model type that its springs go without static correction (no mesh)."""
    name = type(model).__name__
    if name in _WARNED:
        return
    _WARNED.add(name)
    if hasattr(model, "rigid_mode_shapes_at"):
        log.warning("a %s has no mesh: its contact springs hold its rigid-body and elastic modes without "
                    "static correction (attachment vectors), so stiff springs come out stiffer (against "
                    "the dry mesh path: 0.6 %% for FillLevel-v0's grasp of the empty mug, 12 %% with "
                    "1e7 N/m table springs under a small can)", name)
    else:
        log.warning("a %s has no mesh: its contact springs act on its elastic modes only, without "
                    "rigid-body modes or static correction (a grounded 1e7 N/m spring can be ~10 %% off)",
                    name)


def spring_modes(model, contacts):
    """``model`` with the springs of ``contacts`` (a :class:`SpringModes`), or ``model``
    itself when no contact is a spring.  Cached per (model, springs)."""
    contacts = list(contacts)
    springs = contact_springs(model, contacts)
    if not springs:
        return model
    # the reference path (static_correction.REUSE_UNIT_LOADS False) is kept apart from the fast one
    key = (IdentityKey(model), tuple((*p.tolist(), *n.tolist(), kn, kt) for p, n, kn, kt in springs),
           static_correction.REUSE_UNIT_LOADS, static_correction.GRAM_PRODUCTS)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    flex = flexible_base(model)
    at = np.array([c.position_m for c in contacts]).reshape(-1, 3)
    if flex is None:
        warn_no_mesh(model)
        out = SpringModes(model, springs, also_at=at)
    else:
        base, fs, ss = flex
        out = SpringModes(model, springs, fs, ss, contact_flexibility(base), also_at=at)
    return _CACHE.put(key, out)


def attachment_at(model, attachment, points_m) -> np.ndarray:
    """An :class:`~sensors.modal.static_correction.AttachmentBasis` of ``model``'s mesh at
    points (n, 3): (n, 3, a), interpolated as :func:`~sensors.modal.static_correction.nodal_at` (only the rows it needs)."""
    p = check_points_m(points_m)
    tet, bary = model.locator.locate(p)
    N = shape_functions(bary, model.element)
    nodes = model.elements[tet]
    return np.einsum("pa,paxr->pxr", N, attachment.nodal(nodes.ravel()).reshape(*nodes.shape, 3, -1))


def _ritz_parts(modes):
    """``(free coefficients (6 + r, r_c), attachment basis or None, its coefficients (a, r_c))``
    of a model's coordinates in the common Ritz basis [R, U]."""
    if hasattr(modes, "split"):      # SpringModes, or a grasp coupled to other bodies (modal.touching)
        n_rigid, r, a = modes.split
        free = np.zeros((6 + r, modes.V.shape[1]))
        free[6 - n_rigid:] = modes.V[:n_rigid + r]
        return free, modes.attachment, modes.V[n_rigid + r:]
    r = len(modes.angular_frequencies_rad_s)
    return np.vstack([np.zeros((6, r)), np.eye(r)]), None, None


def _root(model):
    if hasattr(model, "split"):
        return model.base
    # a grasped object with the objects it touches (modal.touching): its state is the object's
    return getattr(model, "grasped_model", model)


def modal_transfer(from_modes, to_modes) -> np.ndarray:
    """T (r_to, r_from): coordinates of ``to_modes`` of the motion ``from_modes`` describes,
    q_to = T q_from, by the M-orthogonal projection (both mass-normalised: T = Phi_to^T M
    Phi_from).  The identity for the same modes; both must be of the same object."""
    if from_modes is to_modes:
        return np.eye(len(to_modes.angular_frequencies_rad_s))
    if _root(from_modes) is not _root(to_modes):
        raise ValueError("modal_transfer: the two modal models are not of the same object")
    fa, pa, ca = _ritz_parts(from_modes)
    fb, pb, cb = _ritz_parts(to_modes)
    T = fb.T @ fa
    if pa is not None and pb is not None and pa.size and pb.size:
        T += cb.T @ pb.mass_product(pa) @ ca   # Psi M-norms are material-invariant (see SpringModes)
    # the bodies a grasped object touches, when both sides share them (modal.touching)
    partners = getattr(to_modes, "partner_transfer", None)
    if partners is not None:
        T = T + partners(from_modes)
    return T
