"""The fingertip drive's contact force under the looped excitation, for closed-form features.

A recording from rest drives the object with the first-order-hold run of the fingertip drive's
discrete system (``FingertipModel.discretised``) over the whole recording: its sampled
periodic steady state (one period) plus its transient from rest, a sum of the drive's
decaying modes (:class:`sensors.synthesis.window_spectra.Exponentials`).  A settled grasp is
driven by the drive's periodic steady state as ``FingertipDrive.settle`` gives it (per
harmonic with the band-limited drive).  :func:`drive_spectrum` gives both, and the lowest
dynamic contact force either may reach (the separation check).

Two evaluations of the run from rest, the same numbers to rounding:

- the reference (``CLOSED_FORM_DRIVE = False``): ``SteadyState`` of the actuator and the
  microphone side (period-aliased impulse responses, two FFTs each), the state at phase 0 by
  ``DiscreteSystem.periodic_state`` and its modal coordinates by the inverse eigenvectors;
- the closed form (True, the default): the drive in complex modes (``FingertipModel.modes``:
  one lean eigen-solve of the 8 x 8 state matrix, four modes); one compiled pass
  over the period from rest gives the state at phase 0 in modal coordinates,
  z0 = z[P] / (1 - a^P), and a second from z0 both sides' steady periods at once; the
  steady period's DFT at the feature bins, which the window spectra need, is the discrete
  transfer function there, U_m (D + sum_k Re-pair of c_k (G0_k w + G1_k) / (1 - a_k w)),
  instead of an FFT of the period.  Per new fingertip model (a randomized object mass) about
  1 ms against 2.6-2.8 ms on GraspPosition-v0's probes; ``tests/test_closed_form_drive.py``.
- with ``EXCITER_SUMS`` (the default), no pass over the period at all: the phase-0 state from
  the exciter period's geometric sums at the drive's four poles, the separation check from a
  bound (each mode's steady |z| <= (|G0| + |G1|) max|u| / (1 - |a|)), the period and the exact
  lowest force only where that bound cannot rule a separation out (a grip below about 25 N
  at the default fingertip).  The window spectra then take the object's phase-0 state from
  the same sums through the drive's modes (``sensors.synthesis.exciter_sums``);
  ``tests/test_exciter_sums.py``.
"""

from __future__ import annotations

import numpy as np

from .._infra.jit import jitted
from .._infra.lru import CACHE_SIZES, LRU
from .fingertip import FingertipModel
from .exciter_sums import ExciterSums, SteadyDrive
from .lti import EigenPart, SteadyState
from .window_spectra import Exponentials, bin_phasors, closed_form_supported, periodic_transient

__all__ = ["CLOSED_FORM_DRIVE", "DriveSpectrum", "drive_spectrum", "exciter_period"]

#: :func:`drive_spectrum` from rest: True evaluates the drive's steady period, its state at
#: phase 0 and its spectrum at the feature bins in closed form (two compiled passes over one
#: period), False through ``SteadyState`` and ``periodic_state`` (the reference; the same
#: numbers to rounding, ``tests/test_closed_form_drive.py``).  Read at each call.
CLOSED_FORM_DRIVE = True

#: The closed-form drive from rest: True takes its phase-0 state from the exciter period's
#: geometric sums (``sensors.synthesis.exciter_sums``: one real product for its four modes) and
#: runs its steady period only where a cheap bound cannot rule out a separation, and the window
#: spectra take the object's phase-0 state from the same sums (``SteadyDrive``); False runs
#: the period (two compiled passes) and the object's state from it (the reference; the same
#: numbers to rounding, ``tests/test_exciter_sums.py``).  Read at each call.
EXCITER_SUMS = True


class DriveSpectrum:
    """One fingertip model under the looped excitation: the contact force's steady ``period``
    [N] and ``transient`` from rest, the lowest contact force either may reach
    (``lowest_dynamic_n``, a bound; ``lowest_bound_n`` a lower one known without the period;
    :meth:`separates` is the separation check), and the
    period's DFT at the feature bins where known (``bin_spectrum``, else ``None``: the window
    spectra transform the period).  ``steady``: the drive in complex modes at phase 0 of its
    steady state (``EXCITER_SUMS``), which gives the period and the lowest force on first use."""

    def __init__(self, period: np.ndarray | None, transient: Exponentials, lowest_dynamic_n: float | None,
                 bin_spectrum: np.ndarray | None = None, steady: "_SteadyRun | None" = None,
                 lowest_bound_n: float = -np.inf) -> None:
        self._period = period
        self.transient = transient
        self._lowest = lowest_dynamic_n
        self.bin_spectrum = bin_spectrum
        self.steady = steady
        self.lowest_bound_n = lowest_bound_n      # <= lowest_dynamic_n, known without the period

    def _run(self) -> None:
        self._period, self._lowest = self.steady.run(self.transient)

    @property
    def period(self) -> np.ndarray:
        if self._period is None:
            self._run()
        return self._period

    @property
    def lowest_dynamic_n(self) -> float:
        if self._lowest is None:
            self._run()
        return self._lowest

    def separates(self, grip_force_n: float) -> bool:
        """Whether a contact may separate under ``grip_force_n`` (grip plus the lowest dynamic
        force below 0); the cheap bound settles it where it can, the period elsewhere."""
        if grip_force_n + self.lowest_bound_n >= 0:
            return False
        return grip_force_n + self.lowest_dynamic_n < 0


#: The exciter force period the drive runs under and its ``np.fft.rfft``, per (excitation,
#: band-limited, actuator force): a new object mass (a randomized density) changes the drive's
#: systems, never its input, so every new drive spectrum shares these (the same numbers).
_EXCITER_PERIODS: LRU = LRU(CACHE_SIZES["synthesis.exciter_periods"])


def exciter_period(stream, actuator_force_n: float, period: np.ndarray):
    """``(force period [N], its rfft, its ExciterSums)`` of the exciter (read-only), kept per
    excitation."""
    def build():
        fe = actuator_force_n * period
        spectrum = np.fft.rfft(fe)
        fe.setflags(write=False)
        spectrum.setflags(write=False)
        return fe, spectrum, ExciterSums(fe)

    key = (stream.excitation, stream.drive.bandlimited, float(actuator_force_n))
    return _EXCITER_PERIODS.get_or_build(key, build)


def drive_spectrum(stream, tip: FingertipModel, from_rest: bool, bins: np.ndarray | None = None) -> DriveSpectrum | None:
    """The drive's contact force as the time-domain chain computes it (``stream``: an
    ``AcousticStream``, ``tip``: the grasp's fingertip model with grip force 0): settled, its
    periodic steady state (``FingertipDrive.settle``); from rest, one first-order-hold run
    over the whole recording (``FingertipDrive.forces``), i.e. the discrete system's periodic
    steady state under the (prefiltered) exciter samples plus its transient from rest.
    ``bins``: the feature bins whose spectrum to give (closed form only).  ``None`` where the
    drive is not in complex modes (the time-domain chain then runs)."""
    sy = stream.drive.systems(tip)
    if not from_rest:
        act, mic = sy.steady()
        return DriveSpectrum(act.output, Exponentials.none(), float(min(act.output.min(), mic.output.min())))
    fe, fe_spectrum, sums = exciter_period(stream, tip.actuator_force_n, sy.period)
    modes = tip.modes(stream.excitation.sample_rate_hz) if CLOSED_FORM_DRIVE else None
    if modes is not None:
        if EXCITER_SUMS:
            return _from_sums(*modes, fe, fe_spectrum, sums, bins)
        return _closed_form(*modes, fe, fe_spectrum, bins)
    if not (closed_form_supported(sy.drive.act) and closed_form_supported(sy.drive.mic)):
        return None
    act = SteadyState(sy.drive.act, fe, input_spectrum=fe_spectrum)       # sampled (FOH) steady states
    mic = SteadyState(sy.drive.mic, fe, input_spectrum=fe_spectrum)
    x0 = sy.drive.act.periodic_state(fe)
    transient = periodic_transient(sy.drive.act, x0)
    mic_tr = periodic_transient(sy.drive.mic, x0)
    lowest = min(act.output.min() - transient.bound(), mic.output.min() - mic_tr.bound())
    return DriveSpectrum(act.output, transient, float(lowest))


def _closed_form(act: EigenPart, mic: EigenPart, fe: np.ndarray, fe_spectrum: np.ndarray,
                 bins: np.ndarray | None) -> DriveSpectrum:
    """The run from rest of one complex-mode part observed at two outputs (one state
    equation: ``FingertipModel.modes``): two compiled passes over the period."""
    run = jitted(globals(), "_periodic_run", cache=True)
    a_P = np.exp(act.lam * act.T * len(fe))                   # as EigenPart.periodic_vector
    z0, act_period, mic_period = run(act.a, a_P, act.G0, act.G1, act.co, mic.co, act.D, mic.D,
                                     np.ascontiguousarray(fe))
    transient, mic_tr = (_transient(p, z0) for p in (act, mic))
    lowest = min(act_period.min() - transient.bound(), mic_period.min() - mic_tr.bound())
    act_period.setflags(write=False)
    spectrum = None
    if bins is not None:
        m = np.asarray(bins, dtype=int)
        w = bin_phasors(m, len(fe))
        spectrum = fe_spectrum[m] * _transfer(act, w)
    return DriveSpectrum(act_period, transient, float(lowest), spectrum)


def _from_sums(act: EigenPart, mic: EigenPart, fe: np.ndarray, fe_spectrum: np.ndarray, sums: ExciterSums,
               bins: np.ndarray | None) -> DriveSpectrum:
    """As :func:`_closed_form`, the phase-0 state from the exciter's sums: the period and the
    exact lowest force wait for first use, the separation check takes a bound first."""
    z0 = sums.start(act)
    transient, mic_tr = _transient(act, z0), _transient(mic, z0)
    steady_act, steady_mic = _steady_bounds(act, mic, sums.input_max)
    bound = min(-steady_act - transient.bound(), -steady_mic - mic_tr.bound())
    spectrum = None
    if bins is not None:
        m = np.asarray(bins, dtype=int)
        spectrum = fe_spectrum[m] * _transfer(act, bin_phasors(m, len(fe)))
    return DriveSpectrum(None, transient, None, spectrum, _SteadyRun(sums, act, mic, z0, fe), bound)


def _steady_bounds(act: EigenPart, mic: EigenPart, input_max: float) -> tuple[float, float]:
    """Upper bounds of |y| over the periodic steady states of ``act`` and ``mic`` (one state
    equation, two outputs) under any input of magnitude at most ``input_max``: each mode's
    |z| <= (|G0| + |G1|) max|u| / (1 - |a|) and |y| <= sum |co| |z| + |D| max|u| (inf if a
    mode does not decay)."""
    a = np.abs(act.a)
    if not np.all(a < 1.0):
        return np.inf, np.inf
    z_max = (np.abs(act.G0) + np.abs(act.G1)) / (1.0 - a) * input_max
    return (float(np.abs(act.co) @ z_max) + abs(act.D) * input_max,
            float(np.abs(mic.co) @ z_max) + abs(mic.D) * input_max)


class _SteadyRun(SteadyDrive):
    """The drive at phase 0 of its steady state (:class:`SteadyDrive`, for the window spectra)
    with its microphone side, for the steady period and the exact lowest force on demand."""

    def __init__(self, sums: ExciterSums, act: EigenPart, mic: EigenPart, z0: np.ndarray, fe: np.ndarray) -> None:
        super().__init__(sums, act, z0)
        self.mic = mic
        self._fe = fe

    def run(self, transient: Exponentials) -> tuple[np.ndarray, float]:
        """The actuator side's steady period [N] and the lowest dynamic force of both sides
        (as :func:`_closed_form`: two compiled passes over the period)."""
        act, mic = self.drive, self.mic
        run = jitted(globals(), "_periodic_run", cache=True)
        a_P = np.exp(act.lam * act.T * len(self._fe))
        z0, act_period, mic_period = run(act.a, a_P, act.G0, act.G1, act.co, mic.co, act.D, mic.D,
                                         np.ascontiguousarray(self._fe))
        lowest = min(act_period.min() - transient.bound(), mic_period.min() - _transient(mic, self.start_coords).bound())
        act_period.setflags(write=False)
        return act_period, float(lowest)


def _transient(part: EigenPart, z0: np.ndarray) -> Exponentials:
    """The output transient from rest of a part whose periodic steady state passes phase 0 in
    the coordinates ``z0`` (``periodic_transient`` without the change of coordinates)."""
    c = -part.co * z0
    s = part.lam * part.T
    return Exponentials(np.concatenate([c / 2, np.conj(c) / 2]), np.concatenate([s, np.conj(s)]))


def _transfer(part: EigenPart, w: np.ndarray) -> np.ndarray:
    """The sampled (first-order-hold) transfer function of a complex-mode part at the DFT
    phasors ``w``: an input period's DFT times this is its steady output period's."""
    M = len(w)
    ww = np.concatenate([w, np.conj(w)])                           # at w and at conj(w) at once
    at = part.co @ ((part.G0[:, None] * ww + part.G1[:, None]) / (1.0 - part.a[:, None] * ww))
    return part.D + 0.5 * (at[:M] + np.conj(at[M:]))


# compiled by numba on first use (sensors._infra.jit)
def _periodic_run(a, a_P, G0, G1, co_act, co_mic, D_act, D_mic, u):
    """A complex-mode system z[n+1] = a z[n] + G0 u[n] + G1 u[n+1] under the P-periodic input
    ``u``: the state at phase 0 of its periodic steady state, z0 = z[P] / (1 - a^P) with z[P]
    one period from rest, and from there one period of both outputs y[n] = Re(co . z[n]) +
    D u[n] (actuator and microphone side).  Each step waits for the last: two modes at a time,
    everything in scalar registers, keep that wait short (an odd last mode is paired with
    itself, weight 0)."""
    K = a.shape[0]
    P = u.shape[0]
    ext = np.empty(P + 1)
    ext[:P] = u
    ext[P] = u[0]
    z0 = np.zeros(K, dtype=np.complex128)
    act = D_act * u
    mic = D_mic * u
    for k in range(0, K, 2):
        j = k + 1 if k + 1 < K else k
        wj = 1.0 if j != k else 0.0
        ar, ai, br, bi = a[k].real, a[k].imag, a[j].real, a[j].imag
        g0r, g0i, g1r, g1i = G0[k].real, G0[k].imag, G1[k].real, G1[k].imag
        h0r, h0i, h1r, h1i = G0[j].real, G0[j].imag, G1[j].real, G1[j].imag
        zr, zi, yr, yi = 0.0, 0.0, 0.0, 0.0
        for n in range(P):                       # from rest over one period
            u0 = ext[n]
            u1 = ext[n + 1]
            # the input terms first: one product and two sums from one step to the next
            t = (g0r * u0 + g1r * u1) + (ar * zr - ai * zi)
            zi = (g0i * u0 + g1i * u1) + (ar * zi + ai * zr)
            zr = t
            t = (h0r * u0 + h1r * u1) + (br * yr - bi * yi)
            yi = (h0i * u0 + h1i * u1) + (br * yi + bi * yr)
            yr = t
        zk = complex(zr, zi) / (1.0 - a_P[k])
        zj = complex(yr, yi) / (1.0 - a_P[j])
        z0[k] = zk
        z0[j] = zj
        c0r, c0i, c1r, c1i = co_act[k].real, co_act[k].imag, co_mic[k].real, co_mic[k].imag
        d0r, d0i = wj * co_act[j].real, wj * co_act[j].imag
        d1r, d1i = wj * co_mic[j].real, wj * co_mic[j].imag
        zr, zi, yr, yi = zk.real, zk.imag, zj.real, zj.imag
        for n in range(P):                       # the steady period from z0, with the outputs
            act[n] += (c0r * zr - c0i * zi) + (d0r * yr - d0i * yi)
            mic[n] += (c1r * zr - c1i * zi) + (d1r * yr - d1i * yi)
            u0 = ext[n]
            u1 = ext[n + 1]
            t = (g0r * u0 + g1r * u1) + (ar * zr - ai * zi)
            zi = (g0i * u0 + g1i * u1) + (ar * zi + ai * zr)
            zr = t
            t = (h0r * u0 + h1r * u1) + (br * yr - bi * yi)
            yi = (h0i * u0 + h1i * u1) + (br * yi + bi * yr)
            yr = t
    return z0, act, mic
