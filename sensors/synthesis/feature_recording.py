"""The features of a simulated recording without its samples: ``simulate_features``.

When only the 140 spectral features are observed, the recording of a static grasp under the
looping excitation need not be synthesized sample by sample: each feature window's spectrum
at the feature bins has a closed form (:mod:`sensors.synthesis.window_spectra`).  The chain is
the one of :func:`sensors.synthesis.recording.simulate_recording`, term by term:

- the fingertip drive's contact force: from rest, the first-order-hold run of its discrete
  system over the whole recording (on the exciter samples, prefiltered by 1 / sinc^4 with the
  band-limited drive), i.e. that system's sampled periodic steady state (one period) plus its
  transient from rest, a sum of the drive's decaying modes; settled, the drive's periodic
  steady state as ``FingertipDrive.settle`` gives it (per harmonic with the band-limited drive)
  (:mod:`sensors.synthesis.drive_spectrum`);
- the object at the microphone: from rest, the modal system's window spectra under that force
  (steady state, particular solutions and each mode's onset); settled, its steady state per
  bin (the band-limited drive: per harmonic from the continuous-time transfer function, as
  ``SteadyState(..., bandlimited=True)``); times the microphone gain;
- the noise: the same seeded samples drawn as the time-domain chain draws them, transformed
  (so the generator's stream and the results are the same in both paths);
- the spectra's magnitudes averaged over the windows as ``sensors.spectral_features`` does.

Both paths agree to rounding (``tests/test_closed_form_features.py``: 1e-6 relative, the
time-domain waveform being float32).  Where the closed form does not apply the time-domain
chain runs and its features are returned (metadata ``features_path``): a leak (its alignment
needs the synthesized signal's excitation peak), a fingertip contact that may separate, a
dense fallback part, a window that is not a whole number of samples or bins.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU
from ..modal.contact import Contact
from ..signals.excitation import Excitation
from ..signals.features import feature_frequencies_hz
from ..signals.leak import LeakRecording
from .caches import IdentityKey, SynthesisCache
from . import drive_spectrum as _drive
from .fingertip import FingertipModel
from .grasp_state import GraspState
from .microphone import mic_gain
from .recording import simulate_recording
from .stream import AcousticStream
from .window_spectra import bandlimited_steady_spectra, window_spectra

__all__ = ["FeatureObservation", "simulate_features"]

#: The stream a grasp's spectra are resolved through is given a generator for its (never read)
#: microphone noise: ``np.random.default_rng()`` seeds itself from the OS, about 45 of the
#: stream's 110 us per grasp.  Nothing on this path draws noise (the reference's generator is
#: seeded from OS entropy, yet features are reproducible under a seed), so the spectra are the
#: same bytes.  False: a fresh self-seeded generator per grasp (the reference).  Read at each call.
LEAN_FEATURE_STREAM = True
# never drawn from (see LEAN_FEATURE_STREAM)
UNUSED_RNG = np.random.Generator(np.random.PCG64(0))


@dataclass
class FeatureObservation:
    """A simulated recording's spectral features without its samples.

    ``window_amplitudes`` (n_windows, n_features): the amplitude per excitation-period
    window, as ``sensors.spectral_features(..., average=False)`` gives it; ``metadata``: as
    ``simulate_recording``'s, plus ``features_path`` (``"closed_form"`` or ``"time_domain"``).
    """

    window_amplitudes: np.ndarray
    sample_rate_hz: int
    excitation: Excitation
    metadata: dict = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """The length of the recording these features stand for [s]."""
        return float(self.metadata["duration_s"])

    def features(self, *, average: bool = True) -> np.ndarray:
        """The 140 features (mean over windows), or one row per window."""
        return self.window_amplitudes.mean(axis=0) if average else self.window_amplitudes.copy()


_BINS: LRU = LRU(CACHE_SIZES["synthesis.feature_bins"])


def _feature_bins(excitation: Excitation) -> np.ndarray | None:
    """The feature frequencies as DFT bins of one excitation period, or None if they are not
    whole bins (the time-domain chain's chirp-z path then applies)."""
    def build():
        P = excitation.period_samples
        bins = feature_frequencies_hz() * P / excitation.sample_rate_hz
        whole = int(round(excitation.period_s * excitation.sample_rate_hz)) == P and \
            np.allclose(bins, np.round(bins), rtol=0, atol=1e-9)
        return (np.round(bins).astype(int) if whole else None,)

    return _BINS.get_or_build((excitation.sample_rate_hz, excitation.period_s), build)[0]


def _window_amplitudes(spectra: np.ndarray, P: int) -> np.ndarray:
    return 2.0 * np.abs(spectra) / P


def simulate_features(model, excitation: Excitation, duration_s: float,
                      actuator_contact: Contact | None, mic_contact: Contact | None,
                      other_contacts: Sequence[Contact] = (), fingertip: FingertipModel | None = None,
                      leak: LeakRecording | str | os.PathLike | None = None, noise_std: float = 0.0,
                      rng=None, output: str = "displacement", method: str = "exact",
                      steady_state: bool = False, cache: SynthesisCache | None = None,
                      contact_model: str = "spring_damper", bandlimited: bool = True) -> FeatureObservation:
    """The features of ``simulate_recording(...)`` (same arguments) without synthesizing its
    samples where the closed form applies (module docstring); the time-domain chain otherwise.

    The noise generator ``rng`` advances exactly as in ``simulate_recording``.
    """
    if not isinstance(excitation, Excitation):
        raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
    if not np.isfinite(noise_std) or noise_std < 0:
        raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
    sample_rate_hz = excitation.sample_rate_hz
    n = excitation.loop_samples(duration_s)
    P = excitation.period_samples
    bins = _feature_bins(excitation)
    others = tuple(other_contacts)
    cache = SynthesisCache() if cache is None else cache
    grasp = GraspState(model, actuator_contact, mic_contact, others)
    spectra = None
    meta: dict = {}
    if bins is not None and leak is None and n >= P:
        spectra, meta = _object_spectra(grasp, excitation, fingertip, output, method, steady_state, cache,
                                        bins, n // P, contact_model, bandlimited)
    if spectra is None:
        rec = simulate_recording(model, excitation, duration_s, actuator_contact, mic_contact, others,
                                 fingertip=fingertip, leak=leak, noise_std=noise_std, rng=rng, output=output,
                                 method=method, steady_state=steady_state, cache=cache, contact_model=contact_model,
                                 bandlimited=bandlimited)
        meta = dict(rec.metadata, features_path="time_domain", duration_s=rec.duration_s)
        return FeatureObservation(rec.features(average=False), sample_rate_hz, excitation, meta)
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    total = mic_gain(output) * spectra
    if noise_std > 0:
        noise = rng.standard_normal(n)                   # drawn as the Microphone draws it
        W = n // P
        total = total + noise_std * np.fft.rfft(noise[:W * P].reshape(W, P), axis=1)[:, bins]
    meta.update({"source": "sim", "output": output, "method": method, "steady_state": bool(steady_state),
                 "contact_model": contact_model, "mic_gain": mic_gain(output), "noise_std": float(noise_std),
                 "contacts": {"actuator": None if actuator_contact is None else actuator_contact.to_dict(),
                              "mic": None if mic_contact is None else mic_contact.to_dict(),
                              "other": [c.to_dict() for c in others]},
                 "synthesized": grasp.closed, "features_path": "closed_form", "duration_s": n / sample_rate_hz})
    return FeatureObservation(_window_amplitudes(total, P), sample_rate_hz, excitation, meta)


def _object_spectra(grasp: GraspState, excitation: Excitation, fingertip, output, method, steady_state,
                    cache: SynthesisCache, bins: np.ndarray, n_windows: int, contact_model: str,
                    bandlimited: bool):
    """The motion at the microphone as window spectra (``None`` where the closed form does not
    apply) and its metadata.  Cached per contact table (the spectra of the system the table was
    first resolved to), fingertip model, excitation and windows: sensing a grasp again costs
    only its noise."""
    if not grasp.closed:
        return np.zeros((n_windows, len(bins)), complex), {}
    table = grasp.contact_table()
    # per model (a few: they can be large), then per grasp (many: a task's grasp positions)
    grasps = cache.window_spectra.get_or_build(IdentityKey(grasp.model),
                                               lambda: LRU(CACHE_SIZES["synthesis.grasp_spectra"]))
    key = (table.shape, table.tobytes(), fingertip, excitation, output, method, n_windows, bool(steady_state),
           bins.tobytes(), contact_model, bandlimited, bool(_drive.CLOSED_FORM_DRIVE), bool(_drive.EXCITER_SUMS))
    grip = grasp.actuator.force_n
    hit = grasps.get(key)
    if hit is None:
        hit = grasps.put(key, _build_spectra(grasp, excitation, fingertip, output, method, steady_state, cache,
                                             bins, n_windows, contact_model, bandlimited))
    spectra, drive, tip = hit
    if spectra is None or drive.separates(grip):
        return None, {}     # no closed form, or the contact may separate: the time-domain chain decides
    fingertip_meta = {k: float(v) for k, v in tip.__dict__.items()}
    fingertip_meta["grip_force_n"] = float(grip)        # grasp_fingertip(fingertip, model, grip)
    return spectra, {"fingertip_separated": False, "fingertip": fingertip_meta}


def _build_spectra(grasp, excitation, fingertip, output, method, steady_state, cache, bins, n_windows,
                   contact_model, bandlimited):
    """(window spectra or None, drive spectrum, fingertip model with grip force 0)."""
    stream = AcousticStream(excitation, fingertip, output=output, method=method, cache=cache, carry_state=False,
                            contact_model=contact_model, bandlimited=bandlimited,
                            rng=UNUSED_RNG if LEAN_FEATURE_STREAM else None)
    system, tip = stream.grasp_systems(grasp)
    closed_form_drive = (bool(_drive.CLOSED_FORM_DRIVE), bool(_drive.EXCITER_SUMS))
    drive = cache.drive_spectra.get_or_build((tip, excitation, bool(steady_state), bandlimited, closed_form_drive),
                                             lambda: _drive.drive_spectrum(stream, tip, not steady_state, bins))
    if drive is None:
        return None, None, tip
    if steady_state and bandlimited:          # the settled chain's steady state is per harmonic
        spectra = bandlimited_steady_spectra(system, drive.period, bins, n_windows)
    else:
        spectra = window_spectra(system, None if drive.steady else drive.period, drive.transient, bins, n_windows,
                                 from_rest=not steady_state, input_spectrum=drive.bin_spectrum, input_start=drive.steady)
    return spectra, drive, tip
