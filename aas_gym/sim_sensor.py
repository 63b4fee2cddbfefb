"""``SimAcousticSensor``: the simulated active acoustic sensor on any MuJoCo model.

The sensor needs two sites (default ``aas_actuator`` and ``aas_mic``, on the bodies of the
fingertips carrying the exciter and the microphone) and, for every object it may sense, a
shape and material: given explicitly as ``objects={body: ObjectSpec | "<material>_<shape>" |
sensors.ModalModel}``, or read from the ``aas_object:<body>`` custom texts our scenes carry.

Nothing happens until ``sense`` is called: it then reads the contacts of the current MuJoCo
state (the caller steps the simulation), finds the object pressed by both sensor fingertips,
builds or loads its modal model (memory cache here, disk cache in ``sensors``) and runs
``sensors.simulate_recording``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

import sensors
from aas_gym.contacts import ContactStream, ObjectContacts
from aas_gym.object_bodies import object_specs_from_model
from aas_gym.touching_grasp import TouchingMemo, touching_grasp
from sensors import Excitation, LeakRecording, SynthesisCache, load_leak
from sensors._infra.lru import CACHE_SIZES, LRU
from sensors.materials import scaled_material
from sensors.modal import TouchingObjects
from sensors.modal.basis import ModalBasis, with_material
from sensors.objects.catalog import ObjectSpec, get_object
from sensors.synthesis import simulate_features


#: Modal models of this process by (object, build options), ``ObjectSpec.modal_model`` built once:
#: scenes and envs holding the same object share one model (the disk cache in ``sensors`` serves
#: new processes). Pass your own ``LRU`` as ``SimAcousticSensor(models=...)`` to control its size
#: and lifetime.
MODAL_MODELS = LRU(CACHE_SIZES["sim.models"])


@dataclass(frozen=True)
class SensorVariation:
    """Per-episode variation of the simulated sensor (domain randomization), passed to
    :meth:`SimAcousticSensor.sense` as a value instead of set on the sensor.

    Attributes:
        noise_std: microphone noise std in waveform units (``None``: the sensor's own).
        damping_scale: multiplies the material's Rayleigh and contact damping.
        modulus_scale, density_scale: multiply Young's modulus and density (modes rescaled
            exactly, no new FEM solve).
        leak_scale: multiplies the leak recording.
    """

    noise_std: float | None = None
    damping_scale: float = 1.0
    modulus_scale: float = 1.0
    density_scale: float = 1.0
    leak_scale: float = 1.0

    def __post_init__(self) -> None:
        if self.noise_std is not None and not (math.isfinite(self.noise_std) and self.noise_std >= 0):
            raise ValueError(f"noise_std must be >= 0, got {self.noise_std!r}")
        for name in ("damping_scale", "modulus_scale", "density_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {v!r}")
        if not (math.isfinite(self.leak_scale) and self.leak_scale >= 0):
            raise ValueError(f"leak_scale must be >= 0, got {self.leak_scale!r}")

    @property
    def material_scales(self) -> tuple[float, float, float]:
        return (self.damping_scale, self.modulus_scale, self.density_scale)

    def to_dict(self) -> dict:
        return {"damping_scale": self.damping_scale, "modulus_scale": self.modulus_scale,
                "density_scale": self.density_scale, "leak_scale": self.leak_scale}


NO_VARIATION = SensorVariation()


class SensorSitesError(ValueError):
    """The model lacks the sensor's sites."""


class NoGraspError(RuntimeError):
    """No sensed object is pressed by both sensor fingertips: there is nothing to record."""


class SimAcousticSensor:
    """Simulated ``sensors.AcousticSensor`` reading contacts from a MuJoCo model.

    Args:
        model, data: the MuJoCo model and the data the caller steps.
        objects: body name -> ``ObjectSpec``, object name (``"wood_bar"``) or a ready
            ``sensors.ModalModel``. ``None`` reads the model's ``aas_object:`` descriptions.
        actuator_site, mic_site: names of the sensor sites.
        fingertip: ``sensors.FingertipModel`` (lumped exciter/fingertip drive); its grip force
            is the grasp's. ``None``: the synthesis default (with the object's mass).
        leak: ``sensors.LeakRecording`` or its .npz path, or a mapping excitation name ->
            leak (the rig records one per excitation); added to every recording.
        noise_std: std of additive microphone noise.
        seed: seed of the noise generator (``rng`` wins if given).
        rng: ``numpy.random.Generator`` for the noise (an env passes its ``np_random``).
        min_force_n: contacts carrying less force are ignored (resting, touching-only).
        on_no_grasp: ``"raise"`` (``NoGraspError``) or ``"silence"``: return what the
            microphone records with nothing in the hand (leak and noise only).
        modal_options: options for ``sensors.ModalModel.bar/tube/rod`` (e.g.
            ``max_frequency_hz``).
        models: the ``sensors._infra.lru.LRU`` models come from, keyed by (object, build
            options) (default: the process's ``MODAL_MODELS``, shared between sensors).
        bandlimited: the excitation reaches the fingertip as the band-limited signal a sound
            card plays (default); False: piecewise linear between samples, the drive of
            earlier datasets (``sensors.synthesis.drive``).

    Per-episode variation (domain randomization) is passed to :meth:`sense` as a
    :class:`SensorVariation`. ``cache`` (a ``sensors.SynthesisCache``) holds this sensor's
    per-grasp systems and drive forces.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData,
                 objects: Mapping[str, Any] | None = None, *, actuator_site: str = "aas_actuator",
                 mic_site: str = "aas_mic", fingertip=None, leak=None, noise_std: float = 0.0,
                 seed: int | None = None, rng: np.random.Generator | None = None,
                 min_force_n: float = 1e-3, on_no_grasp: str = "raise",
                 modal_options: Mapping[str, Any] | None = None, models: LRU | None = None,
                 contact_model: str = "spring_damper", bandlimited: bool = True) -> None:
        missing = [s for s in (actuator_site, mic_site)
                   if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) < 0]
        if missing:
            raise SensorSitesError(
                f"model has no site(s) {missing}: the acoustic sensor needs a site on the actuator "
                f"fingertip ({actuator_site!r}) and one on the microphone fingertip ({mic_site!r})")
        if on_no_grasp not in ("raise", "silence"):
            raise ValueError(f"on_no_grasp must be 'raise' or 'silence', got {on_no_grasp!r}")
        if not (np.isfinite(noise_std) and noise_std >= 0):
            raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
        self.model, self.data = model, data
        if objects is None:
            objects = object_specs_from_model(model)
            if not objects:
                raise ValueError("no objects given and the model describes none (no 'aas_object:<body>' "
                                 "custom texts): pass objects={body_name: ObjectSpec or '<material>_<shape>'}")
        self._specs: dict[str, ObjectSpec | None] = {}
        self._modal: dict[str, Any] = {}
        for body, desc in objects.items():
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body) < 0:
                raise ValueError(f"model has no body named {body!r} (objects must map body names)")
            if isinstance(desc, (str, ObjectSpec)):
                self._specs[body] = get_object(desc)
            elif isinstance(desc, ModalBasis):
                self._specs[body] = None
                self._modal[body] = desc
            else:
                raise TypeError(f"object {body!r}: expected an ObjectSpec, an object name or a "
                                f"sensors.ModalModel, got {type(desc).__name__}")
        self.actuator_site, self.mic_site = actuator_site, mic_site
        self.fingertip, self.leak = fingertip, leak
        self.contact_model = contact_model  # sensors.synthesis.modal_system.CONTACT_MODELS
        self.bandlimited = bool(bandlimited)
        self.noise_std = float(noise_std)
        self.rng = rng if rng is not None else np.random.default_rng(seed)
        self.min_force_n = float(min_force_n)
        self.on_no_grasp = on_no_grasp
        self.modal_options = dict(modal_options or {})
        self.stream = ContactStream(model, list(self._specs), actuator_site, mic_site)
        self.models = MODAL_MODELS if models is None else models
        self.cache = SynthesisCache()
        # material views per (body, scales), with the model they view: the same object for the
        # same episode's grasps, so the synthesis cache recognizes it across excitations
        self._views = LRU(CACHE_SIZES["sim.material_views"])
        # coupled groups of a grasped object and the objects it touches (reused within a tolerance)
        self.touching = TouchingMemo()

    @property
    def bodies(self) -> list[str]:
        """Names of the bodies this sensor can sense."""
        return list(self._specs)

    def object_spec(self, body: str) -> ObjectSpec | None:
        """Shape and material of ``body`` (``None`` if it was given as a ready modal model)."""
        return self._specs[body]

    def modal_model(self, body: str):
        """The ``sensors.ModalModel`` of ``body``, built or loaded on first use."""
        if body not in self._modal:
            spec = self._specs.get(body)
            if spec is None:
                raise KeyError(f"{body!r} is not an object of this sensor; known: {self.bodies}")
            options = self.modal_options
            self._modal[body] = self.models.get_or_build((spec, tuple(sorted(options.items()))),
                                                         lambda: spec.modal_model(**options))
        return self._modal[body]

    def set_modal_model(self, body: str, model) -> None:
        """Hear ``body`` through ``model`` (any ``sensors.ModalBasis`` in the body's frame)
        from now on, e.g. the wet modes of a filled container (``aas_gym/FillLevel-v0``)."""
        if body not in self._specs:
            raise KeyError(f"{body!r} is not an object of this sensor; known: {self.bodies}")
        self._modal[body] = model

    def contacts(self) -> dict[str, ObjectContacts]:
        """The contact datastream of the sensed objects in the current state."""
        return self.stream.read(self.data)

    def grasped_body(self, contacts: Mapping[str, ObjectContacts] | None = None) -> str | None:
        """The object pressed by both sensor fingertips (the one with the larger grip if
        several), or ``None``."""
        contacts = self.contacts() if contacts is None else contacts
        best, best_force = None, 0.0
        for body, c in contacts.items():
            fa, fm = c.total_normal_force_n("actuator"), c.total_normal_force_n("mic")
            if fa > self.min_force_n and fm > self.min_force_n and min(fa, fm) > best_force:
                best, best_force = body, min(fa, fm)
        return best

    def grasp_contacts(self, contacts: Mapping[str, ObjectContacts] | None = None):
        """``(body, actuator_contact, mic_contact, other_contacts)`` as ``sensors.Contact``
        in the grasped object's frame; raises ``NoGraspError`` if nothing is grasped."""
        contacts = self.contacts() if contacts is None else contacts
        body = self.grasped_body(contacts)
        if body is None:
            touching = {b: sorted(set(c.kinds.tolist())) for b, c in contacts.items() if len(c)}
            raise NoGraspError(
                "no object is pressed by both the actuator fingertip (site "
                f"{self.actuator_site!r}) and the microphone fingertip ({self.mic_site!r}); "
                f"current object contacts by kind: {touching or 'none'}")
        grasp = contacts[body].sensor_grasp(self.min_force_n, self.object_materials())
        for kind, tip in (("actuator", grasp.actuator), ("mic", grasp.mic)):
            if tip is None:  # forces on opposite faces cancel: not one fingertip patch
                raise NoGraspError(f"the {kind} fingertip touches {body!r} on opposite sides; "
                                   "no single contact to excite or record through")
        return body, grasp.actuator, grasp.mic, grasp.others

    def sense(self, excitation, duration_s: float = 1.0, *, variation: SensorVariation | None = None,
              rng: np.random.Generator | None = None, waveform: bool = True,
              contacts: Mapping[str, ObjectContacts] | None = None):
        """Play ``excitation`` (a ``sensors.Excitation`` or its name) for ``duration_s`` seconds
        through the current grasp and return the ``sensors.AcousticObservation``.

        ``variation``: this episode's :class:`SensorVariation` (default none); ``rng``: the
        noise generator for this call (default the sensor's own). The grasp is taken as
        constant during the recording (the paper records a static grasp).
        ``waveform=False``: only the features are wanted; returns a
        ``sensors.synthesis.FeatureObservation`` computed in closed form where it applies
        (``sensors.synthesis.simulate_features``: the same features, no samples synthesized).
        ``contacts``: :meth:`contacts` of the current state if the caller read them already.
        """
        record = sensors.simulate_recording if waveform else simulate_features
        variation = NO_VARIATION if variation is None else variation
        if not isinstance(variation, SensorVariation):
            raise TypeError(f"variation must be a SensorVariation, got {type(variation).__name__}")
        rng = self.rng if rng is None else rng
        noise_std = self.noise_std if variation.noise_std is None else variation.noise_std
        if isinstance(excitation, str):
            excitation = Excitation.by_name(excitation)
        if not isinstance(excitation, Excitation):
            raise TypeError(f"excitation must be a sensors.Excitation or a name, got {type(excitation).__name__}")
        duration_s = float(duration_s)
        if not (np.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration_s must be > 0, got {duration_s!r}")
        contacts = self.contacts() if contacts is None else contacts
        leak = self.leak_for(excitation, variation.leak_scale)
        try:
            body, act, mic, others = self.grasp_contacts(contacts)
        except NoGraspError:
            if self.on_no_grasp == "raise":
                raise
            # Nothing between the fingertips: the microphone hears the leak and its noise.
            obs = record(None, excitation, duration_s, None, None, leak=leak, noise_std=noise_std, rng=rng)
            obs.metadata.update({"grasped": False})
            return obs
        spec = self._specs.get(body)
        model, others = touching_grasp(self, body, contacts, variation, others)
        obs = record(
            model, excitation, duration_s, act, mic, other_contacts=others,
            fingertip=self.fingertip, leak=leak, noise_std=noise_std, rng=rng, cache=self.cache,
            contact_model=self.contact_model, bandlimited=self.bandlimited)
        obs.metadata.update({
            "source": "sim", "grasped": True, "object_body": body,
            "material": spec.material if spec else None, "shape": spec.shape if spec else None,
            "label": spec.label if spec else None,
            "actuator_contact": act.to_dict(), "mic_contact": mic.to_dict(),
            "other_contacts": [o.to_dict() for o in others],
            "coupled_objects": len(model.partners) if isinstance(model, TouchingObjects) else 0,
        })
        return obs

    def object_materials(self) -> dict:
        """Material name of each sensed object body (the other body of a contact between
        objects, for its Hertz stiffness)."""
        from sensors import MATERIALS

        return {b: s.material for b, s in self._specs.items() if s is not None and s.material in MATERIALS}

    def leak_for(self, excitation, leak_scale: float = 1.0):
        """The leak recording for ``excitation`` (scaled by ``leak_scale``), or ``None``."""
        leak = self.leak
        if leak is None:
            return None
        if isinstance(leak, Mapping):
            leak = leak.get(excitation.kind, leak.get(excitation.name, None))
            if leak is None:
                return None
        if not isinstance(leak, LeakRecording):
            leak = load_leak(leak)
        if leak_scale != 1.0:
            leak = LeakRecording(leak.waveform * leak_scale, leak.sample_rate_hz, leak.excitation,
                                 dict(leak.metadata))
        return leak

    def scaled_model(self, body: str, variation: SensorVariation):
        """The modal model of ``body`` in the episode's randomized material (an exact
        ``sensors.MaterialView``, memoized so the synthesis cache recognizes it)."""
        model = self.modal_model(body)
        scales = variation.material_scales
        if scales == (1.0, 1.0, 1.0):
            return model
        key = (body, scales)
        hit = self._views.get(key)
        if hit is None or hit[0] is not model:  # new, or the body hears another model now
            d, e, rho = scales
            view = with_material(model, scaled_material(model.material, damping_scale=d, modulus_scale=e,
                                                        density_scale=rho))
            hit = self._views.put(key, (model, view))
        return hit[1]
