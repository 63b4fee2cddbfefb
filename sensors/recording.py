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

from .contact import Contact
from .excitation import Excitation
from .fingertip import FingertipModel
from .leak import LeakRecording, align_leak, excitation_lag, load_leak
from .observation import AcousticObservation
from .synthesis import ModalSystem

__all__ = ["MIC_GAIN_PER_M", "mic_gain", "simulate_recording"]

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
                       steady_state: bool = False) -> AcousticObservation:
    """Simulate the contact microphone while the actuator plays ``excitation`` in a grasp.

    Parameters
    ----------
    model : modal model of the grasped object (``sensors.ModalModel`` or compatible).
    excitation : the looping excitation (``.loop``, ``.fs``, ``.period_s``, ``.to_dict``).
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

    Returns
    -------
    sensors.AcousticObservation with float32 waveform, metadata ``source="sim"`` and the
    settings used.
    """
    if not isinstance(excitation, Excitation):
        raise TypeError(f"excitation must be a sensors.Excitation, got {type(excitation).__name__}")
    if not np.isfinite(noise_std) or noise_std < 0:
        raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
    fs = excitation.fs
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
        sysm = _cached_system(model, fs, geom, contacts, method, output)
        if steady_state:
            force_p, info = _periodic_fingertip_force(fingertip, excitation)
            y = np.resize(sysm.periodic_response(force_p), n)
        else:
            force, info = _cached_force(fingertip, excitation, e)
            y = sysm.response(force)
        meta["fingertip_separated"] = info["separated"]
        meta["fingertip"] = {k: float(v) for k, v in fingertip.__dict__.items()}
    wave = mic_gain(output) * y
    if noise_std > 0:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        wave = wave + noise_std * gen.standard_normal(n)
    if leak is not None:
        if not isinstance(leak, LeakRecording):
            meta["leak_file"] = os.fspath(leak)
            leak = load_leak(leak)
        # the synthesized signal's own excitation peak (0 when nothing was synthesized)
        target = excitation_lag(y, excitation.signal, max_lag=excitation.period_samples - 1) if touching else 0
        wave = wave + align_leak(leak, excitation, n, target_lag=target)
        meta["leak_target_lag"] = int(target)
    return AcousticObservation(wave.astype(np.float32), fs, excitation, 0.0, meta)


# The per-grasp set-up (damping matrix, eigen-decomposition) dominates a short recording;
# the same grasp is typically sensed with several excitations, so keep the last few systems.
_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()
_CACHE_SIZE = 8


def _cached_system(model, fs, geom, contacts, method, output) -> ModalSystem:
    key = (id(model), float(fs), method, output,
           np.concatenate([np.ravel(g) for g in geom]).tobytes(), tuple(contacts))
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is model:
        _CACHE.move_to_end(key)
        return hit[1]
    sysm = ModalSystem.build(model, fs, *geom, contacts, method=method, output=output)
    _CACHE[key] = (model, sysm)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return sysm


_FORCE_CACHE: "OrderedDict[tuple, tuple]" = OrderedDict()


def _cached_force(fingertip: FingertipModel, excitation: Excitation, e: np.ndarray):
    """The drive force depends on the fingertip model and the excitation only, not on the
    grasp: computed once per (fingertip, excitation, length)."""
    key = (fingertip, excitation, len(e))
    hit = _FORCE_CACHE.get(key)
    if hit is not None:
        _FORCE_CACHE.move_to_end(key)
        return hit
    force, info = fingertip.contact_force(e, excitation.fs, return_info=True)
    force.setflags(write=False)
    _FORCE_CACHE[key] = (force, info)
    while len(_FORCE_CACHE) > _CACHE_SIZE:
        _FORCE_CACHE.popitem(last=False)
    return force, info


def _periodic_fingertip_force(fingertip: FingertipModel, excitation: Excitation):
    """Periodic steady-state drive force (linear fingertip model; one period)."""
    f, info = fingertip.periodic_contact_force(excitation.signal, excitation.fs, return_info=True)
    if info["separated"]:
        raise ValueError("the fingertip contact separates in steady state: the periodic (linear) "
                         "steady state does not exist; use steady_state=False")
    return f, info
