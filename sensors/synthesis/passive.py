"""Passive sound: impacts, knocks and sliding excite the object by themselves (issue 26, item 4).

The active drive is not the only force on the object.  Every contact pushes on it, and when a
contact force changes (a touch-down on the table, a knock against another object, a contact
lifting off, a slide moving the contact point) the change enters the modal equations as a
force at the contact point, on top of the fingertip drive:

    q'' + C q' + Lambda q = b u(t) + p(t),     p(t) = sum_c U(x_c)^T F_c(t)

(mass-normalised shapes U, F_c the full force vector the contact exerts ON the object: normal
plus friction, object frame).  What a stream knows of the contacts is one :class:`ContactLoads`
per span (one per contact read of a MuJoCo scene), so p(t) is modelled as:

- constant while the contacts do not change (a resting object is in equilibrium: only
  changes make sound; a stream counts an object's loads from its first closed grasp, when it
  starts following the object's ringing);
- a change of the forces of contacts that persist is linear over the span (linear
  interpolation between MuJoCo's steps: it resolves nothing faster);
- an impact (a contact whose partner body did not press in the previous read: a touch-down,
  a knock, a fingertip closing on the object) and a stick-slip event (below) are sharper than a
  physics step: their load rises linearly over ``rise_time_s`` from the start of the span (at
  most the span).  A ramp of duration tau has the spectrum of a step times sinc(f tau): 0.2 ms
  (default) is the contact time of a hard knock (Hertz contact of plastic, wood or metal at
  the speeds of a robot hand: 0.05-0.5 ms); MuJoCo resolves an impact only to its physics step
  (2 ms), so the rise time is a modelling choice, recorded in the stream's metadata.

Sliding (roughness and stick-slip): a contact whose friction force is at the friction cone
(|F_t| >= ``SLIDING_CONE_RATIO`` mu F_n, MuJoCo's contact force frame) slides.  Its friction
force then does not stay smooth: asperities catch and release (stick-slip).  Each contact
read of a sliding contact adds roughness xi F_t to its friction force F_t, xi ~ N(0, 1) from
the passive model's own generator (seeded: streams stay reproducible), as a sharp event (it
replaces the previous read's fluctuation): every read of a slide is one micro-slip event of
relative size ``roughness``.  Sliding also moves the contact point, which changes
U(x_c)^T F_c by itself (smoothly).

The response to such a load is exact (no discretisation error): over each piece where the
load is affine in time the particular solution of x' = A x + [0; p(t)] is affine too,
x_p = alpha + beta t (one solve with A each, :func:`ramp_particular`), and the stream adds it
to the exact solution of the drive from the shifted state.

Contact springs (``contact_model="spring_damper"``): the state of each contact set is in its
coupled modes (rigid-body, elastic and attachment parts, ``sensors.modal.spring_modes``), so
U above are the shapes of the modes of the system that runs: a stream keeps each read's
forces (:class:`LoadRead`) and projects them onto each system's modes.  At a change of
contact set the state is carried relative to the load's static state, with the same forces
on both sides (those of the latest read; a load change in the span ramps in after it):

    x_new = x_eq,new + T (x - x_eq,old),     x_eq = [Omega^-1 p; 0] (each set's own p, Omega),

T the M-projection of ``sensors.synthesis.modal_system.transfer_state``.  The ringing is
carried as without loads (no switch adds energy), and a constant load makes no sound at a
contact change, as under the damping-only model (where T = I and x_eq does not change);
only the displacement output's static deflection steps to the new springs' (transferring
x_eq itself would ring the object towards the new deflection at every contact change).
What it leaves out: a MuJoCo stream reads the contacts only when their signature moves beyond
its ``ContactTolerance`` (``aas_gym.sim_stream``), so force changes below it are not heard;
the displacement output keeps the quasi-static deflection under a changed load (a step of
about 1e-5 of full scale when a bar leaves the table), which an AC-coupled piezo would let
decay; loads on modes above Nyquist (dropped from the system) are not simulated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from .caches import IdentityKey
from .lti import one_blas_thread, scipy_linalg
from .modal_system import modal_state_matrix
from .partner_loads import load_shapes

__all__ = ["ContactLoads", "LoadRead", "LoadSolver", "PassiveSound", "SLIDING_CONE_RATIO", "modal_load",
           "project_reads", "ramp_particular"]

#: A contact slides when its friction force is at least this fraction of mu times its normal
#: force (MuJoCo's soft contacts reach the cone only approximately while sliding).
SLIDING_CONE_RATIO = 0.95


@dataclass(frozen=True, eq=False)
class ContactLoads:
    """The forces the touching bodies exert on an object during one span (object frame).

    Parameters
    ----------
    positions_m : (n, 3) contact points [m].
    normals : (n, 3) unit outward surface normals of the object there.
    forces_n : (n, 3) force ON the object at each point (normal plus friction) [N].
    sliding : (n,) bool, the contact slides (friction at the cone); default none.
    impact : (n,) bool, the contact just touched down (its partner did not press before);
        default none.
    bodies : (n,) names of the bodies exerting the forces (default: none named).  A load
        from a body the object is coupled to (``sensors.modal.TouchingPartner.name``) acts on
        that body too, equal and opposite (:mod:`sensors.synthesis.partner_loads`).
    """

    positions_m: np.ndarray
    normals: np.ndarray
    forces_n: np.ndarray
    sliding: np.ndarray | None = None
    impact: np.ndarray | None = None
    bodies: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = np.array(self.positions_m, dtype=float).reshape(-1, 3)
        n = np.array(self.normals, dtype=float).reshape(-1, 3)
        f = np.array(self.forces_n, dtype=float).reshape(-1, 3)
        if not (p.shape == n.shape == f.shape):
            raise ValueError(f"ContactLoads: {len(p)} points, {len(n)} normals and {len(f)} forces")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n)) and np.all(np.isfinite(f))):
            raise ValueError("ContactLoads positions_m, normals and forces_n must be finite")
        flags = {}
        for name in ("sliding", "impact"):
            v = getattr(self, name)
            v = np.zeros(len(p), bool) if v is None else np.array(v, bool).reshape(-1)
            if v.shape != (len(p),):
                raise ValueError(f"ContactLoads: {len(p)} points but {v.size} {name} flags")
            flags[name] = v
        names = np.full(len(p), "", dtype=object) if self.bodies is None else np.array(self.bodies, dtype=object)
        names = names.reshape(-1)
        if names.shape != (len(p),):
            raise ValueError(f"ContactLoads: {len(p)} points but {names.size} body names")
        flags["bodies"] = np.array([str(b) for b in names], dtype=object)
        for name, v in (("positions_m", p), ("normals", n), ("forces_n", f), *flags.items()):
            v.setflags(write=False)
            object.__setattr__(self, name, v)

    def __len__(self) -> int:
        return len(self.positions_m)

    def friction_n(self) -> np.ndarray:
        """(n, 3) the tangential (friction) part of each force [N]."""
        fn = np.einsum("ij,ij->i", self.forces_n, self.normals)
        return self.forces_n - fn[:, None] * self.normals


@dataclass(frozen=True)
class PassiveSound:
    """How contact force changes and slides excite the object (see the module docstring).

    Parameters
    ----------
    rise_time_s : duration of the linear ramp of an impact or stick-slip event [s] (at most
        the span); other force changes ramp over the span.
    roughness : relative fluctuation of a sliding contact's friction force per contact read.
    seed : seed of the roughness generator.
    """

    rise_time_s: float = 2e-4
    roughness: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("rise_time_s", "roughness"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"PassiveSound.{name} must be finite and >= 0, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "seed", int(self.seed))

    def rise_samples(self, sample_rate_hz: float, span: int) -> int:
        """Samples of the ramp in a span of ``span`` samples (at least 1, at most the span)."""
        return int(min(span, max(1, round(self.rise_time_s * sample_rate_hz))))

    def to_dict(self) -> dict:
        return {"rise_time_s": self.rise_time_s, "roughness": self.roughness, "seed": self.seed}


class LoadRead:
    """One contact read of an object's loads with the roughness drawn for it (``rng`` is
    drawn once, here): the physical forces, projected onto any modes on demand.  With contact
    springs the modes an object's state is in change with its contact set while the forces do
    not, so a stream keeps the reads and projects them onto each system's modes."""

    def __init__(self, loads: ContactLoads | None, rng: np.random.Generator | None = None,
                 roughness: float = 0.0) -> None:
        self.loads = loads
        self.slip_n = None                    # (n, 3) the roughness added to each friction force [N]
        if loads is not None and len(loads) and roughness > 0 and rng is not None and loads.sliding.any():
            idx = np.flatnonzero(loads.sliding)
            self.slip_n = np.zeros((len(loads), 3))
            self.slip_n[idx] = (roughness * rng.standard_normal(idx.size))[:, None] * loads.friction_n()[idx]
        self._projections: LRU[tuple] = LRU(CACHE_SIZES["passive.load_projections"])

    def modal(self, modes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(total, impacts, fluctuation), each (r,), on ``modes`` (any ``ModalBasis``: the
        free model or its coupled modes with contact springs; mass-normalised shapes, so
        [N / sqrt(kg)]): sum_c U(x_c)^T (F_c + slip_c), the part of the impact contacts and
        the part of the roughness.  On the coupled modes of a grasp touching other objects,
        a load from a partner acts on it too, equal and opposite (:func:`load_shapes`)."""
        return self._projections.get_or_build(IdentityKey(modes), lambda: self._project(modes))

    def _project(self, modes):
        r = len(modes.angular_frequencies_rad_s)
        loads = self.loads
        if loads is None or len(loads) == 0:
            return np.zeros(r), np.zeros(r), np.zeros(r)
        return self.combine(load_shapes(modes, loads))

    def combine(self, U: np.ndarray):
        """(total, impacts, fluctuation) of :meth:`modal` from the read's load shapes U
        (n, 3, r) (:func:`load_shapes`)."""
        loads = self.loads
        F = np.array(loads.forces_n, dtype=float)
        slip = np.zeros_like(F) if self.slip_n is None else self.slip_n
        impacts = np.einsum("nd,ndr->r", np.where(loads.impact[:, None], F, 0.0), U)
        fluctuation = np.einsum("nd,ndr->r", slip, U)
        return np.einsum("nd,ndr->r", F, U) + fluctuation, impacts, fluctuation


def project_reads(reads, modes) -> None:
    """Projects every read of ``reads`` not yet projected onto ``modes`` (``None`` and
    empty reads skipped), the points of all through one :func:`load_shapes` call: at a new
    contact set a stream needs its base, previous and new read on the new modes, and one
    evaluation of the shapes at all their points costs about what one read's does (the
    shapes of a point do not depend on the others evaluated with it: equal to projecting
    each read alone to rounding, tests/test_passive_sound.py)."""
    key = IdentityKey(modes)
    todo = [r for r in dict.fromkeys(reads)
            if r is not None and r.loads is not None and len(r.loads) and key not in r._projections]
    if len(todo) < 2:
        return
    merged = ContactLoads(np.concatenate([r.loads.positions_m for r in todo]),
                          np.concatenate([r.loads.normals for r in todo]),
                          np.concatenate([r.loads.forces_n for r in todo]),
                          bodies=np.concatenate([r.loads.bodies for r in todo]))
    U = load_shapes(modes, merged)
    at = 0
    for r in todo:
        n = len(r.loads)
        r._projections.put(key, r.combine(U[at:at + n]))
        at += n


def modal_load(model, loads: ContactLoads | None, rng: np.random.Generator | None = None,
               roughness: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The modal force sum_c U(x_c)^T F_c (r,) of ``loads`` on ``model`` (mass-normalised
    shapes: [N / sqrt(kg)]) with each sliding contact's friction F_t fluctuating by
    roughness xi F_t (xi ~ N(0, 1) from ``rng``).  Returns (total, impacts, fluctuation): the
    whole load, the part of the impact contacts and the part of the fluctuations
    (:class:`LoadRead` keeps the draw to project it onto other modes too)."""
    return LoadRead(loads, rng, roughness).modal(model)


def ramp_particular(lu, p_start: np.ndarray, p_end: np.ndarray, ramp_s: float):
    """Particular solution x_p(t) = alpha + beta t (t [s] from the ramp's start) of
    x' = A x + [0; p(t)], the modal load p rising linearly from ``p_start`` to ``p_end`` over
    ``ramp_s`` seconds (equal loads: the equilibrium, beta = 0).  ``lu``: A's LU factors
    (``scipy.linalg.lu_factor``).  Returns (alpha, beta), each (2 r,)."""
    r = len(p_start)
    slope = (np.asarray(p_end, float) - np.asarray(p_start, float)) / ramp_s if ramp_s > 0 else np.zeros(r)
    beta = np.zeros(2 * r)
    if np.any(slope):
        rhs = np.zeros(2 * r)
        rhs[r:] = -slope
        beta = _lu_solve(lu, rhs)
    rhs = beta.copy()
    rhs[r:] -= p_start
    return _lu_solve(lu, rhs), beta


def _lu_solve(lu, rhs: np.ndarray) -> np.ndarray:
    """``scipy.linalg.lu_solve(lu, rhs)`` for one finite float64 right-hand side: the same
    LAPACK getrs call (the same bits) without the argument checks and batch dispatch, which
    cost ten times the solve of a stream's small modal system (3 per contact read)."""
    a, piv = lu
    getrs = scipy_linalg().lapack.get_lapack_funcs("getrs", (a, rhs))
    x, info = getrs(a, piv, rhs)
    if info != 0:
        raise ValueError(f"getrs: illegal value in argument {-info}")
    return x


class LoadSolver:
    """Particular solutions of one ``ModalSystem`` under a ramped modal load, in the system's
    full scaled state (modes the system does not simulate: 0)."""

    def __init__(self, system) -> None:
        w, C = system.kept_modal
        with one_blas_thread():
            self.lu = scipy_linalg().lu_factor(modal_state_matrix(w, C))
        self.kept = system.kept
        self.glob = np.concatenate([system.kept, system.n_modes + system.kept])
        self.size = 2 * system.n_modes

    def particular(self, p_start: np.ndarray, p_end: np.ndarray, ramp_s: float):
        """(alpha, beta) of :func:`ramp_particular` for loads over all the model's modes."""
        a, b = ramp_particular(self.lu, p_start[self.kept], p_end[self.kept], ramp_s)
        alpha, beta = np.zeros(self.size), np.zeros(self.size)
        alpha[self.glob], beta[self.glob] = a, b
        return alpha, beta
