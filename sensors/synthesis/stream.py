"""A continuously recording contact microphone while the grasp changes (issue 12).

The real rig plays its excitation in a loop and records without a break while the robot
moves.  :class:`AcousticStream` does the same in simulation: each call to
:meth:`AcousticStream.advance` synthesizes the samples of one span of time during which the
contact state (a ``GraspState``) was constant, e.g. one physics step, and carries every
piece of state into the next span:

- the excitation's phase (an absolute sample counter; the loop never restarts);
- the modal state of each object (scaled state x = [w q; q'], see ``sensors.synthesis.modal_system``),
  propagated exactly through every contact set, heard or not;
- the state of the lumped fingertip drive (``sensors.synthesis.drive``) while the actuator
  fingertip stays on the object;
- the noise generator and the leak's phase (``sensors.synthesis.microphone``).

A batch recording (``sensors.simulate_recording``) is this stream over one constant span,
from rest (or settled into its periodic steady state, :meth:`AcousticStream.settle`).

Timing convention (as ``sensors.modal_response`` with a contact schedule): a span of n
samples starting at sample s covers the time interval [s, s + n) / sample_rate_hz.  Its system governs
the n steps from sample s to sample s + n; its microphone reads samples s .. s + n - 1.  The
drive force is piecewise linear between samples and continuous across span boundaries (with
the band-limited drive, those samples stand for the band-limited force: ``sensors.synthesis.drive``).

Open grasps: a parallel gripper opens both fingers together, so the object is heard only while
BOTH fingertips touch it with a positive force.  Otherwise the microphone records leak and
noise only, while the object keeps ringing down unheard under the damping of the contacts it
still has.  When the grasp closes again the drive model starts from rest (the fingertip
settles onto the object as a new grasp; its free vibration in the air reaches the microphone
through the gripper, which is what the leak recording holds) and the microphone hears the
object's decayed ringing plus the new drive.

Reusing systems: the stream's ``SystemCache`` (``sensors.synthesis.caches``) treats a contact
set as unchanged when it matches a cached one within a ``ContactTolerance``;
``ContactTolerance.exact()`` reuses only identical contact sets.  The state at the end of a
span is computed when the next span needs it (a batch recording never does).  Heard spans in a
row on one system (with passive sound, every contact read starts a span) share one drive
convolution, each new span's load entering as a state jump (``ONE_CONVOLUTION_PER_RUN``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Hashable

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from ..signals.excitation import Excitation
from ..signals.features import spectral_features
from ..signals.leak import LeakRecording
from .caches import IdentityKey, SynthesisCache, SystemCache
from .drive import FingertipDrive, grasp_fingertip
from .fingertip import FingertipModel
from .grasp_state import ContactTolerance, GraspState
from .lti import SETTLE_E_FOLDS, SteadyState
from .microphone import Microphone
from .modal_system import CONTACT_MODELS, ModalSystem, transfer_state
from .passive import LoadRead, LoadSolver, PassiveSound, project_reads

__all__ = ["AcousticStream", "ONE_CONVOLUTION_PER_RUN"]

#: Heard spans in a row on one system (with passive sound each contact read starts a span,
#: and a span whose load changes is two pieces: the sharp part's ramp over the rise time, then
#: the rest).  True: one drive convolution over the whole run, each piece's start entering as
#: a state jump (``_Run``); False: each piece synthesized from the previous one's end state
#: (the reference path).  Equal to rounding (tests/test_passive_sound.py); read at each span.
ONE_CONVOLUTION_PER_RUN = True


@dataclass
class _ObjectState:
    model: Any
    n_state: int                     # 2 r: the length of its scaled modal state
    x: np.ndarray | None             # the state at sample ``at`` (None: ``end`` or ``steady`` holds it)
    at: int
    end: tuple | None = None         # (system, force, start state, offset) of its latest span: the state at its end
    geometry: tuple | None = None    # last closed grasp's (drive p, n, mic p, n): for ring-down builds
    last: GraspState | None = None   # contacts of its latest span (for gaps while not in the stream)
    system: ModalSystem | None = None  # the system of its latest heard samples ...
    settled: int = 0                 # ... and how many of them ran under a periodic drive
    steady: SteadyState | None = None  # while in periodic steady state: the state is periodic
    modes: Any = None                # the modes the state is in (the model, or it with contact springs)
    # passive sound (sensors.synthesis.passive): reads of the object's loads, physical (each
    # system projects them onto its own modes); loads count relative to ``base``
    base: LoadRead | None = None     # the read under which the object started being followed
    read: LoadRead | None = None     # the latest read ...
    load_grasp: GraspState | None = None  # ... and the grasp it is of
    eq: np.ndarray | None = None     # the static state (in ``modes``) under the load the state is
    #                                  under: added to a steady state, carried across mode changes
    run: "_Run | None" = None        # heard spans not yet synthesized (ONE_CONVOLUTION_PER_RUN): the
    #                                  state at ``at`` is their end

    def state_in(self, modes, eq: np.ndarray | None = None) -> np.ndarray:
        """The state at sample ``at`` in ``modes`` (projected from the modes it is in when the
        contact springs changed them, ``sensors.synthesis.modal_system.transfer_state``).
        Under a load the part relative to its static state is projected and ``eq``, the static
        state under the same load in ``modes``, added (``sensors.synthesis.passive``)."""
        x = self.state()
        if modes is not self.modes:
            x = transfer_state(x if self.eq is None else x - self.eq, self.modes, modes)
            self.x, self.modes, self.eq = (x if eq is None else x + eq), modes, eq
        return self.x

    def state(self) -> np.ndarray:
        """The state at sample ``at``: propagated through the latest span now, or taken out
        of the periodic steady state."""
        self.flush()
        if self.end is not None:
            system, force, x0, offset = self.end
            x = system.final_state(force, x0)
            self.x, self.end = (x if offset is None else x + offset), None
        elif self.x is None:
            if self.steady is None:
                raise ValueError("this stream does not carry the modal state (carry_state=False): "
                                 "it records one span per object")
            x = self.steady.state_at(self.at)
            self.x, self.steady = (x if self.eq is None else x + self.eq), None
        return self.x

    def flush(self) -> None:
        """Synthesize the pending run of heard spans (their samples and the end state)."""
        if self.run is not None:
            self.end, self.run = self.run.flush(), None


class _Run:
    """Heard spans in a row on one system, synthesized together (``ONE_CONVOLUTION_PER_RUN``).

    Each span is one or two pieces on which the passive load is affine in time, with the
    particular solution alpha + beta t (``sensors.synthesis.passive.LoadSolver``).  The
    reference synthesizes piece after piece from x_i - alpha_i, each start state the previous
    piece's exact end plus alpha_(i-1) + beta_(i-1) len T.  By linearity that is the response
    of the whole run to the drive from x_0 - alpha_0 with the state jumping by
    j_i = alpha_(i-1) + beta_(i-1) len_(i-1) T - alpha_i at each later piece's start
    (``DiscreteSystem.response``'s ``jumps``: one convolution, each jump adding its free
    response), plus each piece's alpha + beta t at the output; the end state is the run's from
    x_0 - alpha_0 plus the jumps propagated freely to the end plus the last piece's offset."""

    def __init__(self, system: ModalSystem, x: np.ndarray, sample_rate_hz: int) -> None:
        self.system, self.x, self.T = system, x, 1.0 / sample_rate_hz
        self.n = 0
        self.forces: list[np.ndarray] = []      # each span's force at its n samples ...
        self.last_force: np.ndarray | None = None   # ... and at the sample after the run
        self.outs: list[tuple[int, np.ndarray]] = []
        self.pieces: list[tuple[int, int, np.ndarray | None, np.ndarray | None]] = []   # start, stop, alpha, beta
        self.jumps: list[tuple[int, np.ndarray]] = []
        self.end: np.ndarray | None = None       # alpha + beta len T of the last piece

    def add(self, u: np.ndarray, n: int, out: np.ndarray, pieces) -> None:
        """A span of n samples (its force u at samples 0 .. n) written to ``out`` at the flush;
        ``pieces``: (start, stop, alpha, beta) within it, alpha and beta None for no load."""
        for a, b, alpha, beta in pieces:
            a, b = self.n + a, self.n + b
            if not self.pieces:
                if alpha is not None:
                    self.x = self.x - alpha
            else:
                jump = self.end if alpha is None else (-alpha if self.end is None else self.end - alpha)
                if jump is not None:
                    self.jumps.append((a, jump))
            self.pieces.append((a, b, alpha, beta))
            self.end = None if alpha is None else alpha + beta * ((b - a) * self.T)
        self.forces.append(u[:n])
        self.outs.append((self.n, out))
        self.last_force = u[n:n + 1]
        self.n += n

    def flush(self) -> tuple:
        """Writes the spans' samples; returns the end state's ``_ObjectState.end`` form."""
        sysm, T = self.system, self.T
        u = np.concatenate(self.forces + [self.last_force])
        y = sysm.response(u[:self.n], self.x, self.jumps)
        for a, b, alpha, beta in self.pieces:
            if alpha is not None:
                y[a:b] += sysm.output(alpha) + sysm.output(beta) * (np.arange(b - a) * T)
        for at, out in self.outs:
            out[:] = y[at:at + len(out)]
        offset = self.end
        for at, jump in self.jumps:
            free = sysm.free_state(jump, self.n - at)
            offset = free if offset is None else offset + free
        return sysm, u, self.x, offset


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


class AcousticStream:
    """The simulated microphone, recording without a break while contacts change.

    Parameters
    ----------
    excitation : looped forever; sample k of the stream plays ``excitation.signal[k % P]``.
    fingertip : the lumped drive model.  Its grip force always follows the actuator
        contact's normal force; ``None``: ``FingertipModel()`` with the object's ``mass_kg``
        when the model has one (``sensors.synthesis.drive.grasp_fingertip``).
    leak : ``LeakRecording`` or its .npz path, recorded with this excitation; looped and
        aligned as ``sensors.align_leak`` aligns it for a recording that starts at phase 0
        with target lag ``leak_lag_samples``.  ``simulate_recording`` aligns its leak to the
        synthesized signal's excitation peak (its metadata ``leak_target_lag``); a stream
        cannot know that ahead of time and uses a fixed lag (0: the leak's excitation peak at
        the start of each loop period).
    noise_std, rng : white sensor noise (recorded units) from this ``numpy.random.Generator``
        (or seed), drawn sample by sample in stream order.
    output, method, contact_model : as ``simulate_recording``.
    tolerance : when a contact set counts as unchanged (``ContactTolerance``; default
        ``ContactTolerance()``).
    cache_size : systems kept in :attr:`systems` (default ``CACHE_SIZES["stream.systems"]``).
    cache : a ``SynthesisCache`` to share systems and drive runs with other recordings (its
        ``SystemCache`` then decides tolerance and size; default: a new one).
    carry_state : False for a stream that records one span per object from rest and stops
        (a batch recording): its systems then keep only the modes that the drive reaches and
        the microphone sees, as no later contact set needs the others' state.
    bandlimited : the excitation reaches the fingertip as the band-limited signal a sound
        card plays (default; ``sensors.synthesis.drive``); False: piecewise linear between
        its samples, the drive of earlier datasets (spectrum low by about sinc^4(f/fs)).
    passive : a ``PassiveSound``: changes of the forces in each span's ``GraspState.loads``
        (impacts, knocks, slides) excite the object on top of the drive, exactly
        (``sensors.synthesis.passive``); ``None`` (default): only the drive excites it.  An
        object's ringing is followed from its first closed grasp on: it starts at rest under
        the loads it has then, and their changes count from there.  Displacement or velocity
        output only.
    """

    def __init__(self, excitation: Excitation, fingertip: FingertipModel | None = None,
                 leak: LeakRecording | str | os.PathLike | None = None, noise_std: float = 0.0,
                 rng=None, output: str = "displacement", method: str = "exact",
                 tolerance: ContactTolerance | None = None, cache_size: int | None = None,
                 leak_lag_samples: int = 0, cache: SynthesisCache | None = None, *, carry_state: bool = True,
                 contact_model: str = "spring_damper", bandlimited: bool = True,
                 passive: PassiveSound | None = None):
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
        if fingertip is not None and not isinstance(fingertip, FingertipModel):
            raise TypeError("fingertip must be a sensors.FingertipModel or None")
        self.microphone = Microphone(excitation, output, noise_std, rng, leak, leak_lag_samples)
        if cache is None:
            cache = SynthesisCache(systems=SystemCache(tolerance or ContactTolerance(), cache_size))
        elif tolerance is not None or cache_size is not None:
            raise ValueError("a stream given a cache uses its SystemCache's tolerance and size: "
                             "pass tolerance and cache_size to that SystemCache")
        self.excitation = excitation
        self.sample_rate_hz = int(excitation.sample_rate_hz)
        self.fingertip = fingertip
        self.output = output
        self.method = method
        self.cache = cache
        self.systems = cache.systems
        self.bandlimited = bool(bandlimited)
        self.drive = FingertipDrive(excitation, cache.forces, self.bandlimited)
        if passive is not None and not isinstance(passive, PassiveSound):
            raise TypeError(f"passive must be a sensors.PassiveSound or None, got {type(passive).__name__}")
        if passive is not None and output == "acceleration":
            raise ValueError("passive sound needs output 'displacement' or 'velocity' (an acceleration "
                             "output would carry the load directly)")
        self.passive = passive
        self._passive_rng = None if passive is None else np.random.default_rng(passive.seed)
        self._load_solvers: LRU[LoadSolver] = LRU(CACHE_SIZES["stream.systems"])
        self.carry_state = bool(carry_state)
        if contact_model not in CONTACT_MODELS:
            raise ValueError(f"contact_model must be one of {CONTACT_MODELS}, got {contact_model!r}")
        self.contact_model = contact_model
        # the fingertip pads' springs (their own contacts give none): part of every system
        self._pad = fingertip if fingertip is not None else FingertipModel()
        pads = (self._pad.contact_stiffness_n_m, self._pad.contact_tangential_stiffness_n_m)
        self._settings = (self.sample_rate_hz, method, output, self.carry_state, contact_model, pads)
        self.sample_index = 0                     # absolute index of the next sample
        self._objects: dict[Hashable, _ObjectState] = {}
        self._current: Hashable | None = None
        self._steadies: LRU[SteadyState] = LRU(CACHE_SIZES["stream.steady_states"])  # per (system, drive)
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
        self.heard_samples = 0

    # -- public ---------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Stream time of the next sample [s]."""
        return self.sample_index / self.sample_rate_hz

    @property
    def noise_std(self) -> float:
        return self.microphone.noise_std

    @property
    def rng(self) -> np.random.Generator:
        return self.microphone.rng

    @property
    def gain(self) -> float:
        return self.microphone.gain

    @property
    def leak_lag_samples(self) -> int:
        return self.microphone.leak_lag_samples

    @property
    def fingertip_separated(self) -> bool:
        """A fingertip contact would have pulled (the drive then ran one-sided)."""
        return self.drive.separated

    @property
    def min_contact_force_n(self) -> float:
        """The lowest total fingertip contact force so far [N] (inf before any drive)."""
        return self.drive.min_contact_force_n

    def advance(self, n_samples, grasp: GraspState | None = None) -> np.ndarray:
        """Record the next span(s); returns their float32 samples.

        ``advance(n, grasp)`` records n samples under one contact state;
        ``advance([(n0, grasp0), (n1, grasp1), ...])`` records consecutive spans (e.g. the
        physics steps of one env step) and returns them concatenated.
        """
        start = self.sample_index
        y, heard = self._synthesize(n_samples, grasp)
        out = self.microphone.record(y, start)
        self._feed_features(start, out, heard)
        return out

    def synthesize(self, n_samples, grasp: GraspState | None = None) -> np.ndarray:
        """The object's motion at the microphone (float64, in the units of ``output``) over
        the next span(s), as :meth:`advance` takes them, before the microphone: no gain,
        noise, leak or features (``simulate_recording`` adds its own).  A stream is either
        recorded (:meth:`advance`) or synthesized, not both."""
        return self._synthesize(n_samples, grasp)[0]

    def settle(self, grasp: GraspState) -> None:
        """Start ``grasp`` (closed) in its periodic steady state, as if it had been held for
        ever: the drive and the object repeat one loop period from here until the contacts
        change.  ValueError where a fingertip contact would separate in steady state."""
        if not isinstance(grasp, GraspState):
            raise TypeError(f"grasp must be a sensors.GraspState, got {type(grasp).__name__}")
        if not grasp.closed:
            raise ValueError("only a closed grasp (both fingertips pressing) has a periodic steady state")
        res = self._resolve(grasp)
        st = self._object_state(grasp)
        modes = res.system.modes
        if self._modal_change(st, self._load_change(st, grasp), modes) is not None:
            raise ValueError("settle() starts an object at rest under its loads: settle it before its loads change")
        drive = self.drive.settle(res.fingertip, res.grip_force_n)
        st.system, st.settled = res.system, 0
        st.steady, st.x, st.end = self._steady_of(res.system, drive), None, None
        st.modes, st.eq = modes, self._equilibrium(res.system, self._load(st, modes))
        st.geometry = (grasp.actuator.position_m, grasp.actuator.normal, grasp.mic.position_m, grasp.mic.normal)

    def grasp_systems(self, grasp: GraspState) -> tuple[ModalSystem, FingertipModel]:
        """The modal system (from this stream's cache) and the fingertip drive model (grip
        force 0) a closed ``grasp`` is synthesized with."""
        if not grasp.closed:
            raise ValueError("only a closed grasp (both fingertips pressing) is driven")
        res = self._resolve(grasp)
        return res.system, res.fingertip

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
                "contact_model": self.contact_model,
                "drive": "bandlimited" if self.bandlimited else "foh",
                "passive": None if self.passive is None else self.passive.to_dict(),
                "mic_gain": self.gain, "noise_std": self.noise_std,
                "sample_index": int(self.sample_index), "heard_samples": int(self.heard_samples),
                "fingertip_separated": bool(self.fingertip_separated),
                "min_contact_force_n": (None if not np.isfinite(self.min_contact_force_n)
                                        else float(self.min_contact_force_n)),
                "leak_lag_samples": self.leak_lag_samples,
                "system_cache": {"size": self.systems.size, "hits": self.systems.hits,
                                 "misses": self.systems.misses},
                "tolerance": self.systems.tolerance.__dict__.copy()}
        if self.microphone.leak_file is not None:
            meta["leak_file"] = self.microphone.leak_file
        return meta

    # -- the spans of one call -------------------------------------------------------------
    def _synthesize(self, n_samples, grasp: GraspState | None) -> tuple[np.ndarray, np.ndarray]:
        """The object's motion over the spans and which samples were heard."""
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
            # passive sound: a new contact read may bring new loads, its span starts a group
            if groups and key.same_systems(groups[-1][2]) and (self.passive is None or g is groups[-1][1]):
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
            f, steady = self.drive.forces(key.fingertip, min(r[3] for r in run), self.sample_index,
                                          sum(r[0] for r in run))
            at = 0
            for n_i, g_i, key_i, _ in run:
                off = self.sample_index - start
                self._span(n_i, g_i, key_i, y[off:off + n_i], f[at:at + n_i + 1], steady)
                heard[off:off + n_i] = True
                at += n_i
            k = m
        for st in self._objects.values():
            st.flush()                                    # the samples of pending runs
        return y, heard

    # -- resolving a grasp to its systems --------------------------------------------------
    def _resolve(self, g: GraspState) -> _Resolved:
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
        # carrying the state: keep every mode, any may carry state into a later contact set
        return self.systems.get_or_build(g, True, self._settings, lambda: ModalSystem.build(
            g.model, self.sample_rate_hz, g.actuator.position_m, g.actuator.normal, g.mic.position_m,
            g.mic.normal, [self._pad.pad(g.actuator), self._pad.pad(g.mic), *others], method=self.method,
            output=self.output, contact_model=self.contact_model, keep_all_modes=self.carry_state))

    def _ring_system(self, g: GraspState, geometry) -> ModalSystem:
        """Free ring-down under the contacts the object still has (no drive, not heard).
        The drive/mic points only shape B and C, which zero force and no output ignore."""
        tips = [self._pad.pad(c) for c in (g.actuator, g.mic) if c is not None]
        contacts = [c for c in (*tips, *g.others) if c.force_n > 0]
        return self.systems.get_or_build(g, False, self._settings, lambda: ModalSystem.build(
            g.model, self.sample_rate_hz, *geometry, contacts, method=self.method, output=self.output,
            contact_model=self.contact_model, keep_all_modes=True))

    def _drive_model(self, g: GraspState) -> FingertipModel:
        """The grasp's fingertip model with grip force 0 (``FingertipDrive`` applies the grip)."""
        tip = self._tips.get(g.object_key)
        if tip is None:
            tip = self._tips[g.object_key] = grasp_fingertip(self.fingertip, g.model, 0.0)
        return tip

    # -- synthesis of one merged span ------------------------------------------------------
    def _object_state(self, g: GraspState) -> _ObjectState:
        key = g.object_key
        st = self._objects.get(key)
        r = len(g.model.angular_frequencies_rad_s)
        if st is None:
            st = _ObjectState(g.model, 2 * r, np.zeros(2 * r), self.sample_index, modes=g.model)
            self._objects[key] = st
        elif st.n_state != 2 * r:
            raise ValueError(f"object {key!r} changed its number of modes -> {r}")
        if st.at < self.sample_index:
            # the object was out of the stream: ring it down over the gap under its last contacts
            x = st.state()
            if (np.any(x) or st.read is not st.base) and st.geometry is not None and st.last is not None:
                ring = self._ring_system(st.last, st.geometry)
                load = self._load(st, ring.modes)
                x = self._state_in(st, ring, load)
                eq = self._equilibrium(ring, load)
                eq = np.zeros_like(x) if eq is None else eq
                st.x = np.linalg.matrix_power(ring.transition_matrix(), self.sample_index - st.at) @ (x - eq) + eq
                st.eq = None if not np.any(eq) else eq
            st.at = self.sample_index
        if key != self._current:
            self.drive.reset()      # another object in the hand: the drive starts from rest
            self._current = key
        return st

    def _span(self, n: int, g: GraspState, res: _Resolved, out: np.ndarray, u: np.ndarray | None,
              steady_drive: SteadyState | None = None) -> None:
        """Synthesize n samples under one set of systems; ``u``: the drive force at samples
        s .. s + n when heard; ``steady_drive``: the drive is in periodic steady state."""
        st = self._object_state(g)
        s = self.sample_index
        change = self._load_change(st, g)
        if res.heard:
            sysm = res.system                 # n + 1 samples: s .. s + n
            change = self._modal_change(st, change, sysm.modes)
            if sysm is not st.system or steady_drive is None:
                st.system, st.settled = sysm, 0
            if (change is None and st.steady is not None and st.steady.system is sysm
                    and steady_drive is not None):
                # periodic steady state: the output repeats every period, nothing to compute
                out[:] = st.steady.output[(s + np.arange(n)) % len(st.steady.output)]
                if st.eq is not None:
                    out += sysm.output(st.eq)
                self.steady_samples += n
            else:
                self._evolve(st, sysm, u, n, change, out, self.carry_state)
                if steady_drive is not None:
                    st.settled += n
                    if st.settled * sysm.slowest_decay_rate_per_s() >= SETTLE_E_FOLDS * self.sample_rate_hz:
                        st.flush()                # its samples; the state is the steady one's
                        st.steady, st.end = self._steady_of(sysm, steady_drive), None   # plus st.eq
            st.geometry = (g.actuator.position_m, g.actuator.normal, g.mic.position_m, g.mic.normal)
            self.heard_samples += n
        else:
            self.drive.reset()
            st.system = None
            x = st.state()
            if st.geometry is not None and (np.any(x) or change is not None or st.read is not st.base):
                ring = self._ring_system(g, st.geometry)
                self._evolve(st, ring, np.zeros(n + 1), n, self._modal_change(st, change, ring.modes), None, True)
        st.last = g
        st.at = s + n
        self.sample_index = s + n

    def _evolve(self, st: _ObjectState, sysm: ModalSystem, u: np.ndarray, n: int, change, out, keep: bool) -> None:
        """The object's response (into ``out`` unless None) and state over n samples under
        ``sysm`` and the drive force ``u`` (samples s .. s + n), with the passive load
        (``sensors.synthesis.passive``): after a change (``change``: loads before and after,
        and the sharp part of the step) the sharp part ramps in over the rise time and the rest
        over the span, constant otherwise.  On each piece where the load is affine in time its
        particular solution (affine too) is added to the exact solution of the drive from the
        shifted state.  Loads and states are in ``sysm``'s modes (the state carried into them
        relative to the load's static state).  ``keep``: carry the end state."""
        load = self._load(st, sysm.modes)             # the latest read's, after any change
        if ONE_CONVOLUTION_PER_RUN and out is not None and keep:
            self._add_to_run(st, sysm, u, n, change, load, out)
            return
        x = self._state_in(st, sysm, load if change is None else change[0])
        if change is None and (load is None or not np.any(load)):
            if out is not None:
                out[:] = sysm.response(u[:n], x)
            st.x, st.end, st.eq = None, (sysm, u, x, None) if keep else None, None
            return
        solver = self._load_solvers.get_or_build(IdentityKey(sysm), lambda: LoadSolver(sysm))
        T = 1.0 / self.sample_rate_hz
        pieces = self._load_pieces(n, change, load)
        for i, (a, b, p0, p1) in enumerate(pieces):
            alpha, beta = solver.particular(p0, p1, (b - a) * T if p1 is not p0 else 0.0)
            if out is not None:
                out[a:b] = (sysm.response(u[a:b], x - alpha) + sysm.output(alpha)
                            + sysm.output(beta) * (np.arange(b - a) * T))
            end = alpha + beta * ((b - a) * T)
            if i < len(pieces) - 1:
                x = sysm.final_state(u[a:b + 1], x - alpha) + end
            else:
                st.x, st.end = None, (sysm, u[a:], x - alpha, end) if keep else None
        # the static state under the load from here on (its ramp's particular solution is not)
        st.eq = alpha if change is None else self._equilibrium(sysm, load)

    def _load_pieces(self, n: int, change, load) -> list:
        """A span's pieces of constant or linearly ramped load, ``(start, end, load at start, load
        at end)`` in samples: the whole span under ``load``, or, for a ``change`` (old, new,
        sharp), a rise of ``passive.rise_samples`` from old (plus the sharp jump) then the rest."""
        if change is None:
            return [(0, n, load, load)]
        old, new, sharp = change
        k = self.passive.rise_samples(self.sample_rate_hz, n)
        mid = old + sharp + (new - old - sharp) * (k / n)
        return [(0, k, old, mid)] + ([(k, n, mid, new)] if k < n else [])

    def _add_to_run(self, st: _ObjectState, sysm: ModalSystem, u: np.ndarray, n: int, change, load,
                    out: np.ndarray) -> None:
        """``_evolve`` of a heard span through the object's pending ``_Run`` (a new run when
        its system differs: the state is then carried into ``sysm`` as ``_evolve`` does)."""
        if st.run is None or st.run.system is not sysm:
            x = self._state_in(st, sysm, load if change is None else change[0])     # flushes a run
            st.run, st.x, st.end = _Run(sysm, x, self.sample_rate_hz), None, None
        T = 1.0 / self.sample_rate_hz
        pieces = []
        for a, b, p0, p1 in self._load_pieces(n, change, load):
            if p0 is p1 and (p0 is None or not np.any(p0)):
                pieces.append((a, b, None, None))
                continue
            solver = self._load_solvers.get_or_build(IdentityKey(sysm), lambda: LoadSolver(sysm))
            alpha, beta = solver.particular(p0, p1, (b - a) * T if p1 is not p0 else 0.0)
            pieces.append((a, b, alpha, beta))
        st.run.add(u, n, out, pieces)
        alpha = pieces[-1][2]
        st.eq = alpha if change is None else self._equilibrium(sysm, load)

    # -- passive sound ---------------------------------------------------------------------
    def _load_change(self, st: _ObjectState, g: GraspState):
        """``(previous read, new read)`` of the object's loads when this span brings a new
        contact read, else ``None`` (passive sound off, the same grasp, or the object not yet
        followed: until its first closed grasp it is at rest under whatever loads it has, and
        they become the reference).  Draws the read's roughness (once per read, in order)."""
        if self.passive is None or g is st.load_grasp:
            return None
        read = LoadRead(g.loads, self._passive_rng, self.passive.roughness)
        st.load_grasp = g
        if st.base is None or st.geometry is None:
            st.base = st.read = read
            return None
        previous, st.read = st.read, read
        return previous, read

    def _load(self, st: _ObjectState, modes) -> np.ndarray | None:
        """The object's modal load on ``modes`` (relative to its base read) after its latest
        read; ``None`` when there is none."""
        if st.base is None or st.read is None:
            return None
        project_reads((st.base, st.read), modes)
        return st.read.modal(modes)[0] - st.base.modal(modes)[0]

    def _modal_change(self, st: _ObjectState, change, modes):
        """A load change (``_load_change``) on ``modes``: the load before and after and the
        sharp part of the step (impacts, stick-slip), or ``None`` when the load is unchanged."""
        if change is None:
            return None
        previous, read = change
        project_reads((st.base, previous, read), modes)
        base = st.base.modal(modes)[0]
        total, impacts, fluctuation = read.modal(modes)
        before, _, fluctuation_before = previous.modal(modes)
        old, new = before - base, total - base
        return None if np.array_equal(old, new) else (old, new, impacts + fluctuation - fluctuation_before)

    def _state_in(self, st: _ObjectState, sysm: ModalSystem, load) -> np.ndarray:
        """The object's state in ``sysm``'s modes, carried relative to the static state under
        ``load`` (on those modes) where the modes change (``_ObjectState.state_in``)."""
        eq = self._equilibrium(sysm, load) if st.modes is not sysm.modes else None
        return st.state_in(sysm.modes, eq)

    def _equilibrium(self, sysm: ModalSystem, load) -> np.ndarray | None:
        """The static state of ``sysm`` under a constant modal load (None: no load)."""
        if load is None or not np.any(load):
            return None
        solver = self._load_solvers.get_or_build(IdentityKey(sysm), lambda: LoadSolver(sysm))
        return solver.particular(load, load, 0.0)[0]

    def _steady_of(self, sysm: ModalSystem, drive: SteadyState) -> SteadyState:
        """The periodic steady state of ``sysm`` under the steady drive force (cached)."""
        return self._steadies.get_or_build((IdentityKey(sysm), IdentityKey(drive.output)),
                                           lambda: SteadyState(sysm, drive.output, self.bandlimited))

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
