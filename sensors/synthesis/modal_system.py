"""Modal synthesis: the object's response at the microphone to a sampled force.

Solves  q'' + C_m q' + Lambda q = U_d^T f(t)  for the mass-normalised modal coordinates q and
reads  y = n_mic . U_mic q  (displacement; velocity and acceleration as options).

State
-----
The state is scaled to x = [Omega q; q'] (Omega = diag(w)), so that

    x' = A x + B u,   A = [[0, Omega], [-Omega, -C_m]],   B = [0; b],

and the modal energy is E = |x|^2 / 2.  Undamped, A is skew-symmetric (normal, eigenvectors
perfectly conditioned); damping C_m >= 0 makes d|x|^2/dt = -2 q'^T C_m q' <= 0, so the exact
one-step map is a contraction in this norm.  ``sensors.synthesis.lti`` discretises it
exactly for a piecewise-linear force (first-order hold) in complex modes, with a dense
fallback for ill-conditioned eigenvectors.

Methods
-------
``"exact"`` keeps the coupled damping matrix (complex modes of the whole system; from 40
modes with a low-rank contact factor through ``sensors.synthesis.low_rank_modes``).
``"diagonal"`` keeps only diag(C_m) (the usual approximation): independent 2x2 systems with
closed-form eigenvalues; modes near critical damping use the dense fallback.

Fast paths (change no result beyond rounding)
---------------------------------------------
- modes decoupled (through C_m) from every mode that the drive reaches, or from every mode the
  microphone sees, contribute exactly nothing and are dropped;
- zero force and zero initial state -> zeros without building anything.
Modes at or above Nyquist are dropped by default (``max_frequency_hz``): a sampled signal
cannot carry them, and their only effect on the samples is a quasi-static compliance far below
the band (reported by ``benchmarks/synthesis.py`` under mode truncation).

Contacts are springs and dampers (``contact_model="spring_damper"``, the default): the system
of a contact set is built on the object's modes with the contacts' springs
(:mod:`sensors.modal.spring_modes`: rigid-body, elastic and attachment modes).  The paper's
model, ``contact_model="damping"``, keeps the free modes and only damps them.

Contacts may change over time (piecewise-constant contact sets): each segment gets its own
system and the full modal state is carried across the switch (projected onto the next set's
modes where the springs change them, :func:`sensors.modal.spring_modes.modal_transfer`).  For a static grasp under a
periodic force, :func:`periodic_response` gives the exact periodic steady state.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey
from ..modal.contact import Contact
from ..modal.damping import check_groups_on_surface, check_on_surface, modal_damping_matrix, modal_damping_parts
from ..modal.spring_modes import modal_transfer, spring_modes
from ..modal.touching import TouchingObjects, coupled_grasp_modes
from .low_rank_modes import low_rank_modes
from .lti import DensePart, DiscreteSystem, EigenPart, force_signal, lti_parts, one_blas_thread

__all__ = ["CONTACT_MODELS", "ModalSystem", "contact_modal_model", "modal_response", "periodic_response",
           "modal_state_energy", "modal_state_matrix", "transfer_state"]

#: How contacts act on the object: ``"spring_damper"`` (default; stiffness and damping) or
#: ``"damping"`` (the paper's model: contact damping on the free modes).
CONTACT_MODELS = ("spring_damper", "damping")

_OUTPUTS = ("displacement", "velocity", "acceleration")
_METHODS = ("exact", "diagonal")
_HOLDS = ("foh", "zoh")
# Relative size below which a gain or a coupling counts as exactly zero (rounding level).
_NEGLIGIBLE = 1e-13
# A moving grasp switches back and forth between a few contact sets (about half of a
# ContactFormation-v0 stream's transfers repeat a pair): T kept per (from, to) modes.
_TRANSFERS: LRU = LRU(CACHE_SIZES["stream.transfers"])
# The low-rank complex-mode path (sensors.synthesis.low_rank_modes) pays off from about this many
# modes, while the contact factor has at most this many rows per mode (benchmarks/synthesis.py).
LOW_RANK_MIN_MODES = 40
LOW_RANK_MAX_RATIO = 0.5
#: Whether ``ModalSystem.build`` checks the drive/mic point and the contacts on the surface in
#: one query and evaluates the mode shapes at all of them in one call (True, fast), or checks
#: and evaluates once per consumer (False, the reference: drive/mic, contacts, the damping).  A
#: point's distance and shapes do not depend on the batch it is asked in, so both give the same
#: bytes (``tests/test_modal_system_points.py``).  Read at each call.
ONE_POINT_PASS = True


def _as_contacts(contacts) -> list[Contact]:
    out = list(contacts)
    for c in out:
        if not isinstance(c, Contact):
            raise TypeError(f"expected sensors.Contact, got {type(c).__name__}")
    return out


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be a finite 3-vector, got {v}")
    length = float(np.linalg.norm(v))
    if abs(length - 1.0) > 1e-4:
        raise ValueError(f"{what} must be a unit vector (|n| = {length:.6g})")
    return v / length


def _point(p, what: str) -> np.ndarray:
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be a finite 3-vector [m], got {p}")
    return p


def contact_modal_model(model, contacts, contact_model: str = "spring_damper"):
    """The modes a contact set's system is built on: ``model`` with the contacts' springs
    (``"spring_damper"``; ``model`` itself when no contact is a spring) or ``model``
    (``"damping"``)."""
    if contact_model not in CONTACT_MODELS:
        raise ValueError(f"contact_model must be one of {CONTACT_MODELS}, got {contact_model!r}")
    if isinstance(model, TouchingObjects):
        if contact_model != "spring_damper":
            raise ValueError("a TouchingObjects couples bodies through contact springs (contact_model="
                             "'spring_damper'); for 'damping' pass the object's own model and all its contacts")
        return coupled_grasp_modes(model, contacts)
    return spring_modes(model, contacts) if contact_model == "spring_damper" else model


def transfer_state(x, from_modes, to_modes) -> np.ndarray:
    """The scaled state x = [w q; q'] of ``from_modes`` as a state of ``to_modes`` (the same
    object under another contact set); ``x`` itself when the modes are the same.

    Both halves are mapped by T = Phi_to^T M Phi_from (the M-orthogonal projection,
    :func:`sensors.modal.spring_modes.modal_transfer`): the velocity field carries over, and so
    does the displacement of every mode the switch leaves unchanged.  A mode whose frequency
    the new springs change keeps its strain energy rather than its amplitude: a contact forms
    unstretched, so a spring that engages on a displaced point (a bar rocking on its pads
    touching the table) must not store 1/2 k u^2 out of nothing, which in a stream switching
    every physics step would pump energy into the object.  As ||T|| <= 1 (orthonormal bases),
    no switch adds energy.
    """
    if from_modes is to_modes or x is None:
        return x
    ra = len(from_modes.angular_frequencies_rad_s)
    x = np.asarray(x, float).reshape(2, ra)
    T = _TRANSFERS.get_or_build((IdentityKey(from_modes), IdentityKey(to_modes)),
                                lambda: modal_transfer(from_modes, to_modes))
    return np.concatenate([T @ x[0], T @ x[1]])


def modal_state_energy(x: np.ndarray) -> np.ndarray:
    """Modal energy |x|^2 / 2 [J] of a scaled state x = [w q; q'] (along the last axis).

    With mass-normalised modes (U^T M U = I) this is the object's kinetic plus strain energy
    in the kept modes.
    """
    x = np.asarray(x)
    return 0.5 * np.sum(x * x, axis=-1)


# ----------------------------------------------------------------------------------------
# the system for one contact set
# ----------------------------------------------------------------------------------------

@dataclass
class _Setup:
    w: np.ndarray      # (r,) angular frequencies of the kept modes
    C: np.ndarray      # (r, r) damping
    b: np.ndarray      # (r,) modal input gain per newton
    o: np.ndarray      # (r,) modal output gain (displacement per modal coordinate)
    d: np.ndarray | None = None  # (r,) Rayleigh part of C and (k, r) the factor of its
    Q: np.ndarray | None = None  # contact part, C = diag(d) + Q^T Q, when C is not given


class ModalSystem(DiscreteSystem):
    """The discretised modal system for one contact set, drive point and microphone.

    Build once per grasp (``ModalSystem.build``), then call :meth:`response` as often as
    needed (the evaluation is :class:`sensors.synthesis.lti.DiscreteSystem`'s).  State vectors
    are the scaled state x = [w q; q'] of ALL the model's modes (length 2 r_model); modes
    dropped by a fast path simply keep a zero state and are not simulated: build with the
    same ``initial_state`` (and ``keep_unobservable``) to keep modes that only an initial
    state excites.
    """

    def __init__(self, parts, n_modes: int, kept: np.ndarray, sample_rate_hz: float, hold: str, modes=None):
        super().__init__(parts, 2 * n_modes, sample_rate_hz, hold)
        self.n_modes = n_modes
        self.kept = kept  # indices of modes that take part in the synthesis
        self.modes = modes  # the modes its state is in (the model, or the model with contact springs)

    @classmethod
    def build(cls, model, sample_rate_hz: float, drive_point_m, drive_normal, mic_point_m, mic_normal,
              contacts: Sequence[Contact] = (), method: str = "exact",
              output: str = "displacement", hold: str = "foh",
              max_frequency_hz: float | None = None, damping=None,
              keep_unobservable: bool = False, initial_state=None, contact_model: str = "spring_damper",
              keep_all_modes: bool = False) -> "ModalSystem":
        """Discretise the modal system of ``model`` at ``sample_rate_hz`` [Hz].

        The drive force pushes INTO the object at ``drive_point_m`` (along ``-drive_normal``,
        as a finger does); the output is the motion of the object at ``mic_point_m`` along
        ``+mic_normal`` (outward).  ``damping`` overrides C_m (r x r) if given.
        ``keep_unobservable`` keeps modes the microphone cannot see (needed when the state
        is carried into a later contact set); modes with a nonzero ``initial_state`` count as
        reached by the drive; ``keep_all_modes`` keeps every mode below ``max_frequency_hz``
        (a system whose state is carried into any later contact set).  ``contact_model``: see
        :data:`CONTACT_MODELS`; with springs the state is in the coupled modes
        (:attr:`modes`, ``transfer_state`` maps states between contact sets).
        """
        if method not in _METHODS:
            raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
        if output not in _OUTPUTS:
            raise ValueError(f"output must be one of {_OUTPUTS}, got {output!r}")
        if hold not in _HOLDS:
            raise ValueError(f"hold must be one of {_HOLDS}, got {hold!r}")
        sample_rate_hz = float(sample_rate_hz)
        if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
            raise ValueError(f"sample_rate_hz must be a positive sample rate [Hz], got {sample_rate_hz}")
        dp, mp = _point(drive_point_m, "drive_point_m"), _point(mic_point_m, "mic_point_m")
        dn, mn = _unit(drive_normal, "drive_normal"), _unit(mic_normal, "mic_normal")
        contacts = _as_contacts(contacts)
        ends = np.array([dp, mp])
        at_contacts = np.array([c.position_m for c in contacts]).reshape(-1, 3)
        one_pass = ONE_POINT_PASS and damping is None
        if one_pass:
            check_groups_on_surface(model, [(ends, "drive/mic point"), (at_contacts, "contact")])
        else:
            check_on_surface(model, ends, "drive/mic point")
        if damping is None:  # a given C_m is of the model's own modes: no springs then
            if not one_pass:
                check_on_surface(model, at_contacts, "contact")
            model = contact_modal_model(model, contacts, contact_model)

        w_all = np.asarray(model.angular_frequencies_rad_s, dtype=float)
        r_all = len(w_all)
        if one_pass:   # the shapes at the drive/mic point and every contact, in one call
            shapes = np.asarray(model.mode_shapes_at(np.concatenate([ends, at_contacts])), dtype=float)
            Ush, contact_shapes = shapes[:2], shapes[2:]
        else:
            Ush, contact_shapes = np.asarray(model.mode_shapes_at(ends), dtype=float), None  # (2, 3, r)
        if damping is None:
            d_all, Q_all = modal_damping_parts(model, contacts, contact_shapes=contact_shapes)
            C_all = np.diag(d_all) + Q_all.T @ Q_all
        else:
            d_all, Q_all, C_all = None, None, np.asarray(damping, float)
        b_all = -dn @ Ush[0]
        o_all = mn @ Ush[1]
        fmax = sample_rate_hz / 2.0 if max_frequency_hz is None else float(max_frequency_hz)
        kept = np.flatnonzero(w_all < 2 * np.pi * fmax)
        excited = np.full(r_all, bool(keep_all_modes))
        keep_unobservable = keep_unobservable or bool(keep_all_modes)
        if initial_state is not None and not keep_all_modes:
            x0 = np.asarray(initial_state, dtype=float).reshape(2, r_all)
            excited = np.any(x0 != 0, axis=0)
        kept = _relevant_modes(kept, C_all, b_all, o_all, keep_unobservable, excited)
        su = _Setup(w_all[kept], C_all[np.ix_(kept, kept)], b_all[kept], o_all[kept],
                    None if d_all is None else d_all[kept], None if Q_all is None else Q_all[:, kept])
        parts = _build_parts(su, method, output, 1.0 / sample_rate_hz, hold)
        # map part-local state indices (over kept modes) to the global scaled state
        glob = np.concatenate([kept, r_all + kept])
        for p in parts:
            p.idx = glob[p.idx]
        system = cls(parts, r_all, kept, sample_rate_hz, hold, model)
        # what a load on the kept modes needs (sensors.synthesis.passive: x' = A x + [0; p]),
        # in the modes the state is in (``model``: with springs, the coupled modes)
        system.kept_modal = (su.w, su.C)
        return system


def _relevant_modes(kept, C, b, o, keep_unobservable, excited):
    """Drop groups of modes (connected through C) that the drive cannot reach or the mic
    cannot see: they contribute exactly zero."""
    if len(kept) == 0:
        return kept
    Ck = C[np.ix_(kept, kept)]
    off = np.abs(Ck - np.diag(np.diag(Ck)))
    scale = np.abs(Ck).max()
    link = off > _NEGLIGIBLE * scale
    np.fill_diagonal(link, True)
    if link.all(axis=1).any():  # a mode coupled to every other (any grasp's contacts): one group
        ncomp, lab = 1, np.zeros(len(kept), int)
    else:
        from scipy.sparse.csgraph import connected_components  # ~0.1 s to import: first use only

        ncomp, lab = connected_components(link, directed=False)
    bk, ok = np.abs(b[kept]), np.abs(o[kept])
    reach = np.zeros(ncomp, bool)
    seen = np.zeros(ncomp, bool)
    np.logical_or.at(reach, lab, (bk > _NEGLIGIBLE * max(bk.max(), 1e-300)) | excited[kept])
    np.logical_or.at(seen, lab, ok > _NEGLIGIBLE * max(ok.max(), 1e-300))
    keep = reach[lab] & (seen[lab] | keep_unobservable)
    return kept[keep]


def modal_state_matrix(w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """State matrix A = [[0, Omega], [-Omega, -C]] of q'' + C q' + Omega^2 q = 0 in the scaled
    state x = [Omega q; q'] (see the module docstring): the one place it is built."""
    w = np.asarray(w, dtype=float)
    r = w.size
    A = np.zeros((2 * r, 2 * r))
    A[:r, r:] = np.diag(w)
    A[r:, :r] = -np.diag(w)
    A[r:, r:] = -np.asarray(C, dtype=float)
    return A


def _state_matrices(su: _Setup, output: str):
    r = len(su.w)
    A = modal_state_matrix(su.w, su.C)
    B = np.concatenate([np.zeros(r), su.b])
    if output == "displacement":
        Cout, D = np.concatenate([su.o / su.w, np.zeros(r)]), 0.0
    elif output == "velocity":
        Cout, D = np.concatenate([np.zeros(r), su.o]), 0.0
    else:  # q'' = -Omega (Omega q) - C q' + b u
        Cout, D = np.concatenate([-su.o * su.w, -(su.o @ su.C)]), float(su.o @ su.b)
    return A, B, Cout, D


def _build_parts(su: _Setup, method: str, output: str, T: float, hold: str):
    r = len(su.w)
    if r == 0:
        return []
    if method == "diagonal":
        su = _Setup(su.w, np.diag(np.diag(su.C)), su.b, su.o)
        return _diagonal_parts(su, output, T, hold)
    A, B, Cout, D = _state_matrices(su, output)
    if su.Q is not None and r >= LOW_RANK_MIN_MODES and su.Q.shape[0] <= LOW_RANK_MAX_RATIO * r:
        with one_blas_thread():
            modes = low_rank_modes(su.w, su.d, su.Q)
        if modes is not None:
            lam, V, W = modes
            lam = np.minimum(lam.real, 0.0) + 1j * lam.imag  # passive, as in lti_parts
            return [EigenPart(np.arange(2 * r), lam, V, W, B, Cout, D, T, hold)]
    # diag(1, -1) A is symmetric when C is: the input gains from the modes' S-orthogonality
    return lti_parts(A, B, Cout, D, T, hold, passive=True, signature=np.repeat([1.0, -1.0], r))


def _diagonal_parts(su: _Setup, output: str, T: float, hold: str):
    """Closed-form eigen-decomposition of each 2x2 block [[0, w], [-w, -c]]."""
    r = len(su.w)
    w, c = su.w, np.diag(su.C)
    disc = np.sqrt((c * c - 4 * w * w).astype(complex))
    l1, l2 = (-c + disc) / 2, (-c - disc) / 2
    near_critical = np.abs(l1 - l2) < 1e-5 * (np.abs(l1) + np.abs(l2))
    good = np.flatnonzero(~near_critical)
    parts = []
    A, B, Cout, D = _state_matrices(su, output)
    if good.size:
        # one eigenvalue for an under-damped pair (Im > 0), both for an over-damped mode
        over = good[np.abs(disc[good].imag) == 0]
        ev_mode = np.concatenate([good, over])
        ev_lam = np.concatenate([np.where(l1[good].imag >= 0, l1[good], l2[good]), l2[over]])
        ev_other = np.concatenate([np.where(l1[good].imag >= 0, l2[good], l1[good]), l1[over]])
        K = len(ev_mode)
        V = np.zeros((2 * r, K), complex)
        Vinv = np.zeros((K, 2 * r), complex)
        kk = np.arange(K)
        wm = w[ev_mode]
        # eigenvector [w; lambda]; inverse rows from the 2x2 inverse of [[w, w], [l, l']]
        V[ev_mode, kk] = wm
        V[r + ev_mode, kk] = ev_lam
        det = wm * (ev_other - ev_lam)
        Vinv[kk, ev_mode] = ev_other / det
        Vinv[kk, r + ev_mode] = -wm / det
        idx = np.arange(2 * r)
        parts.append(EigenPart(idx, ev_lam, V, Vinv, B, Cout, 0.0, T, hold))
    bad = np.flatnonzero(near_critical)
    if bad.size:
        sub = np.concatenate([bad, r + bad])
        parts.append(DensePart(sub, A[np.ix_(sub, sub)], B[sub], Cout[sub], 0.0, T, hold))
    if D != 0.0:
        parts[0].D = D
    return parts


# ----------------------------------------------------------------------------------------
# public functions
# ----------------------------------------------------------------------------------------

def _schedule(contacts, sample_rate_hz: float, n: int):
    """[(start_sample, [Contact...]), ...] from a contact list or a (time_s, contacts) list."""
    items = list(contacts)
    if all(isinstance(c, Contact) for c in items):
        return [(0, items)]
    sched = []
    for it in items:
        if not (isinstance(it, (tuple, list)) and len(it) == 2):
            raise TypeError("contacts must be a sequence of Contact or of (start_time_s, contacts)")
        t, cs = it
        t = float(t)
        if not np.isfinite(t):
            raise ValueError("contact switch time must be finite")
        sched.append((int(round(t * sample_rate_hz)), _as_contacts(cs)))
    starts = [s for s, _ in sched]
    if not sched or starts[0] != 0 or any(b <= a for a, b in zip(starts, starts[1:])):
        raise ValueError("contact schedule must start at t = 0 s with increasing switch times")
    return [(s, cs) for s, cs in sched if s < n] or [(0, sched[0][1])]


def modal_response(model, force_n, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                   contacts=(), method: str = "exact", output: str = "displacement",
                   hold: str = "foh", max_frequency_hz: float | None = None,
                   initial_state=None, contact_model: str = "spring_damper") -> np.ndarray:
    """Object response at the microphone to a sampled force, zero initial state.

    Parameters
    ----------
    model : modal model (``angular_frequencies_rad_s``, ``material``, ``mode_shapes_at``,
        optionally ``surface_distance_m``).
    force_n : (N,) force [N] at the drive point, pushing INTO the object (along
        ``-drive_normal``); piecewise linear between samples (``hold="foh"``, exact) or
        held constant over each sample (``"zoh"``).
    sample_rate_hz : sample rate [Hz].
    drive_point_m, drive_normal, mic_point_m, mic_normal : object frame; normals are unit
        outward normals.
    contacts : sequence of :class:`Contact` (static), or a schedule
        ``[(start_time_s, [Contact, ...]), ...]`` starting at 0 s: piecewise-constant contact
        sets, the modal state carried across each switch.
    method : ``"exact"`` (coupled damping, complex modes) or ``"diagonal"`` (diag(C_m) only).
    output : ``"displacement"`` [m] (default, the paper's choice), ``"velocity"`` [m/s] or
        ``"acceleration"`` [m/s^2] of the object at the mic point along ``+mic_normal``.
    max_frequency_hz : drop modes at or above this frequency (default: Nyquist, sample_rate_hz/2).
    initial_state : optional scaled state [w q; q'] (2 r,) at the first sample, in the modes
        of the first contact set (:func:`contact_modal_model`).
    contact_model : ``"spring_damper"`` (default) or ``"damping"`` (:data:`CONTACT_MODELS`).

    Returns
    -------
    (N,) float64, one output sample per force sample.
    """
    u = force_signal(force_n)
    n = len(u)
    if n == 0:
        return np.zeros(0)
    sample_rate_hz = float(sample_rate_hz)
    sched = _schedule(contacts, sample_rate_hz, n)
    if not np.any(u != 0) and (initial_state is None or not np.any(initial_state)):
        # fast path, but still validate the geometry so bad input fails the same way
        for _, cs in sched:
            modal_damping_matrix(model, cs)
        check_on_surface(model, np.array([_point(drive_point_m, "drive_point_m"),
                                          _point(mic_point_m, "mic_point_m")]), "drive/mic point")
        _unit(drive_normal, "drive_normal"), _unit(mic_normal, "mic_normal")
        return np.zeros(n)
    y = np.zeros(n)
    x = initial_state
    modes = None
    bounds = [s for s, _ in sched] + [n]
    for i, (s, cs) in enumerate(sched):
        e = bounds[i + 1]
        last = i == len(sched) - 1
        if modes is not None:
            x = transfer_state(x, modes, contact_modal_model(model, cs, contact_model))
        sysm = ModalSystem.build(model, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                                 cs, method=method, output=output, hold=hold,
                                 max_frequency_hz=max_frequency_hz, keep_unobservable=not last,
                                 initial_state=x, contact_model=contact_model)
        modes = sysm.modes
        y[s:e] = sysm.response(u[s:e], x)
        if not last:
            # the force is continuous through the switch sample e: propagate over [s, e]
            x = sysm.final_state(u[s:e + 1], x)
    return y


def periodic_response(model, force_period_n, sample_rate_hz, drive_point_m, drive_normal, mic_point_m,
                      mic_normal, contacts=(), method: str = "exact",
                      output: str = "displacement", hold: str = "foh",
                      max_frequency_hz: float | None = None, contact_model: str = "spring_damper",
                      bandlimited: bool = False) -> np.ndarray:
    """Exact periodic steady state (one period) for a static grasp under a looping force.

    Same arguments as :func:`modal_response`; ``force_period_n`` is one period of the
    looping force.  Equals the time-domain response once the transient has decayed.
    ``bandlimited``: the force is the band-limited signal of the hold's interpolant without
    its images (``DiscreteSystem.periodic_response``; prefilter the samples with
    ``sensors.synthesis.lti.bandlimited_samples`` for the band-limited signal through them).
    """
    sysm = ModalSystem.build(model, sample_rate_hz, drive_point_m, drive_normal, mic_point_m, mic_normal,
                             contacts, method=method, output=output, hold=hold,
                             max_frequency_hz=max_frequency_hz, contact_model=contact_model)
    return sysm.periodic_response(force_period_n, bandlimited)
