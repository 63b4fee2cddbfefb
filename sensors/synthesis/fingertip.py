"""Lumped actuator / fingertip / object / environment model (the paper's drive model).

The exciter does not impose a force on the object directly: it shakes its own inertial mass
against the fingertip housing, and the housing presses on the object through a compliant,
one-sided contact preloaded by the grip force.  Along the grip axis (coordinate pointing from
the actuator finger into the object, i.e. along ``-normal`` of the actuator contact):

    actuator mass  m_a  --(k_a, c_a; exciter force +F_e on m_a, -F_e on the housing)--
    fingertip      m_f  --(k_h, c_h to the hand; grip force F_g)--
                        --(one-sided contact k_c, c_c)--  object m_o  --(k_e, c_e)-- environment
                                                          object --(one-sided contact k_c, c_c)--
    microphone fingertip m_m --(k_h, c_h to the hand; grip force F_g)--

All coordinates are deviations from the static grasp equilibrium, where each contact carries
the grip force F_g.  A contact force is  f = F_g + k_c d + c_c d'  while the (total)
penetration F_g / k_c + d is positive, clipped at 0 (no adhesion): the contact separates
when the vibration would pull harder than the grip pushes.  The hand is taken as fixed (0.73 kg
plus the arm behind it, far heavier than the fingertips).

Output: the dynamic force the actuator fingertip exerts on the object along the grip
direction, f_c(t) - F_g [N].  The static grip force is already in equilibrium before the
recording and a piezo contact microphone is AC-coupled, so only the dynamic part drives
the modal synthesis.

If neither contact ever separates the model is linear; it is then solved exactly (same
first-order-hold discretisation as the modal synthesis).  Otherwise a compiled fixed-step RK4
integrator (numba) runs the one-sided model with the excitation linearly interpolated.

Parameter values (defaults) and why
-----------------------------------
- ``grip_force_n = 40``: the paper's grasp force.
- ``actuator_force_n = 1.0``: peak exciter force per unit excitation amplitude; small
  bone-conduction exciters (e.g. 10 W class) produce on the order of 1 N.
- ``actuator_mass_kg = 0.008``, ``actuator_resonance_hz = 500``, ``actuator_damping_ratio =
  0.3``: moving mass and suspension of a small bone-conduction exciter (resonances of a few
  hundred Hz, heavily damped).
- ``fingertip_mass_kg = 0.06``: Franka finger (0.015 kg, menagerie model) plus a 3D-printed
  sensor housing and the exciter body.  ``mic_fingertip_mass_kg = 0.04``: finger + piezo
  housing.
- ``finger_stiffness_n_m = 2e5``, ``finger_damping_n_s_m = 20``: the finger's drive train
  (rack, screw) relative to the hand: stiff but not rigid.
- ``contact_stiffness_n_m = 2e6``: Hertz-like stiffness of a printed fingertip on a metal/
  plastic object at 40 N (order 1e6-1e7 N/m); ``contact_damping_n_s_m = 70``: damping ratio
  ~0.1 of the fingertip on that contact.
- ``contact_tangential_stiffness_n_m = 1.56e6``: the pad's spring across the normal while it
  sticks (Mindlin, ``sensors.modal.contact_stiffness``): k_t / k_n = 2 (1 - nu) / (2 - nu) =
  0.78 for the printed pad's nu = 0.36 (it is the softer body, so its nu sets the ratio).
  With ``contact_model="spring_damper"`` both pad springs hold the object's modes at each
  fingertip contact (``FingertipModel.pad``); the lumped drive above uses the normal one.
- ``object_mass_kg = 0.1``: rigid-body mass of the object (pass the real one when known);
  ``environment_*``: coupling of the object to the table/world along the grip axis
  (0 = held in the air).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .._infra.jit import jitted
from .lti import MAX_EIGVEC_COND, DiscreteSystem, EigenPart, lti_system

__all__ = ["DriveSystems", "FingertipModel", "SHARED_DRIVE_EIGENSOLVE"]

#: ``FingertipModel.discretised``: True builds the microphone-side system from the actuator
#: side's eigen-decomposition (``DiscreteSystem.with_output``), False solves it again (the
#: reference; the same numbers bit for bit, one eigen-solve and one inverse more per model).
SHARED_DRIVE_EIGENSOLVE = True


@dataclass(frozen=True)
class DriveSystems:
    """The linear (always in contact) fingertip model discretised at one sample rate: exciter
    force [N] -> dynamic contact force [N] on the object at the actuator fingertip (``act``,
    what drives the modal synthesis) and at the microphone fingertip (``mic``, for the
    separation check).  Both share the state of :meth:`FingertipModel.state_space`."""

    act: DiscreteSystem
    mic: DiscreteSystem


@dataclass(frozen=True)
class FingertipModel:
    """Parameters of the lumped drive model (see the module docstring for the values)."""

    grip_force_n: float = 40.0
    actuator_force_n: float = 1.0
    actuator_mass_kg: float = 0.008
    actuator_resonance_hz: float = 500.0
    actuator_damping_ratio: float = 0.3
    fingertip_mass_kg: float = 0.06
    mic_fingertip_mass_kg: float = 0.04
    finger_stiffness_n_m: float = 2e5
    finger_damping_n_s_m: float = 20.0
    contact_stiffness_n_m: float = 2e6
    contact_damping_n_s_m: float = 70.0
    object_mass_kg: float = 0.1
    environment_stiffness_n_m: float = 0.0
    environment_damping_n_s_m: float = 0.0
    substeps: int = 8  # RK4 steps per sample for the one-sided (separating) case
    contact_tangential_stiffness_n_m: float = 1.56e6

    def __post_init__(self) -> None:
        for k, v in vars(self).items():          # the fields (asdict would deep-copy them)
            # math, not numpy: a model is made per grasp (3 per GraspPosition-v0 probe), and
            # np.isfinite of a Python float costs about 1 us
            if not math.isfinite(v) or v < 0:
                raise ValueError(f"FingertipModel.{k} must be finite and >= 0, got {v!r}")
        for k in ("actuator_mass_kg", "fingertip_mass_kg", "mic_fingertip_mass_kg", "object_mass_kg",
                  "contact_stiffness_n_m", "actuator_resonance_hz"):
            if getattr(self, k) <= 0:
                raise ValueError(f"FingertipModel.{k} must be > 0")
        if int(self.substeps) < 1:
            raise ValueError("substeps must be >= 1")

    def with_(self, **changes) -> "FingertipModel":
        return replace(self, **changes)

    def pad(self, contact):
        """A fingertip ``sensors.Contact`` with this pad's springs (``contact_stiffness_n_m``
        along the normal, ``contact_tangential_stiffness_n_m`` across it) where it gives none."""
        changes = {}
        if contact.normal_stiffness_n_per_m is None:
            changes["normal_stiffness_n_per_m"] = self.contact_stiffness_n_m
        if contact.tangential_stiffness_n_per_m is None:
            changes["tangential_stiffness_n_per_m"] = self.contact_tangential_stiffness_n_m
        return replace(contact, **changes) if changes else contact

    # -- matrices -----------------------------------------------------------------------
    def _params(self) -> np.ndarray:
        ka = self.actuator_mass_kg * (2 * np.pi * self.actuator_resonance_hz) ** 2
        ca = 2 * self.actuator_damping_ratio * np.sqrt(ka * self.actuator_mass_kg)
        return np.array([self.actuator_mass_kg, ka, ca, self.fingertip_mass_kg, self.mic_fingertip_mass_kg,
                         self.finger_stiffness_n_m, self.finger_damping_n_s_m, self.contact_stiffness_n_m,
                         self.contact_damping_n_s_m, self.object_mass_kg, self.environment_stiffness_n_m,
                         self.environment_damping_n_s_m, self.grip_force_n], dtype=float)

    def state_space(self):
        """Linear (always-in-contact) model: x' = A x + B F_e, y = C x (dynamic contact
        force), state [d_a, v_a, d_f, v_f, d_o, v_o, d_m, v_m] (deviations, grip axis)."""
        ma, ka, ca, mf, mm, kh, ch, kc, cc, mo, ke, ce, _ = self._params()
        # positions a=0, f=1, o=2, m=3
        K = np.array([[ka, -ka, 0, 0],
                      [-ka, ka + kh + kc, -kc, 0],
                      [0, -kc, 2 * kc + ke, -kc],
                      [0, 0, -kc, kc + kh]])
        Cd = np.array([[ca, -ca, 0, 0],
                       [-ca, ca + ch + cc, -cc, 0],
                       [0, -cc, 2 * cc + ce, -cc],
                       [0, 0, -cc, cc + ch]])
        Minv = 1.0 / np.array([ma, mf, mo, mm])
        A = np.zeros((8, 8))
        A[0::2, 1::2] = np.eye(4)
        A[1::2, 0::2] = -Minv[:, None] * K
        A[1::2, 1::2] = -Minv[:, None] * Cd
        B = np.zeros(8)
        B[1] = 1.0 / ma
        B[3] = -1.0 / mf
        C = np.zeros(8)
        C[2], C[3], C[4], C[5] = kc, cc, -kc, -cc
        return A, B, C

    def mic_output(self) -> np.ndarray:
        """The output row of the dynamic contact force at the microphone fingertip (state of
        :meth:`state_space`): k_c (d_o - d_m) + c_c (v_o - v_m)."""
        kc, cc = self.contact_stiffness_n_m, self.contact_damping_n_s_m
        Cm = np.zeros(8)
        Cm[4], Cm[5], Cm[6], Cm[7] = kc, cc, -kc, -cc
        return Cm

    def discretised(self, sample_rate_hz: float) -> DriveSystems:
        """The linear model, exactly discretised (first-order hold) at ``sample_rate_hz``."""
        A, B, C = self.state_space()
        Cm = self.mic_output()
        act = lti_system(A, B, C, 0.0, sample_rate_hz)
        # both outputs observe one state equation: one eigen-solve (the same numbers)
        mic = act.with_output(Cm) if SHARED_DRIVE_EIGENSOLVE else lti_system(A, B, Cm, 0.0, sample_rate_hz)
        return DriveSystems(act, mic)

    def modes(self, sample_rate_hz: float) -> tuple[EigenPart, EigenPart] | None:
        """The linear model in complex modes at ``sample_rate_hz`` (first-order hold), observed
        at the actuator and at the microphone contact: the parts of :meth:`discretised`'s two
        systems, from numpy's eigen-solve of the 8 x 8 state matrix and the input gains by one
        solve (without ``lti_parts``' BLAS thread limit, LU factors kept for a lazy inverse
        and scipy's checks: 0.23 against 0.35 ms; the same numbers to rounding).  ``None``
        where the eigenvectors are ill-conditioned (1-norm condition number above
        ``MAX_EIGVEC_COND``: :meth:`discretised` then takes its dense form).  The parts map
        no state back (no inverse): they serve periodic runs from rest."""
        A, B, C = self.state_space()
        lam, V = np.linalg.eig(A)
        V = V / np.linalg.norm(V, axis=0)
        if not np.linalg.cond(V, 1) < MAX_EIGVEC_COND:
            return None
        keep = lam.imag >= 0
        g = np.linalg.solve(V, B.astype(complex))[keep]
        act = EigenPart(np.arange(8), lam[keep], V[:, keep], None, B, C, 0.0, 1.0 / float(sample_rate_hz), "foh", g=g)
        return act, act.with_output(self.mic_output())

    # -- simulation ---------------------------------------------------------------------
    def contact_force(self, excitation_signal, sample_rate_hz: float, return_info: bool = False):
        """Dynamic force [N] the actuator fingertip exerts on the object (grip direction)
        for an excitation waveform (full scale 1) sampled at ``sample_rate_hz``; zero initial state
        (the grasp at rest).  With ``return_info`` also returns a dict: ``separated``
        (bool) and ``min_contact_force_n`` (smallest total force over both contacts)."""
        e = np.asarray(excitation_signal, dtype=float)
        if e.ndim != 1 or not np.all(np.isfinite(e)):
            raise ValueError("excitation_signal must be a finite 1-D array")
        fe = self.actuator_force_n * e
        f_act, f_mic = self._linear_forces(fe, sample_rate_hz, periodic=False)
        min_total = self.grip_force_n + min(f_act.min(initial=0.0), f_mic.min(initial=0.0))
        separated = bool(min_total < 0.0)
        if separated:
            f_act, min_total, _ = self.one_sided_forces(fe, sample_rate_hz)
        if return_info:
            return f_act, {"separated": separated, "min_contact_force_n": float(min_total)}
        return f_act

    def periodic_contact_force(self, excitation_period, sample_rate_hz: float, return_info: bool = False):
        """Periodic steady state of :meth:`contact_force` (one period) for an excitation that
        loops ``excitation_period`` forever, from the linear model.  ``separated`` in the info
        dict means a contact would lift off: the linear steady state is then not valid."""
        fe = self.actuator_force_n * np.asarray(excitation_period, dtype=float)
        f_act, f_mic = self._linear_forces(fe, sample_rate_hz, periodic=True)
        min_total = self.grip_force_n + min(f_act.min(), f_mic.min())
        if return_info:
            return f_act, {"separated": bool(min_total < 0.0), "min_contact_force_n": float(min_total)}
        return f_act

    def one_sided_forces(self, exciter_force_n, sample_rate_hz: float, initial_state=None):
        """The one-sided (separating) model integrated by RK4 (``substeps`` per sample) for
        the exciter force [N] at each sample, linear between samples, from ``initial_state``
        (the 8-state of :meth:`state_space`, default rest): the dynamic actuator contact force
        at each sample, the smallest total contact force [N] over both contacts and the state
        at the last sample."""
        fe = np.ascontiguousarray(exciter_force_n, dtype=float)
        x0 = np.zeros(8) if initial_state is None else np.array(initial_state, dtype=float)
        return _simulate_one_sided(self._params(), fe, float(sample_rate_hz), int(self.substeps), x0)

    def _linear_forces(self, fe: np.ndarray, sample_rate_hz: float, periodic: bool):
        """Dynamic contact forces (actuator side, mic side) of the linear model for the
        exciter force ``fe``: from rest, or the periodic steady state."""
        drive = self.discretised(sample_rate_hz)
        return [s.periodic_response(fe) if periodic else s.response(fe) for s in (drive.act, drive.mic)]


# compiled by numba on first use (sensors._infra.jit)
def _rhs(x, fe, p, out):
    ma, ka, ca, mf, mm, kh, ch, kc, cc, mo, ke, ce, fg = p
    da, va, df, vf, do, vo, dm, vm = x
    # one-sided contacts: total force from the preloaded spring-damper, clipped at 0
    pen1 = fg / kc + df - do
    f1 = fg + kc * (df - do) + cc * (vf - vo) if pen1 > 0.0 else 0.0
    f1 = f1 if f1 > 0.0 else 0.0
    pen2 = fg / kc + do - dm
    f2 = fg + kc * (do - dm) + cc * (vo - vm) if pen2 > 0.0 else 0.0
    f2 = f2 if f2 > 0.0 else 0.0
    fs_ = ka * (da - df) + ca * (va - vf)
    out[0] = va
    out[1] = (fe - fs_) / ma
    out[2] = vf
    out[3] = (-fe + fs_ - kh * df - ch * vf - (f1 - fg)) / mf
    out[4] = vo
    out[5] = ((f1 - fg) - (f2 - fg) - ke * do - ce * vo) / mo
    out[6] = vm
    out[7] = ((f2 - fg) - kh * dm - ch * vm) / mm
    return f1, f2


# compiled by numba on first use (sensors._infra.jit), with _rhs
def _simulate(p, fe, sample_rate_hz, substeps, x0):
    n = fe.shape[0]
    out = np.zeros(n)
    x = x0.copy()
    k1 = np.zeros(8)
    k2 = np.zeros(8)
    k3 = np.zeros(8)
    k4 = np.zeros(8)
    tmp = np.zeros(8)
    h = 1.0 / (sample_rate_hz * substeps)
    fg = p[12]
    min_f = fg
    for i in range(n):
        f1, f2 = _rhs(x, 0.0, p, tmp)  # forces at the sample (input does not enter them)
        out[i] = f1 - fg
        min_f = min(min_f, f1, f2)
        if i == n - 1:
            break
        u0, u1 = fe[i], fe[i + 1]
        for s in range(substeps):
            a = s / substeps
            b = (s + 0.5) / substeps
            c = (s + 1.0) / substeps
            ua = u0 + (u1 - u0) * a
            ub = u0 + (u1 - u0) * b
            uc = u0 + (u1 - u0) * c
            _rhs(x, ua, p, k1)
            for j in range(8):
                tmp[j] = x[j] + 0.5 * h * k1[j]
            _rhs(tmp, ub, p, k2)
            for j in range(8):
                tmp[j] = x[j] + 0.5 * h * k2[j]
            _rhs(tmp, ub, p, k3)
            for j in range(8):
                tmp[j] = x[j] + h * k3[j]
            _rhs(tmp, uc, p, k4)
            for j in range(8):
                x[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
    return out, min_f, x


def _simulate_one_sided(p, fe, sample_rate_hz, substeps, x0=None):
    """Compiled RK4 of the one-sided model from the state ``x0`` (default rest): (dynamic
    actuator contact force, min total force, state at the last sample)."""
    simulate = jitted(globals(), "_simulate", callees=("_rhs",), cache=True)
    x0 = np.zeros(8) if x0 is None else np.ascontiguousarray(x0, dtype=float)
    return simulate(np.ascontiguousarray(p), np.ascontiguousarray(fe), sample_rate_hz, substeps, x0)
