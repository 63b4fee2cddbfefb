"""The fingertip drive across the spans of a recording: which fingertip model, and its force.

The exciter drives the object through the lumped fingertip model
(``sensors.FingertipModel``).  :func:`grasp_fingertip` is the one rule for the model a grasp
uses; :class:`FingertipDrive` computes the dynamic actuator contact force span by span,
carrying the model's state while the actuator fingertip stays on the same object:

- from rest (a new grasp) or from the carried state, exactly (the linear model discretised
  with first-order hold, ``FingertipModel.discretised``);
- where a contact would pull (grip force plus dynamic force below zero), the one-sided model
  integrated from the same state instead (``FingertipModel.one_sided_forces``), and the
  recording says the fingertip separated;
- once its transient has decayed by ``SETTLE_E_FOLDS`` e-folds, its periodic steady state
  (one precomputed period, repeated), or from the start when a grasp is settled.

Forces are given at the samples s .. s + n of a span of n samples: the force is piecewise
linear between samples and continuous across span boundaries.

Band-limited drive (``bandlimited=True``, the default of the stream and of batch recordings):
the sound card plays the band-limited signal through the excitation's samples, not the
piecewise-linear one.  The drive then works on the excitation prefiltered by 1 / sinc^4(f/fs)
per harmonic of the loop (``sensors.synthesis.lti.bandlimited_samples``, two passes: the
fingertip's and the object's first-order holds), and its forces are the samples whose
piecewise-linear interpolant has the true band-limited contact force as its baseband: the
periodic steady states (fingertip and object, ``SteadyState(..., bandlimited=True)``) are then
exact, and the time-domain (first-order-hold) runs differ from them only by the holds'
images (see ``sensors.synthesis.bandlimit``).  ``bandlimited=False`` is the drive of datasets
made before (piecewise-linear excitation, the spectrum tilted by about sinc^4(f/fs)).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from ..signals.excitation import Excitation
from .fingertip import DriveSystems, FingertipModel
from .lti import SETTLE_E_FOLDS, SteadyState, bandlimited_samples

__all__ = ["FingertipDrive", "drive_period", "grasp_fingertip"]


def grasp_fingertip(fingertip: FingertipModel | None, model, grip_force_n: float) -> FingertipModel:
    """The fingertip model of a grasp: ``fingertip`` (default ``FingertipModel()`` with the
    grasped model's ``mass_kg`` when it has one) with the grip force of the grasp, i.e. the
    actuator contact's normal force [N]."""
    if fingertip is None:
        kw = {}
        mass = getattr(model, "mass_kg", None)
        if mass is not None and np.isfinite(mass) and mass > 0:
            kw["object_mass_kg"] = float(mass)
        fingertip = FingertipModel(**kw)
    return replace(fingertip, grip_force_n=float(grip_force_n))


#: One period of the drive's exciter samples per (excitation, band-limited): every recording and
#: stream of the same excitation starts from the same samples (a prefilter costs two FFTs, about
#: as much as the rest of a new grasp's drive); the same function of the same input, bit for bit.
_PERIODS: LRU = LRU(CACHE_SIZES["stream.drive_periods"])


def drive_period(excitation: Excitation, bandlimited: bool = True) -> np.ndarray:
    """One loop period of the samples the fingertip drive works on (read-only): the
    excitation's, prefiltered by 1 / sinc^4 when ``bandlimited`` (see the module docstring)."""
    def build():
        e = excitation.signal
        out = bandlimited_samples(e, passes=2) if bandlimited else np.array(e, dtype=float)
        out.setflags(write=False)
        return out

    return _PERIODS.get_or_build((excitation, bool(bandlimited)), build)


class _TipSystems:
    """One fingertip model's discretised systems and periodic steady states (on first use:
    a batch recording's cached drive run needs neither)."""

    def __init__(self, tip: FingertipModel, excitation: Excitation, period: np.ndarray, bandlimited: bool) -> None:
        self.tip = tip
        self.excitation = excitation
        self.period = period                  # the exciter's samples per unit force (prefiltered if band-limited)
        self.bandlimited = bandlimited
        self._steady: tuple[SteadyState, SteadyState] | None = None

    @cached_property
    def drive(self) -> DriveSystems:
        return self.tip.discretised(self.excitation.sample_rate_hz)

    def steady(self) -> tuple[SteadyState, SteadyState]:
        """Periodic steady state of the actuator and mic contact forces under the looped excitation."""
        if self._steady is None:
            fe = self.tip.actuator_force_n * self.period
            self._steady = (SteadyState(self.drive.act, fe, self.bandlimited),
                            SteadyState(self.drive.mic, fe, self.bandlimited))
        return self._steady


@dataclass
class _Run:
    """The drive in contact: its state at the end of the last span (``None``: periodic steady
    state) and how many samples it has run linearly since it started or last separated."""

    systems: _TipSystems
    x: np.ndarray | None
    run: int = 0


class FingertipDrive:
    """The fingertip drive of one recording (a stream or a batch recording).

    ``forces(tip, grip_force_n, s, n)`` gives the dynamic actuator contact force at samples
    s .. s + n; ``reset()`` lets the next grasp start from rest; ``settle(tip, grip_force_n)``
    puts the drive into its periodic steady state.  ``tip`` is the grasp's fingertip model
    with grip force 0: the grip force does not enter the linear dynamics (tests check it),
    only the separation check and the one-sided model, so one discretised model serves every
    grip force.  ``runs`` (an LRU, e.g. ``SynthesisCache.forces``) keeps runs from rest.
    ``bandlimited``: the excitation is the band-limited signal a sound card plays (see the
    module docstring); False: piecewise linear between its samples (the former drive).
    """

    def __init__(self, excitation: Excitation, runs: LRU | None = None, bandlimited: bool = True) -> None:
        self.excitation = excitation
        self.bandlimited = bool(bandlimited)
        self.sample_rate_hz = int(excitation.sample_rate_hz)
        self._systems: LRU[_TipSystems] = LRU(CACHE_SIZES["stream.drive_systems"])
        self._runs = runs
        self._state: _Run | None = None
        self.separated = False                    # a contact would have pulled
        self.min_contact_force_n = np.inf          # lowest total contact force seen [N]

    @cached_property
    def period(self) -> np.ndarray:
        """One loop period of the excitation samples the drive works on: band-limited,
        prefiltered for the two first-order holds of the chain (:func:`drive_period`)."""
        return drive_period(self.excitation, self.bandlimited)

    def reset(self) -> None:
        """The actuator fingertip left the object: the next grasp starts from rest."""
        self._state = None

    def systems(self, tip: FingertipModel) -> _TipSystems:
        return self._systems.get_or_build(tip, lambda: _TipSystems(tip, self.excitation, self.period, self.bandlimited))

    def settle(self, tip: FingertipModel, grip_force_n: float) -> SteadyState:
        """Put the drive into its periodic steady state (a grasp held for ever) and return the
        actuator force's; ValueError where a contact would separate there."""
        sy = self.systems(tip)
        act, mic = sy.steady()
        lowest = grip_force_n + min(act.output.min(), mic.output.min())
        if lowest < 0:
            raise ValueError("the fingertip contact separates in steady state: the periodic (linear) "
                             "steady state does not exist")
        self.min_contact_force_n = min(self.min_contact_force_n, lowest)
        self._state = _Run(sy, None)
        return act

    def forces(self, tip: FingertipModel, grip_force_n: float, s: int, n: int):
        """Dynamic actuator contact force [N] at samples s .. s + n, and the drive's periodic
        steady state if it is in it (else ``None``); ``grip_force_n`` (the lowest over the
        spans it covers) sets the separation check and the one-sided model."""
        sy = self.systems(tip)
        d = self._state
        if d is None or d.systems is not sy:
            # from rest, or the same contact with new parameters: keep the state
            d = self._state = _Run(sy, np.zeros(8) if d is None else self._state_at(d, s))
        elif d.x is not None and d.run * sy.drive.act.slowest_decay_rate_per_s() >= SETTLE_E_FOLDS * self.sample_rate_hz:
            d.x = None                                      # the transient has decayed: periodic from here on
        if d.x is None:
            act, mic = sy.steady()
            idx = (s + np.arange(n + 1)) % self.excitation.period_samples
            f = act.output[idx]
            lowest = grip_force_n + min(f[:n].min(), mic.output[idx[:n]].min())
            if lowest >= 0:
                self.min_contact_force_n = min(self.min_contact_force_n, lowest)
                return f, act
            d.x, d.run = act.state_at(s), 0               # a contact lifts off: not periodic any more
        x0 = d.x if np.any(d.x) else None
        f, mic_low, d.x = self._linear_run(sy, x0, s, n)
        lowest = grip_force_n + min(f[:n].min(), mic_low)
        if lowest < 0:
            self.separated = True
            f, lowest, d.x = replace(tip, grip_force_n=grip_force_n).one_sided_forces(
                self._exciter_force(tip, s, n), self.sample_rate_hz, x0)
            d.run = 0
        else:
            d.run += n
        self.min_contact_force_n = min(self.min_contact_force_n, lowest)
        return f, None

    def _state_at(self, d: _Run, s: int) -> np.ndarray:
        return d.x if d.x is not None else d.systems.steady()[0].state_at(s)

    def _exciter_force(self, tip: FingertipModel, s: int, n: int) -> np.ndarray:
        """The exciter force [N] at samples s .. s + n."""
        return tip.actuator_force_n * self.period[(s + np.arange(n + 1)) % self.excitation.period_samples]

    def _linear_run(self, sy: _TipSystems, x0, s: int, n: int):
        """The linear model over samples s .. s + n from ``x0`` (None: rest): the actuator
        force there, the lowest mic-side force over s .. s + n - 1, the state at s + n.
        Runs from rest are kept in ``runs`` (a batch recording is one)."""
        def run():
            fe = self._exciter_force(sy.tip, s, n)
            f = np.empty(n + 1)
            f[:n] = sy.drive.act.response(fe[:n], x0)
            x = sy.drive.act.final_state(fe, x0)
            f[n] = sy.drive.act.output(x, fe[n])
            f.setflags(write=False)
            return f, float(sy.drive.mic.response(fe[:n], x0).min()), x

        if x0 is not None or self._runs is None:
            return run()
        key = (sy.tip, self.excitation, self.bandlimited, s % self.excitation.period_samples, n)
        f, mic_low, x = self._runs.get_or_build(key, run)
        return f, mic_low, x.copy()
