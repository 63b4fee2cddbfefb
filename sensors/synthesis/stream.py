"""A continuously recording contact microphone while the grasp changes (issue 12).

The real rig plays its excitation in a loop and records without a break while the robot
moves.  :class:`AcousticStream` does the same in simulation: each call to
:meth:`AcousticStream.advance` synthesizes the samples of one span of time during which the
contact state (a :class:`GraspState`) was constant, e.g. one physics step, and carries every
piece of state into the next span:

- the excitation's phase (an absolute sample counter; the loop never restarts);
- the modal state of each object (scaled state x = [w q; q'], see ``sensors.synthesis.modal_system``),
  propagated exactly through every contact set, heard or not;
- the state of the lumped fingertip drive model (``sensors.FingertipModel``, linear while in
  contact) while the actuator fingertip stays on the object;
- the noise generator and the leak's phase.

Timing convention (as ``sensors.modal_response`` with a contact schedule): a span of n
samples starting at sample s covers the time interval [s, s + n) / sample_rate_hz.  Its system governs
the n steps from sample s to sample s + n; its microphone reads samples s .. s + n - 1.  The
drive force is piecewise linear between samples and continuous across span boundaries.

Open grasps: a parallel gripper opens both fingers together, so (as in
``sensors.simulate_recording``) the object is heard only while BOTH fingertips touch it with
a positive force.  Otherwise the microphone records leak and noise only, while the object
keeps ringing down unheard under the damping of the contacts it still has.  When the grasp
closes again the drive model starts from rest (the fingertip settles onto the object as a
new grasp; its free vibration in the air reaches the microphone through the gripper, which is
what the leak recording holds) and the microphone hears the object's decayed ringing plus
the new drive.

Reusing systems: discretising a contact set (damping matrix, complex modes) costs far more
than synthesizing a physics step with it, and MuJoCo's contact forces and points jitter a
little at every step.  :class:`SystemCache` therefore treats a contact set as unchanged when
it matches a cached one within a :class:`ContactTolerance` and reuses the cached system,
which was built from the FIRST contact set seen (see :class:`ContactTolerance` for what that
costs in accuracy).  ``ContactTolerance.exact()`` reuses only identical contact sets.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Any, Hashable

import numpy as np

from ..modal.contact import Contact
from ..signals.excitation import Excitation
from ..signals.features import spectral_features
from .fingertip import FingertipModel
from ..signals.leak import LeakRecording, align_leak, excitation_lag, leak_file_identity, load_leak
from .recording import mic_gain
from .lti import lti_system
from .modal_system import ModalSystem

__all__ = ["AcousticStream", "ContactTolerance", "GraspState", "SystemCache"]


# ----------------------------------------------------------------------------------------
# the contact state during one span
# ----------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class GraspState:
    """What touches the object during one span of a stream (object frame, see ``Contact``).

    Parameters
    ----------
    model : the object's modal model (anything ``ModalSystem.build`` accepts).
    actuator, mic : the actuator and microphone fingertip contacts, or ``None`` where that
        fingertip does not touch the object.
    others : further contacts (table, other objects); they damp the object.
    object_key : which object this is; its modal state is carried under this key.  Default:
        the identity of ``model``.
    """

    model: Any
    actuator: Contact | None = None
    mic: Contact | None = None
    others: tuple[Contact, ...] = ()
    object_key: Hashable | None = None

    def __post_init__(self) -> None:
        others = tuple(self.others)
        for c in (self.actuator, self.mic, *others):
            if c is not None and not isinstance(c, Contact):
                raise TypeError(f"contacts must be sensors.Contact, got {type(c).__name__}")
        object.__setattr__(self, "others", others)
        if self.object_key is None:
            object.__setattr__(self, "object_key", ("model", id(self.model)))
        object.__setattr__(self, "_table", None)

    def contact_table(self) -> np.ndarray:
        """Rows [position_m (3), normal (3), force_n, friction] of the actuator, mic (NaN
        rows where absent) and other contacts with a positive force; computed once."""
        if self._table is None:
            rows = [_row(self.actuator), _row(self.mic)]
            rows += [_row(c) for c in self.others if c.force_n > 0]
            object.__setattr__(self, "_table", np.array(rows))
        return self._table

    @property
    def closed(self) -> bool:
        """Both fingertips press on the object: the microphone hears it."""
        return (self.actuator is not None and self.mic is not None
                and self.actuator.force_n > 0 and self.mic.force_n > 0)

    def damping_contacts(self) -> list[Contact]:
        """Every contact that damps the object (fingertips that touch, then the others)."""
        return [c for c in (self.actuator, self.mic) if c is not None] + list(self.others)


def _row(c: Contact | None) -> np.ndarray:
    if c is None:
        return np.full(8, np.nan)
    return np.concatenate([c.position_m, c.normal, [c.force_n, c.friction]])


@dataclass(frozen=True)
class ContactTolerance:
    """When two contact sets count as the same system.

    Two contacts match when their positions differ by at most ``position_m``, their normals
    by at most ``normal_rad``, their frictions by at most 1e-9, and their forces by at most
    ``force_rtol * f_ref + force_atol_n``.  Sets match when the roles (actuator, mic) match
    and the other contacts match one to one (any order).

    Effect on accuracy: contact damping is linear in each contact's force, so a matched set
    has each contact's damping contribution within ``force_rtol`` (plus ``force_atol_n``
    times its per-newton damping) of the true one; the damping of a mode that is dominated by
    contact damping (contact-damped decay rates) is off by at most that fraction.  Positions
    enter through the mode shapes: the shift is a small fraction of the shortest bending
    wavelength in band (centimetres for the project's objects at 10 kHz), so the drive and
    microphone gains and the contact damping change by O(k dx) ~ 1e-2 or less at the
    defaults.  Normals enter through n n^T: a relative change of O(angle).  The defaults
    (2 %, 0.05 N, 0.2 mm, 0.02 rad) are above the per-step jitter of MuJoCo's forces in a
    steady grasp and well below the changes the issue asks to hear (lifting off a table,
    pressing on it, a fingertip leaving).
    """

    force_rtol: float = 0.02
    force_atol_n: float = 0.05
    position_m: float = 2e-4
    normal_rad: float = 0.02

    def __post_init__(self) -> None:
        for k in ("force_rtol", "force_atol_n", "position_m", "normal_rad"):
            v = getattr(self, k)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"ContactTolerance.{k} must be finite and >= 0, got {v!r}")

    @classmethod
    def exact(cls) -> "ContactTolerance":
        """Reuse a system only for identical contact sets."""
        return cls(0.0, 0.0, 0.0, 0.0)

    # matching ----------------------------------------------------------------------------
    def rows_match(self, a: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Per row of two contact tables (see ``GraspState.contact_table``): do they match?
        Absent contacts (NaN rows) match only absent ones."""
        absent_a, absent_r = np.isnan(a[:, 0]), np.isnan(ref[:, 0])
        with np.errstate(invalid="ignore"):
            ok = np.abs(a[:, :3] - ref[:, :3]).max(axis=1) <= self.position_m
            # |n - n_ref| = 2 sin(angle / 2) for unit vectors
            dn = np.sqrt(((a[:, 3:6] - ref[:, 3:6]) ** 2).sum(axis=1))
            ok &= dn <= 2 * np.sin(self.normal_rad / 2) + 1e-15
            ok &= np.abs(a[:, 6] - ref[:, 6]) <= self.force_rtol * ref[:, 6] + self.force_atol_n
            ok &= np.abs(a[:, 7] - ref[:, 7]) <= 1e-9
        return np.where(absent_a | absent_r, absent_a & absent_r, ok)

    def tables_match(self, a: np.ndarray, ref: np.ndarray) -> bool:
        """Same roles (actuator, mic rows 0 and 1) and a one-to-one match of the other
        contacts in any order (tried in the given order first; greedy otherwise)."""
        if a.shape != ref.shape:
            return False
        ok = self.rows_match(a, ref)
        if ok.all():
            return True
        if not ok[:2].all():
            return False
        free = list(range(2, len(ref)))
        for i in range(2, len(a)):
            hit = self.rows_match(np.repeat(a[i:i + 1], len(free), axis=0), ref[free])
            if not hit.any():
                return False
            del free[int(np.argmax(hit))]
        return True


# ----------------------------------------------------------------------------------------
# the cache of discretised systems
# ----------------------------------------------------------------------------------------

@dataclass
class _Entry:
    object_key: Hashable
    heard: bool                 # closed grasp (drive + mic) or ring-down only
    table: np.ndarray           # the contact set it was built from (GraspState.contact_table)
    system: ModalSystem


class SystemCache:
    """Discretised modal systems of recent contact sets, least recently used dropped first.

    ``size``, ``hits`` and ``misses`` are readable; ``max_size`` bounds it.
    """

    def __init__(self, tolerance: ContactTolerance, max_size: int = 16):
        if int(max_size) < 1:
            raise ValueError("max_size must be >= 1")
        self.tolerance = tolerance
        self.max_size = int(max_size)
        self.hits = 0
        self.misses = 0
        self._entries: list[_Entry] = []   # most recently used last

    @property
    def size(self) -> int:
        return len(self._entries)

    def lookup(self, key: Hashable, heard: bool, table: np.ndarray) -> ModalSystem | None:
        for i in range(len(self._entries) - 1, -1, -1):
            e = self._entries[i]
            if e.object_key == key and e.heard == heard and self.tolerance.tables_match(table, e.table):
                self._entries.append(self._entries.pop(i))
                self.hits += 1
                return e.system
        self.misses += 1
        return None

    def store(self, key: Hashable, heard: bool, table: np.ndarray, system: ModalSystem) -> None:
        self._entries.append(_Entry(key, heard, table, system))
        while len(self._entries) > self.max_size:
            self._entries.pop(0)


# ----------------------------------------------------------------------------------------
# per-object and drive state
# ----------------------------------------------------------------------------------------

@dataclass
class _ObjectState:
    model: Any
    x: np.ndarray | None             # scaled modal state at sample ``at`` (None: ``steady`` holds it)
    at: int
    geometry: tuple | None = None    # last closed grasp's (drive p, n, mic p, n): for ring-down builds
    last: GraspState | None = None   # contacts of its latest span (for gaps while not in the stream)
    system: ModalSystem | None = None  # the system of its latest heard samples ...
    settled: int = 0                 # ... and how many of them ran under a periodic drive
    steady: "_Steady | None" = None  # while in periodic steady state: the state is periodic


@dataclass
class _Drive:
    """The fingertip model in contact: state at sample ``at`` and the force there."""

    fingertip: FingertipModel
    act: ModalSystem                 # exciter force -> dynamic actuator contact force
    mic: ModalSystem                 # exciter force -> dynamic mic contact force (separation check)
    x: np.ndarray | None = field(default_factory=lambda: np.zeros(8))   # None: periodic
    at: int = 0
    run: int = 0                     # samples driven since it started from rest


@dataclass
class _Steady:
    """A linear system in periodic steady state under the looped excitation: its output and
    state repeat every period (the transient decayed to below exp(-SETTLE_E_FOLDS))."""

    output: np.ndarray               # one period, indexed by loop phase
    state0: np.ndarray               # the state at phase 0
    system: ModalSystem
    force: np.ndarray                # one period of the force driving it (phase-indexed)

    def state_at(self, s: int, P: int) -> np.ndarray:
        """The state at absolute sample ``s`` (propagated from phase 0)."""
        p = s % P
        if p == 0:
            return self.state0.copy()
        return self.system.final_state(self.force[:p + 1], self.state0)


#: A system counts as in periodic steady state after its slowest mode decayed this many
#: e-folds under the periodic drive: exp(-30) ~ 1e-13 of the transient is left.
SETTLE_E_FOLDS = 30.0


# ----------------------------------------------------------------------------------------
# the stream
# ----------------------------------------------------------------------------------------

class AcousticStream:
    """The simulated microphone, recording without a break while contacts change.

    Parameters
    ----------
    excitation : looped forever; sample k of the stream plays ``excitation.signal[k % P]``.
    fingertip : the lumped drive model.  Its grip force always follows the actuator
        contact's normal force; ``None``: ``FingertipModel()`` with the object's ``mass_kg``
        when the model has one (as ``simulate_recording`` does).
    leak : ``LeakRecording`` or its .npz path, recorded with this excitation; looped and
        aligned as ``sensors.align_leak`` aligns it for a recording that starts at phase 0
        with target lag ``leak_lag_samples``.  ``simulate_recording`` aligns its leak to the
        synthesized signal's excitation peak (its metadata ``leak_target_lag``); a stream
        cannot know that ahead of time and uses a fixed lag (0: the leak's excitation peak at
        the start of each loop period).
    noise_std, rng : white sensor noise (recorded units) from this ``numpy.random.Generator``
        (or seed), drawn sample by sample in stream order.
    output, method : as ``simulate_recording``.
    tolerance : when a contact set counts as unchanged (:class:`ContactTolerance`).
    cache_size : systems kept in :attr:`systems`.
    """

    def __init__(self, excitation: Excitation, fingertip: FingertipModel | None = None,
                 leak: LeakRecording | str | os.PathLike | None = None, noise_std: float = 0.0,
                 rng=None, output: str = "displacement", method: str = "exact",
                 tolerance: ContactTolerance | None = None, cache_size: int = 16,
                 leak_lag_samples: int = 0):
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
        if fingertip is not None and not isinstance(fingertip, FingertipModel):
            raise TypeError("fingertip must be a sensors.FingertipModel or None")
        if not np.isfinite(noise_std) or noise_std < 0:
            raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
        self.excitation = excitation
        self.sample_rate_hz = int(excitation.sample_rate_hz)
        self.fingertip = fingertip
        self.noise_std = float(noise_std)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.output = output
        self.method = method
        self.gain = mic_gain(output)
        self.systems = SystemCache(tolerance or ContactTolerance(), cache_size)
        self._period = excitation.signal          # one loop period of the excitation
        self._leak_file = None
        self._leak_period = None                  # the aligned leak, periodic with its own span
        if leak is not None:
            if not isinstance(leak, LeakRecording):
                self._leak_file = leak_file_identity(leak)
                leak = load_leak(leak)
            self._leak_period = _aligned_leak_cycle(leak, excitation, int(leak_lag_samples))
        self.leak_lag_samples = int(leak_lag_samples)
        self.sample_index = 0                     # absolute index of the next sample
        self._objects: dict[Hashable, _ObjectState] = {}
        self._current: Hashable | None = None
        self._drive: _Drive | None = None
        self._drive_systems: "OrderedDict[FingertipModel, tuple[ModalSystem, ModalSystem]]" = OrderedDict()
        self._steady: "OrderedDict[tuple, _Steady]" = OrderedDict()     # (system, drive) -> steady state
        self._drive_steadies: dict = {}           # fingertip model -> the drive's steady states
        self.steady_samples = 0                   # samples taken from a periodic steady state
        self._tips: dict[Hashable, FingertipModel] = {}
        self._last_grasp: GraspState | None = None
        self._last_resolved = None
        # features of the latest complete loop period
        P = excitation.period_samples
        self._window = np.zeros(P, dtype=np.float32)
        self._features: np.ndarray | None = None
        self._features_period = -1
        self._heard_window = np.zeros(P, dtype=bool)   # which samples of the period were heard
        self._features_heard = 0.0
        # facts for metadata
        self.fingertip_separated = False
        self.min_contact_force_n = np.inf
        self.heard_samples = 0

    # -- public ---------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Stream time of the next sample [s]."""
        return self.sample_index / self.sample_rate_hz

    def advance(self, n_samples, grasp: GraspState | None = None) -> np.ndarray:
        """Record the next span(s); returns their float32 samples.

        ``advance(n, grasp)`` records n samples under one contact state;
        ``advance([(n0, grasp0), (n1, grasp1), ...])`` records consecutive spans (e.g. the
        physics steps of one env step) and returns them concatenated.
        """
        segments = [(n_samples, grasp)] if grasp is not None else list(n_samples)
        resolved = []
        for n, g in segments:
            if int(n) != n or n < 0:
                raise ValueError(f"span length must be a non-negative integer, got {n!r}")
            if not isinstance(g, GraspState):
                raise TypeError(f"grasp must be a sensors.GraspState, got {type(g).__name__}")
            if n:
                resolved.append((int(n), g, self._resolve(g)))
        total = sum(n for n, _, _ in resolved)
        y = np.zeros(total)
        heard = np.zeros(total, dtype=bool)
        start = self.sample_index
        # merge consecutive spans that use the same systems: one synthesis call for them
        groups = []                                       # (n, grasp, resolved, lowest grip)
        for n, g, key in resolved:
            if groups and key.same_systems(groups[-1][2]):
                n0, g0, key0, grip0 = groups[-1]
                groups[-1] = (n0 + n, g0, key0, min(grip0, key.grip_force_n))
            else:
                groups.append((n, g, key, key.grip_force_n))
        k = 0
        while k < len(groups):
            n, g, key, grip = groups[k]
            if not key.heard:
                off = self.sample_index - start
                self._span(n, g, key, y[off:off + n], None)
                k += 1
                continue
            # The drive (fingertip model) does not depend on the object's contacts: one call
            # covers every heard group of this object and fingertip in a row.
            m = k + 1
            while (m < len(groups) and groups[m][2].heard and groups[m][2].object_key == key.object_key
                   and groups[m][2].fingertip is key.fingertip):
                m += 1
            run = groups[k:m]
            self._object_state(g)                         # ring-down over a gap, drive reset
            f, steady = self._drive_force(key.fingertip, min(r[3] for r in run), self.sample_index,
                                          sum(r[0] for r in run))
            at = 0
            for n_i, g_i, key_i, _ in run:
                off = self.sample_index - start
                self._span(n_i, g_i, key_i, y[off:off + n_i], f[at:at + n_i + 1], steady)
                heard[off:off + n_i] = True
                at += n_i
            k = m
        return self._record(start, y, heard)

    def latest_features(self) -> np.ndarray | None:
        """The 140-d features (``sensors.spectral_features``) of the latest complete loop
        period (samples [kP, (k+1)P) of the stream), or ``None`` before the first one ends.
        Computed once per completed period."""
        return self._features

    @property
    def latest_features_heard(self) -> float:
        """Fraction of the period behind :meth:`latest_features` during which the grasp was
        closed and the microphone heard the object (0 before the first period)."""
        return self._features_heard

    @property
    def latest_features_period(self) -> int:
        """Index k of the period behind :meth:`latest_features` (-1: none yet)."""
        return self._features_period

    @property
    def metadata(self) -> dict:
        """Settings and running facts, JSON-serialisable (like ``simulate_recording``'s)."""
        meta = {"source": "sim", "stream": True, "output": self.output, "method": self.method,
                "mic_gain": self.gain, "noise_std": self.noise_std,
                "sample_index": int(self.sample_index), "heard_samples": int(self.heard_samples),
                "fingertip_separated": bool(self.fingertip_separated),
                "min_contact_force_n": (None if not np.isfinite(self.min_contact_force_n)
                                        else float(self.min_contact_force_n)),
                "leak_lag_samples": self.leak_lag_samples,
                "system_cache": {"size": self.systems.size, "hits": self.systems.hits,
                                 "misses": self.systems.misses},
                "tolerance": self.systems.tolerance.__dict__.copy()}
        if self._leak_file is not None:
            meta["leak_file"] = self._leak_file
        return meta

    # -- resolving a grasp to its systems --------------------------------------------------
    def _resolve(self, g: GraspState) -> "_Resolved":
        """The systems of a span (consecutive spans with the same systems are merged)."""
        if g is self._last_grasp:
            return self._last_resolved
        if g.closed:
            res = _Resolved(g.object_key, True, self._closed_system(g), self._drive_model(g),
                            g.actuator.force_n)
        else:
            res = _Resolved(g.object_key, False)
        self._last_grasp, self._last_resolved = g, res
        return res

    def _closed_system(self, g: GraspState) -> ModalSystem:
        others = [c for c in g.others if c.force_n > 0]
        hit = self.systems.lookup(g.object_key, True, g.contact_table())
        if hit is not None:
            return hit
        r = len(g.model.angular_frequencies_rad_s)
        sysm = ModalSystem.build(g.model, self.sample_rate_hz, g.actuator.position_m, g.actuator.normal,
                                 g.mic.position_m, g.mic.normal, [g.actuator, g.mic, *others],
                                 method=self.method, output=self.output, keep_unobservable=True,
                                 initial_state=np.ones(2 * r))  # keep every mode: any may carry state
        self.systems.store(g.object_key, True, g.contact_table(), sysm)
        return sysm

    def _ring_system(self, g: GraspState, geometry) -> ModalSystem:
        """Free ring-down under the contacts the object still has (no drive, not heard).
        The drive/mic points only shape B and C, which zero force and no output ignore."""
        contacts = [c for c in g.damping_contacts() if c.force_n > 0]
        hit = self.systems.lookup(g.object_key, False, g.contact_table())
        if hit is not None:
            return hit
        r = len(g.model.angular_frequencies_rad_s)
        sysm = ModalSystem.build(g.model, self.sample_rate_hz, *geometry, contacts, method=self.method,
                                 output=self.output, keep_unobservable=True, initial_state=np.ones(2 * r))
        self.systems.store(g.object_key, False, g.contact_table(), sysm)
        return sysm

    def _drive_model(self, g: GraspState) -> FingertipModel:
        """The drive model for this object with grip force 0: the grip force (the actuator
        contact's normal force) does not enter the linear dynamics, only the separation
        check (``FingertipModel.state_space`` does not read it; tests/test_streaming.py
        checks that), so one discretised drive serves every grip force."""
        tip = self._tips.get(g.object_key)
        if tip is None:
            base = self.fingertip
            if base is None:
                kw = {}
                mass = getattr(g.model, "mass_kg", None)
                if mass is not None and np.isfinite(mass) and mass > 0:
                    kw["object_mass_kg"] = float(mass)
                base = FingertipModel(**kw)
            tip = self._tips[g.object_key] = replace(base, grip_force_n=0.0)
        return tip

    def _drive_systems_for(self, tip: FingertipModel):
        key = tip
        hit = self._drive_systems.get(key)
        if hit is not None:
            self._drive_systems.move_to_end(key)
            return hit
        A, B, C = tip.state_space()
        kc, cc = tip.contact_stiffness_n_m, tip.contact_damping_n_s_m
        Cm = np.zeros(8)   # mic-side contact force, as FingertipModel._linear_forces reads it
        Cm[4], Cm[5], Cm[6], Cm[7] = kc, cc, -kc, -cc
        pair = (lti_system(A, B, C, 0.0, self.sample_rate_hz), lti_system(A, B, Cm, 0.0, self.sample_rate_hz))
        self._drive_systems[key] = pair
        while len(self._drive_systems) > 4:
            self._drive_systems.popitem(last=False)
        return pair

    # -- synthesis of one merged span ------------------------------------------------------
    def _object_state(self, g: GraspState) -> _ObjectState:
        key = g.object_key
        st = self._objects.get(key)
        r = len(g.model.angular_frequencies_rad_s)
        if st is None:
            st = _ObjectState(g.model, np.zeros(2 * r), self.sample_index)
            self._objects[key] = st
        elif len(st.x if st.x is not None else st.steady.state0) != 2 * r:
            raise ValueError(f"object {key!r} changed its number of modes -> {r}")
        if st.at < self.sample_index:
            # the object was out of the stream: ring it down over the gap under its last contacts
            if np.any(self._x(st)) and st.geometry is not None and st.last is not None:
                Phi = self._ring_system(st.last, st.geometry).transition_matrix()
                st.x = np.linalg.matrix_power(Phi, self.sample_index - st.at) @ st.x
            st.at = self.sample_index
        if key != self._current:
            self._drive = None      # another object in the hand: the drive starts from rest
            self._current = key
        return st

    def _x(self, st: _ObjectState) -> np.ndarray:
        """The object's state at sample ``st.at``, out of its periodic steady state if it was in one."""
        if st.x is None:
            st.x = st.steady.state_at(st.at, len(self._period))
            st.steady = None
        return st.x

    def _span(self, n: int, g: GraspState, res: "_Resolved", out: np.ndarray, u: np.ndarray | None,
              steady_drive: "_Steady | None" = None) -> None:
        """Synthesize n samples under one set of systems; ``u``: the drive force at samples
        s .. s + n when heard; ``steady_drive``: the drive is in periodic steady state."""
        st = self._object_state(g)
        s = self.sample_index
        if res.heard:
            sysm = res.system                 # n + 1 samples: s .. s + n
            if sysm is not st.system or steady_drive is None:
                st.system, st.settled = sysm, 0
            if st.steady is not None and st.steady.system is sysm and steady_drive is not None:
                # periodic steady state: the output repeats every period, nothing to compute
                P = len(self._period)
                out[:] = st.steady.output[(s + np.arange(n)) % P]
                self.steady_samples += n
            else:
                x = self._x(st)
                out[:] = sysm.response(u[:n], x)
                st.x = sysm.final_state(u, x)
                if steady_drive is not None:
                    st.settled += n
                    if st.settled * sysm.slowest_decay_rate_per_s() >= SETTLE_E_FOLDS * self.sample_rate_hz:
                        st.steady, st.x = self._steady_of(sysm, steady_drive), None
            st.geometry = (g.actuator.position_m, g.actuator.normal, g.mic.position_m, g.mic.normal)
            self.heard_samples += n
        else:
            self._drive = None
            st.system = None
            x = self._x(st)
            if np.any(x) and st.geometry is not None:
                st.x = self._ring_system(g, st.geometry).final_state(np.zeros(n + 1), x)
        st.last = g
        st.at = s + n
        self.sample_index = s + n

    def _steady_of(self, sysm: ModalSystem, drive: "_Steady") -> _Steady:
        """The periodic steady state of ``sysm`` under the steady drive force (cached)."""
        key = (id(sysm), id(drive.output))
        hit = self._steady.get(key)
        if hit is not None and hit.system is sysm and hit.force is drive.output:
            self._steady.move_to_end(key)
            return hit
        f = drive.output
        st = _Steady(sysm.periodic_response(f), sysm.periodic_state(f), sysm, f)
        self._steady[key] = st
        while len(self._steady) > 8:
            self._steady.popitem(last=False)
        return st

    def _drive_force(self, tip: FingertipModel, grip_force_n: float, s: int, n: int):
        """Dynamic actuator contact force at samples s .. s + n (piecewise linear between) and
        the drive's periodic steady state if it is in it (else ``None``); ``grip_force_n``
        (the lowest over the spans it covers) sets the separation check."""
        act, mic = self._drive_systems_for(tip)
        P = len(self._period)
        d = self._drive
        if d is None or d.act is not act:
            if d is None:
                x0 = np.zeros(8)
            else:                                            # same contact, new parameters: keep state
                x0 = d.x if d.x is not None else self._drive_steady(tip, act, mic)[0].state_at(s, P)
            d = self._drive = _Drive(tip, act, mic, x0, s)
        if d.x is None:
            # periodic steady state: the forces repeat every period
            steady, steady_mic = self._drive_steady(tip, act, mic)
            idx = (s + np.arange(n + 1)) % P
            f, f_mic = steady.output[idx], steady_mic.output[idx]
        else:
            fe = tip.actuator_force_n * self._excitation(s, n + 1)
            x0 = d.x if np.any(d.x) else None
            f = act.response(fe, x0)
            f_mic = mic.response(fe, x0)
            d.x = act.final_state(fe[:n + 1], x0)
            d.run += n
            if d.run * act.slowest_decay_rate_per_s() >= SETTLE_E_FOLDS * self.sample_rate_hz:
                d.x = None                                   # from here on: periodic
            steady = None
        lowest = grip_force_n + min(f.min(), f_mic.min())
        self.min_contact_force_n = min(self.min_contact_force_n, lowest)
        if lowest < 0:
            self.fingertip_separated = True
        d.fingertip, d.at = tip, s + n
        # the state is at sample s + n; the next span starts there with force f[n]
        return f, steady

    def _drive_steady(self, tip, act, mic) -> tuple[_Steady, _Steady]:
        """The drive's periodic steady state (actuator and mic contact forces), cached with its systems."""
        hit = self._drive_steadies.get(tip)
        if hit is None or hit[0].system is not act:
            fe = tip.actuator_force_n * self._period
            hit = (_Steady(act.periodic_response(fe), act.periodic_state(fe), act, fe),
                   _Steady(mic.periodic_response(fe), mic.periodic_state(fe), mic, fe))
            self._drive_steadies[tip] = hit
        return hit

    def _excitation(self, s: int, n: int) -> np.ndarray:
        P = len(self._period)
        return self._period[(s + np.arange(n)) % P]

    def _record(self, start: int, y: np.ndarray, heard: np.ndarray) -> np.ndarray:
        """Microphone units, noise and leak, float32 (same order of operations as
        ``simulate_recording``); feeds the feature window."""
        n = len(y)
        wave = self.gain * y
        if self.noise_std > 0:
            wave = wave + self.noise_std * self.rng.standard_normal(n)
        if self._leak_period is not None:
            lp = self._leak_period
            wave = wave + lp[(start + np.arange(n)) % len(lp)]
        out = wave.astype(np.float32)
        self._feed_features(start, out, heard)
        return out

    def _feed_features(self, start: int, samples: np.ndarray, heard: np.ndarray) -> None:
        P = len(self._window)
        pos = start
        k = 0
        while k < len(samples):
            phase = pos % P
            take = min(P - phase, len(samples) - k)
            self._window[phase:phase + take] = samples[k:k + take]
            self._heard_window[phase:phase + take] = heard[k:k + take]
            k += take
            pos += take
            if pos % P == 0:
                self._features = spectral_features(self._window, self.sample_rate_hz,
                                                   period_s=self.excitation.period_s)
                self._features_period = pos // P - 1
                self._features_heard = float(self._heard_window.mean())


@dataclass(frozen=True, eq=False)
class _Resolved:
    """The systems one span uses."""

    object_key: Hashable
    heard: bool
    system: ModalSystem | None = None
    fingertip: FingertipModel | None = None      # drive model, grip force 0
    grip_force_n: float = 0.0

    def same_systems(self, other: "_Resolved") -> bool:
        """One synthesis call can cover both spans."""
        return (self.object_key == other.object_key and self.heard == other.heard
                and self.system is other.system and self.fingertip is other.fingertip)


def _aligned_leak_cycle(leak: LeakRecording, excitation: Excitation, target_lag: int) -> np.ndarray:
    """One cycle of ``align_leak``'s output for a recording starting at loop phase 0: that
    output is periodic with the whole-period span of the leak recording it cycles through."""
    P = excitation.period_samples
    w = leak.waveform
    if len(w) < P:
        raise ValueError(f"leak recording ({len(w)} samples) is shorter than one excitation period ({P})")
    lag = excitation_lag(w.astype(float), excitation.signal, max_lag=min(P - 1, len(w) - P))
    span = ((len(w) - lag % P) // P) * P
    return align_leak(leak, excitation, span, target_lag=target_lag)
