"""The whole simulated recording: excitation -> fingertip model -> modal synthesis -> mic.

Microphone level
----------------
A piezo contact microphone's output follows the surface motion under it; the rig records it
through a sound card at full scale 1.  ``MIC_GAIN_PER_M`` maps object displacement [m] at the
mic contact (the paper's choice of quantity) to recorded units: 2e5 per metre, i.e. full scale
at 5 um.  It is ONE constant for every object and grasp, so relative levels between objects
(material and damping information) survive.  Measured with the default fingertip model (1 N
exciter, 40 N grip) on the FEM bars (200 x 20 x 20 mm) and tubes (20/16 mm) of the paper's
materials, grasped antipodally 40 mm from the centre, 1 s recordings peak at about
0.003-0.05 (aluminium, steel, wood) under the sweeps, with 3-10 kHz spectral peaks of 1e-5 to
1e-4, well above a 1e-4 noise floor (1e-6 per bin); the soft ABS objects deflect far more
below their first mode and peak at 0.8-2.5 (a real rig would turn its preamp down).  The
grasp position matters as much as the material: moved along the bar (0-80 mm from the
centre) the metal bars peak at 0.001-0.04 under the linear sweep (lowest at 60 mm, e.g.
0.002 for aluminium) and the ABS bar at 0.2-4.  The one-sample impulse carries ~4e4 times
less energy than a sweep (~200x lower RMS).
Velocity and acceleration outputs use the same gain referred to 5 kHz (the middle of the
feature band): divided by 2 pi 5 kHz and (2 pi 5 kHz)^2.
Recorded values are not clipped (the waveform stays float32; a clipping rig would have to
lower its gain).
"""

from __future__ import annotations

import os
from collections import OrderedDict
from typing import Sequence

import numpy as np

from ..modal.contact import Contact
from ..signals.excitation import Excitation
from .fingertip import FingertipModel
from ..signals.leak import LeakRecording, align_leak, excitation_lag, leak_file_identity, load_leak
from ..signals.observation import AcousticObservation
from .modal_system import ModalSystem

__all__ = ["MIC_GAIN_PER_M", "SynthesisCache", "mic_gain", "simulate_recording"]

MIC_GAIN_PER_M = 2e5
_REF_W = 2 * np.pi * 5000.0


def mic_gain(output: str = "displacement") -> float:
    """Recorded units per metre, per m/s or per m/s^2 (see module docstring)."""
    return {"displacement": MIC_GAIN_PER_M, "velocity": MIC_GAIN_PER_M / _REF_W,
            "acceleration": MIC_GAIN_PER_M / _REF_W**2}[output]


def simulate_recording(model, excitation: Excitation, duration_s: float,
                       actuator_contact: Contact | None, mic_contact: Contact | None,
                       other_contacts: Sequence[Contact] = (), fingertip: FingertipModel | None = None,
                       leak: LeakRecording | str | os.PathLike | None = None, noise_std: float = 0.0,
                       rng=None, output: str = "displacement", method: str = "exact",
                       steady_state: bool = False, cache: SynthesisCache | None = None) -> AcousticObservation:
    """Simulate the contact microphone while the actuator plays ``excitation`` in a grasp.

    Parameters
    ----------
    model : modal model of the grasped object (``sensors.ModalModel`` or compatible).
    excitation : the looping excitation (``.loop``, ``.sample_rate_hz``, ``.period_s``, ``.to_dict``).
    duration_s : recording length [s] (the paper records 5 s and uses the first second).
    actuator_contact, mic_contact : the two fingertip contacts on the object (object frame;
        force_n = normal force there).  ``None`` or zero force means that finger does not
        touch the object: no synthesis (the recording holds noise and leak only).
    other_contacts : further contacts (table, other objects); they damp the object.
    fingertip : lumped drive model; default ``FingertipModel`` with the grip force equal to
        the actuator contact's normal force and the model's ``mass_kg`` if it has one.
    leak : ``LeakRecording`` or path to its .npz (recorded for this excitation); aligned to
        the synthesized signal by the excitation peak and added.
    noise_std : standard deviation of white sensor noise, in recorded units (full scale 1).
    rng : seed or ``numpy.random.Generator`` for the noise.
    output : ``"displacement"`` (paper), ``"velocity"`` or ``"acceleration"`` at the mic.
    method : ``"exact"`` or ``"diagonal"`` modal damping (see ``sensors.modal_response``).
    steady_state : if True, the grasp has been vibrating long enough for the transient to
        have decayed: the exact periodic steady state (per harmonic of the loop frequency),
        repeated.  Default False: the recording starts with the excitation, from rest.
    cache : a :class:`SynthesisCache` to reuse per-grasp systems and drive forces across
        calls (``None``: nothing is kept).

    Returns
    -------
    sensors.AcousticObservation with float32 waveform, metadata ``source="sim"`` and the
    settings used.
    """
    if not isinstance(excitation, Excitation):
        raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
    if not np.isfinite(noise_std) or noise_std < 0:
        raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
    sample_rate_hz = excitation.sample_rate_hz
    e = excitation.loop(duration_s)
    n = len(e)
    others = list(other_contacts)
    for c in [actuator_contact, mic_contact, *others]:
        if c is not None and not isinstance(c, Contact):
            raise TypeError(f"contacts must be sensors.Contact, got {type(c).__name__}")
    touching = (actuator_contact is not None and mic_contact is not None
                and actuator_contact.force_n > 0 and mic_contact.force_n > 0)
    meta: dict = {"source": "sim", "output": output, "method": method, "steady_state": bool(steady_state),
                  "mic_gain": mic_gain(output), "noise_std": float(noise_std),
                  "contacts": {"actuator": None if actuator_contact is None else actuator_contact.to_dict(),
                               "mic": None if mic_contact is None else mic_contact.to_dict(),
                               "other": [c.to_dict() for c in others]},
                  "synthesized": bool(touching)}
    y = np.zeros(n)
    if touching:
        if fingertip is None:
            kw = {"grip_force_n": actuator_contact.force_n}
            mass = getattr(model, "mass_kg", None)
            if mass is not None and np.isfinite(mass) and mass > 0:
                kw["object_mass_kg"] = float(mass)
            fingertip = FingertipModel(**kw)
        contacts = [actuator_contact, mic_contact, *others]
        geom = (actuator_contact.position_m, actuator_contact.normal, mic_contact.position_m, mic_contact.normal)
        if cache is None:
            sysm = ModalSystem.build(model, sample_rate_hz, *geom, contacts, method=method, output=output)
        else:
            sysm = cache.system(model, sample_rate_hz, geom, contacts, method, output)
        if steady_state:
            force_p, info = _periodic_fingertip_force(fingertip, excitation)
            y = np.resize(sysm.periodic_response(force_p), n)
        else:
            force, info = _drive_force(fingertip, excitation, e) if cache is None else cache.force(fingertip, excitation, e)
            y = sysm.response(force)
        meta["fingertip_separated"] = info["separated"]
        meta["fingertip"] = {k: float(v) for k, v in fingertip.__dict__.items()}
    wave = mic_gain(output) * y
    if noise_std > 0:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        wave = wave + noise_std * gen.standard_normal(n)
    if leak is not None:
        if not isinstance(leak, LeakRecording):
            meta["leak_file"] = leak_file_identity(leak)
            leak = load_leak(leak)
        # the synthesized signal's own excitation peak (0 when nothing was synthesized)
        target = excitation_lag(y, excitation.signal, max_lag=excitation.period_samples - 1) if touching else 0
        wave = wave + align_leak(leak, excitation, n, target_lag=target)
        meta["leak_target_lag"] = int(target)
    return AcousticObservation(wave.astype(np.float32), sample_rate_hz, excitation, 0.0, meta)


class SynthesisCache:
    """What the recording chain may reuse across calls, owned by whoever passes it (a
    ``SimAcousticSensor`` owns one): the per-grasp modal systems (damping matrix and complex
    modes dominate a short recording, and one grasp is usually sensed with several
    excitations) and the fingertip drive forces (they depend on the fingertip model and the
    excitation only). Least recently used entries go first; ``len``, ``hits`` and ``misses``
    say how well it works. Systems are keyed by the model object itself (held, so its id
    cannot be reused) and the grasp's contacts.
    """

    def __init__(self, maxsize: int = 8) -> None:
        if int(maxsize) < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize!r}")
        self.maxsize = int(maxsize)
        self._systems: OrderedDict[tuple, tuple] = OrderedDict()
        self._forces: OrderedDict[tuple, tuple] = OrderedDict()
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._systems) + len(self._forces)

    def __repr__(self) -> str:
        return (f"SynthesisCache({len(self._systems)} systems, {len(self._forces)} forces, maxsize={self.maxsize}, "
                f"hits={self.hits}, misses={self.misses})")

    def clear(self) -> None:
        self._systems.clear()
        self._forces.clear()

    def _get(self, table: OrderedDict, key, build):
        hit = table.get(key)
        if hit is not None:
            self.hits += 1
            table.move_to_end(key)
            return hit[1]
        self.misses += 1
        value = build()
        table[key] = (key, value)
        while len(table) > self.maxsize:
            table.popitem(last=False)
        return value

    def system(self, model, sample_rate_hz, geom, contacts, method, output) -> ModalSystem:
        key = (_ModelKey(model), float(sample_rate_hz), method, output,
               np.concatenate([np.ravel(g) for g in geom]).tobytes(), tuple(contacts))
        return self._get(self._systems, key,
                         lambda: ModalSystem.build(model, sample_rate_hz, *geom, contacts, method=method, output=output))

    def force(self, fingertip: FingertipModel, excitation: Excitation, e: np.ndarray):
        return self._get(self._forces, (fingertip, excitation, len(e)), lambda: _drive_force(fingertip, excitation, e))


class _ModelKey:
    """Hashes a model by identity while holding it (so the id stays its own)."""

    __slots__ = ("model",)

    def __init__(self, model) -> None:
        self.model = model

    def __hash__(self) -> int:
        return id(self.model)

    def __eq__(self, other) -> bool:
        return isinstance(other, _ModelKey) and other.model is self.model


def _drive_force(fingertip: FingertipModel, excitation: Excitation, e: np.ndarray):
    force, info = fingertip.contact_force(e, excitation.sample_rate_hz, return_info=True)
    force.setflags(write=False)
    return force, info


def _periodic_fingertip_force(fingertip: FingertipModel, excitation: Excitation):
    """Periodic steady-state drive force (linear fingertip model; one period)."""
    f, info = fingertip.periodic_contact_force(excitation.signal, excitation.sample_rate_hz, return_info=True)
    if info["separated"]:
        raise ValueError("the fingertip contact separates in steady state: the periodic (linear) "
                         "steady state does not exist; use steady_state=False")
    return f, info
