"""The whole simulated recording of a static grasp: excitation -> fingertip model -> modal
synthesis -> microphone.

A batch recording is ``sensors.synthesis.stream.AcousticStream`` over one constant span from
rest: the same systems, drive, default fingertip and microphone (``sensors.synthesis.microphone``
for the level, noise and leak).  As nothing follows that span, its system keeps only the
modes the drive reaches and the microphone sees (``carry_state=False``).  What it adds: the
leak is aligned to the synthesized signal's own excitation peak, and ``steady_state=True``
starts the grasp settled (``AcousticStream.settle``).
"""

from __future__ import annotations

import os
from typing import Sequence

import numpy as np

from ..modal.contact import Contact
from ..signals.excitation import Excitation
from ..signals.leak import LeakRecording, excitation_lag
from ..signals.observation import AcousticObservation
from .caches import SynthesisCache
from .drive import grasp_fingertip
from .fingertip import FingertipModel
from .grasp_state import GraspState
from .microphone import Microphone, mic_gain
from .stream import AcousticStream

__all__ = ["simulate_recording"]


def simulate_recording(model, excitation: Excitation, duration_s: float,
                       actuator_contact: Contact | None, mic_contact: Contact | None,
                       other_contacts: Sequence[Contact] = (), fingertip: FingertipModel | None = None,
                       leak: LeakRecording | str | os.PathLike | None = None, noise_std: float = 0.0,
                       rng=None, output: str = "displacement", method: str = "exact",
                       steady_state: bool = False, cache: SynthesisCache | None = None,
                       contact_model: str = "spring_damper", bandlimited: bool = True) -> AcousticObservation:
    """Simulate the contact microphone while the actuator plays ``excitation`` in a grasp.

    Parameters
    ----------
    model : modal model of the grasped object (``sensors.ModalModel`` or compatible).
    excitation : the looping excitation (``.loop``, ``.sample_rate_hz``, ``.period_s``, ``.to_dict``).
    duration_s : recording length [s] (the paper records 5 s and uses the first second).
    actuator_contact, mic_contact : the two fingertip contacts on the object (object frame;
        force_n = normal force there).  ``None`` or zero force means that finger does not
        touch the object: no synthesis (the recording holds noise and leak only).
    other_contacts : further contacts (table, other objects); those with a positive force
        damp the object.
    fingertip : lumped drive model; its grip force is the actuator contact's normal force
        (``sensors.synthesis.drive.grasp_fingertip``); default ``FingertipModel`` with the
        model's ``mass_kg`` if it has one.  Where a contact would separate, the one-sided
        model is integrated instead (metadata ``fingertip_separated``).
    leak : ``LeakRecording`` or path to its .npz (recorded for this excitation); aligned to
        the synthesized signal by the excitation peak and added.
    noise_std : standard deviation of white sensor noise, in recorded units (full scale 1).
    rng : seed or ``numpy.random.Generator`` for the noise.
    output : ``"displacement"`` (paper), ``"velocity"`` or ``"acceleration"`` at the mic.
    method : ``"exact"`` or ``"diagonal"`` modal damping (see ``sensors.modal_response``).
    steady_state : if True, the grasp has been vibrating long enough for the transient to
        have decayed: the exact periodic steady state (per harmonic of the loop frequency),
        repeated.  Default False: the recording starts with the excitation, from rest.
    contact_model : ``"spring_damper"`` (default): every contact, the fingertip pads included
        (their springs from ``fingertip``), is a spring and a damper on the object's modes;
        ``"damping"``: the paper's model, contacts only damp the free modes
        (``sensors.synthesis.modal_system.CONTACT_MODELS``).  Recorded in the metadata.
    cache : a :class:`SynthesisCache` to reuse per-grasp systems and drive forces across
        calls (``None``: nothing is kept).
    bandlimited : the excitation reaches the fingertip as the band-limited signal a sound
        card plays (default; exact in steady state); False: piecewise linear between samples,
        the drive of earlier datasets.  Metadata ``drive`` says which.

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
    n = len(excitation.loop(duration_s))
    others = tuple(other_contacts)
    grasp = GraspState(model, actuator_contact, mic_contact, others)
    meta: dict = {"source": "sim", "output": output, "method": method, "steady_state": bool(steady_state),
                  "contact_model": contact_model,
                  "drive": "bandlimited" if bandlimited else "foh",
                  "mic_gain": mic_gain(output), "noise_std": float(noise_std),
                  "contacts": {"actuator": None if actuator_contact is None else actuator_contact.to_dict(),
                               "mic": None if mic_contact is None else mic_contact.to_dict(),
                               "other": [c.to_dict() for c in others]},
                  "synthesized": grasp.closed}
    y = np.zeros(n)
    if grasp.closed:
        stream = AcousticStream(excitation, fingertip, output=output, method=method,
                                cache=SynthesisCache() if cache is None else cache, carry_state=False,
                                contact_model=contact_model, bandlimited=bandlimited)
        if steady_state:
            try:
                stream.settle(grasp)
            except ValueError as exc:
                raise ValueError(f"{exc}; use steady_state=False") from None
        y = stream.synthesize(n, grasp)
        meta["fingertip_separated"] = stream.fingertip_separated
        tip = grasp_fingertip(fingertip, model, actuator_contact.force_n)
        meta["fingertip"] = {k: float(v) for k, v in tip.__dict__.items()}
    # the leak's excitation peak on the synthesized signal's own (0 when nothing was synthesized)
    target = 0
    if leak is not None and grasp.closed:
        target = excitation_lag(y, excitation.signal, max_lag=excitation.period_samples - 1)
    microphone = Microphone(excitation, output, noise_std, rng, leak, target)
    wave = microphone.record(y)
    if leak is not None:
        if microphone.leak_file is not None:
            meta["leak_file"] = microphone.leak_file
        meta["leak_target_lag"] = int(target)
    return AcousticObservation(wave, sample_rate_hz, excitation, 0.0, meta)
