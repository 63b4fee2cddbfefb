"""The simulated microphone of a MuJoCo scene, recording without a break while it moves.

:class:`SimAcousticStream` follows a scene (built with ``contact_signature=True``) physics
step by physics step: after each ``mj_step`` its :meth:`~SimAcousticStream.grasp_state` says
what touches the heard object now (a ``sensors.GraspState``: both fingertip contacts, table,
other objects and hand links, with forces, points, normals and friction), and
``sensors.AcousticStream`` synthesizes the microphone through that series, carrying every
state across changes.

Reading the contact list costs far more than a physics step, while a steady grasp changes
nothing the sound depends on. So each step first compares the scene's contact signature, a
few MuJoCo contact sensors per object and partner (net force and force-weighted point; see
``aas_gym.contact_sensors.add_contact_signature_sensors``), in the object's frame, with the signature
of the last contact list it read. Only when a partner starts or stops pressing (net force
above the tolerance's ``force_atol_n``), an object becomes touched by both fingertips, or a
net force or point moved beyond the stream's ``ContactTolerance`` does it read the contact
list again; otherwise it hands the stream the same ``GraspState`` object, and the stream
synthesizes all those steps in one call. Changes the signature does not see: a force moving
among the contacts with one partner at constant net force and point, and contacts without
force coming and going (they do not damp).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from aas_gym.contact_sensors import signature_partners, signature_sensor_name
from aas_gym.sim_sensor import NO_VARIATION, SensorVariation, SimAcousticSensor
from aas_gym.touching_grasp import touching_grasp
from sensors import AcousticStream, ContactTolerance, Excitation, GraspState
from sensors.synthesis.passive import PassiveSound

__all__ = ["SimAcousticStream", "span_bounds"]


def span_bounds(n_samples: int, n_steps: int) -> np.ndarray:
    """Sample boundaries of ``n_steps`` physics steps sharing ``n_samples`` samples (the
    step k records samples [b[k], b[k+1]); lengths differ by at most one)."""
    return (np.arange(n_steps + 1) * int(n_samples)) // int(n_steps)


class SimAcousticStream:
    """A continuously recording microphone on the scene of ``sensor``.

    Parameters
    ----------
    sensor : the scene's ``aas_gym.SimAcousticSensor`` (modal models, fingertip model, leak,
        contact stream). Its MuJoCo model must carry the contact-signature sensors
        (``build_scene(..., contact_signature=True)``).
    excitation : looped without a break (``sensors.Excitation`` or a name).
    variation : this episode's ``SensorVariation`` (noise, leak scale, material scales).
    rng : the noise generator (``numpy.random.Generator`` or seed).
    tolerance : when contacts count as unchanged (``sensors.ContactTolerance``).
    passive : a ``sensors.PassiveSound``: each contact read hands the stream the forces of
        every contact on the heard object (``ObjectContacts.sensor_loads``), so that impacts,
        knocks and slides make sound; ``None``: only the drive does.
    """

    def __init__(self, sensor: SimAcousticSensor, excitation: Excitation | str, *,
                 variation: SensorVariation | None = None, rng=None,
                 tolerance: ContactTolerance | None = None, passive: PassiveSound | None = None) -> None:
        if isinstance(excitation, str):
            excitation = Excitation.by_name(excitation)
        variation = NO_VARIATION if variation is None else variation
        if not isinstance(variation, SensorVariation):
            raise TypeError(f"variation must be a SensorVariation, got {type(variation).__name__}")
        self.sensor, self.variation = sensor, variation
        self.model, self.data = sensor.model, sensor.data
        noise = sensor.noise_std if variation.noise_std is None else variation.noise_std
        self.tolerance = tolerance or ContactTolerance()
        self.stream = AcousticStream(excitation, fingertip=sensor.fingertip,
                                     leak=sensor.leak_for(excitation, variation.leak_scale), noise_std=noise,
                                     rng=rng if rng is not None else sensor.rng, tolerance=self.tolerance,
                                     contact_model=sensor.contact_model, bandlimited=sensor.bandlimited,
                                     passive=passive)
        self.bodies = sensor.bodies
        self._vec_adr, self._grasp_adr = _signature_addresses(self.model, self.bodies)
        self._n_partners = self._vec_adr.shape[1] // 2
        self._body_ids = np.array([mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b)
                                   for b in self.bodies])
        self._min_force_n = sensor.min_force_n
        self._ref_present = self._ref_vec = None  # signature when the contacts were last read
        self._heard_index = 0
        self._state: GraspState | None = None
        self._heard: str | None = None           # the body the stream follows
        self.contact_reads = 0
        self._pressing, self._pressing_body = set(), None   # who pressed on which body at the last read

    @property
    def sample_rate_hz(self) -> int:
        return self.stream.sample_rate_hz

    # -- per physics step --------------------------------------------------------------------
    def _signature(self, b: int) -> tuple[list, list]:
        """Which partners press on object ``b`` (net force above the tolerance's
        ``force_atol_n``), which objects both fingertips touch (a grasp may move to another),
        and object ``b``'s net forces [N] then force-weighted points [m] per partner in its
        frame; a few microseconds (this runs every physics step)."""
        d = self.data
        sd = d.sensordata
        R = d.xmat[self._body_ids[b]].reshape(3, 3)
        vec = sd[self._vec_adr[b]] @ R
        n = self._n_partners
        vec[n:] -= d.xpos[self._body_ids[b]] @ R
        v = vec.tolist()
        atol = self.tolerance.force_atol_n
        present = [x * x + y * y + z * z > atol * atol for x, y, z in v[:n]]
        return present + (sd[self._grasp_adr] > 0).tolist(), v

    def signature_changed(self, present: list, v: list) -> bool:
        """Whether a contact signature (``present`` partners, their net forces and points) is
        beyond the tolerance from the one read last."""
        # Plain floats: a dozen numbers compare six times faster than through numpy calls.
        if present != self._ref_present:
            return True
        tol, n = self.tolerance, self._n_partners
        ref = self._ref_vec
        for (x, y, z), (a, b, c) in zip(v[:n], ref[:n]):
            if (math.sqrt((x - a) ** 2 + (y - b) ** 2 + (z - c) ** 2)
                    > tol.force_rtol * math.sqrt(a * a + b * b + c * c) + tol.force_atol_n):
                return True
        p = tol.position_m
        # points of partners that press (a point without force is meaningless)
        return any(on and (abs(x - a) > p or abs(y - b) > p or abs(z - c) > p)
                   for on, (x, y, z), (a, b, c) in zip(present, v[n:], ref[n:]))

    def grasp_state(self) -> GraspState:
        """What touches the heard object after the latest physics step (the previous
        ``GraspState`` object itself while the contact signature did not change)."""
        signature = None
        if self._state is not None:
            signature = self._signature(self._heard_index)
            if not self.signature_changed(*signature):
                return self._state
        index = self._heard_index
        self._state = self.read_state()
        if signature is None or self._heard_index != index:
            signature = self._signature(self._heard_index)   # the same data: no physics step between
        self._ref_present, self._ref_vec = signature
        return self._state

    def read_state(self) -> GraspState:
        """Read the contact list (what :meth:`grasp_state` does when the signature changed): the grasped object (both fingertips press it), else the
        object heard last, else the first (target) object."""
        self.contact_reads += 1
        contacts = self.sensor.contacts()
        body = self.sensor.grasped_body(contacts) or self._heard or self.bodies[0]
        self._heard = body
        self._heard_index = self.bodies.index(body)
        # the other contacts are made only where no touching partner takes them (touching_grasp)
        grasp = contacts[body].sensor_grasp(self._min_force_n, others=False)
        # the sensed objects it touches vibrate with it (spring_damper; aas_gym.touching_grasp)
        model, others = touching_grasp(self.sensor, body, contacts, self.variation, None)
        loads = None
        if self.stream.passive is not None:
            c = contacts[body]
            before = self._pressing if body == self._pressing_body else None
            loads = c.sensor_loads(self._min_force_n, before)
            self._pressing, self._pressing_body = c.pressing_bodies(self._min_force_n), body
        return GraspState(model, grasp.actuator, grasp.mic, tuple(others), object_key=body, loads=loads)

    # -- recording ---------------------------------------------------------------------------
    def step_physics(self, n_steps: int, n_samples: int) -> np.ndarray:
        """``mj_step`` ``n_steps`` times and record ``n_samples`` across them (each physics
        step's share per :func:`span_bounds`); returns the float32 samples."""
        m, d = self.model, self.data
        b = span_bounds(n_samples, n_steps)
        spans = []
        for k in range(int(n_steps)):
            mujoco.mj_step(m, d)
            spans.append((int(b[k + 1] - b[k]), self.grasp_state()))
        return self.stream.advance(spans)

    def latest_features(self) -> np.ndarray | None:
        """140-d features of the latest complete excitation period (``None`` before one)."""
        return self.stream.latest_features()

    @property
    def heard_body(self) -> str | None:
        """The object the stream follows (``None`` before the first step)."""
        return self._heard

    @property
    def metadata(self) -> dict:
        meta = self.stream.metadata
        meta.update({"heard_body": self._heard, "contact_reads": self.contact_reads,
                     "randomization": self.variation.to_dict()})
        return meta


def _signature_addresses(model: mujoco.MjModel, bodies: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """sensordata indices of the signature sensors: per object (2 n_partners, 3) of its net
    forces then its points, and the contact counts of every object with both fingertips;
    a clear error when the scene was built without them."""
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "table") >= 0
    vec, tips = [], []
    for body in bodies:
        forces, points = [], []
        for i, partner in enumerate(signature_partners(bodies, body, table)):
            sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, signature_sensor_name(body, partner))
            if sid < 0:
                raise ValueError("the scene has no contact-signature sensors: build it with "
                                 "aas_gym.scene.build_scene(..., contact_signature=True) to stream sound")
            a = int(model.sensor_adr[sid])     # count, force (3), point (3)
            if i < 2:                          # the fingertips
                tips.append(a)
            forces.append(np.arange(a + 1, a + 4))
            points.append(np.arange(a + 4, a + 7))
        vec.append(forces + points)
    return np.array(vec), np.array(tips)
