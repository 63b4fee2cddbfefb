"""Passive sound (issue 26, item 4): contact force changes and slides excite the object.

References are independent of the code under test: the closed-form response of damped
oscillators to a force ramp (modal superposition, written here), and scipy.signal.lsim of
the object's and the fingertip's state spaces (built here) with the contact loads as a second
input, segment by segment with the states carried.
"""

import numpy as np
import pytest
import scipy.signal as ss

import sensors
from sensors import Contact, Excitation, FingertipModel, GraspState
from sensors.synthesis.microphone import mic_gain
from sensors.synthesis.passive import ContactLoads, PassiveSound, modal_load
from sensors.synthesis.stream import AcousticStream
from synthesis_fakes import BoxModel

FS = 44100
H = 0.01


def _fingers(force_n=40.0):
    return (Contact([0.05, H, 0.001], [0, 1, 0], force_n, 0.5), Contact([0.05, -H, 0.001], [0, -1, 0], force_n, 0.8))


def _knock(force_n, x=-0.06, impact=False):
    """A body pressing on the bottom face at x with ``force_n`` (and a little friction)."""
    return ContactLoads([[x, 0.003, -H]], [[0, 0, -1]], [[0.2 * force_n, 0.0, force_n]], impact=[impact])


def _ramp_response(w, zeta, t, tau):
    """Displacement of x'' + 2 zeta w x' + w^2 x = r(t), r rising linearly 0 -> 1 over tau
    then 1, from rest (closed form: the unit-ramp response, differenced)."""
    wd = w * np.sqrt(1 - zeta ** 2)

    def ramp(tt):
        tt = np.maximum(tt, 0.0)
        e = np.exp(-zeta * w * tt)
        return (tt / w ** 2 - 2 * zeta / w ** 3
                + e * (2 * zeta / w ** 3 * np.cos(wd * tt) + (2 * zeta ** 2 - 1) / (w ** 2 * wd) * np.sin(wd * tt)))

    return (ramp(t) - ramp(t - tau)) / tau


@pytest.fixture(scope="module")
def box():
    m = BoxModel(np.linspace(900, 14000, 12), "wood", seed=4)
    m.material.gamma = 0.0          # no contact damping: diagonal (Rayleigh) modal damping
    return m


@pytest.mark.parametrize("impact,rise_time_s", [(True, 2e-4), (True, 1e-3), (False, 2e-4)])
def test_impact_matches_modal_superposition(box, impact, rise_time_s):
    """A 12 N knock under the grasped box (an impact: over the rise time; a persisting
    contact: over the span): the stream's extra output (passive on minus off) equals the
    closed-form sum over modes of the damped oscillators' ramp responses."""
    act, mic = _fingers()
    exc = Excitation.linear_sweep()
    before = GraspState(box, act, mic, loads=_knock(0.0), object_key="box")
    after = GraspState(box, act, mic, loads=_knock(12.0, impact=impact), object_key="box")
    n0, n1 = 441, 8820
    passive = PassiveSound(rise_time_s=rise_time_s)
    on = AcousticStream(exc, method="diagonal", passive=passive)
    off = AcousticStream(exc, method="diagonal")
    y_on = np.concatenate([on.synthesize(n0, before), on.synthesize(n1, after)])
    y_off = np.concatenate([off.synthesize(n0, before), off.synthesize(n1, after)])
    got = (y_on - y_off)[n0:]
    # reference: modes j, force F at p: modal force phi_j = F . U_j(p); output o_j = n_mic . U_j(mic)
    loads = _knock(12.0)
    U = box.mode_shapes_at(np.vstack([loads.positions_m, mic.position_m]))
    phi = loads.forces_n[0] @ U[0]
    o = mic.normal @ U[1]
    w = box.angular_frequencies_rad_s
    zeta = (box.material.alpha + box.material.beta * w ** 2) / (2 * w)
    tau = (round(rise_time_s * FS) if impact else n1) / FS
    t = np.arange(n1) / FS
    ref = sum(o[j] * phi[j] * _ramp_response(w[j], zeta[j], t, tau) for j in range(len(w)))
    assert np.abs(ref).max() > 0.1 * np.abs(y_off).max()      # not negligible next to the drive
    assert np.abs(got - ref).max() <= 1e-7 * np.abs(ref).max()
    assert on.metadata["passive"]["rise_time_s"] == rise_time_s


def test_constant_loads_make_no_sound_and_resting_objects_do_not_ring(box):
    act, mic = _fingers()
    exc = Excitation.impulse()
    g = GraspState(box, act, mic, loads=_knock(5.0))
    same = GraspState(box, act, mic, loads=_knock(5.0))            # a new read, the same loads
    on = AcousticStream(exc, method="diagonal", passive=PassiveSound())
    off = AcousticStream(exc, method="diagonal")
    a = np.concatenate([on.synthesize(500, g), on.synthesize(700, same)])
    b = np.concatenate([off.synthesize(500, g), off.synthesize(700, same)])
    assert np.array_equal(a, b)


def test_knocks_ring_down_without_growth(box):
    """Loads switching every span (20 contacts, random forces) then held: the passive part of
    the output decays at the slowest mode's rate; nothing grows."""
    act, mic = _fingers()
    exc = Excitation.impulse()
    rng = np.random.default_rng(3)
    spans = []
    for _ in range(40):
        pts = np.column_stack([rng.uniform(-0.09, 0.09, 20), rng.uniform(-H, H, 20), np.full(20, -H)])
        f = np.column_stack([rng.normal(0, 2, 20), rng.normal(0, 2, 20), rng.uniform(0, 30, 20)])
        spans.append((int(rng.integers(1, 90)), GraspState(box, act, mic, loads=ContactLoads(pts, np.tile([0, 0, -1.0], (20, 1)), f))))
    hold = spans[-1][1]
    on = AcousticStream(exc, method="diagonal", passive=PassiveSound(roughness=0.0))
    off = AcousticStream(exc, method="diagonal")
    d = on.synthesize(spans) - off.synthesize(spans)
    rest = on.synthesize(FS, hold) - off.synthesize(FS, hold)
    w = box.angular_frequencies_rad_s
    slowest = np.min((box.material.alpha + box.material.beta * w ** 2) / 2)
    env = [np.abs(rest[i:i + 441] - rest[-1]).max() for i in range(0, FS - 441, 441)]
    bound = np.abs(d).max() * (10 * np.exp(-slowest * np.arange(len(env)) * 0.01) + 1e-14)   # + rounding
    assert np.all(np.isfinite(rest)) and np.all(env <= bound)
    assert env[-1] < 1e-12 * env[0]


def _object_ss(model, C, act, mic):
    w = np.asarray(model.angular_frequencies_rad_s, float)
    r = len(w)
    U = model.mode_shapes_at(np.array([act.position_m, mic.position_m]))
    A = np.block([[np.zeros((r, r)), np.eye(r)], [-np.diag(w ** 2), -C]])
    B = np.zeros((2 * r, 1 + r))
    B[r:, 0] = -act.normal @ U[0]
    B[r:, 1:] = np.eye(r)                         # the modal load, one input per mode
    Cm = np.concatenate([mic.normal @ U[1], np.zeros(r)])[None]
    return A, B, Cm


def test_stream_with_passive_sound_matches_segmentwise_lsim():
    """Contacts and loads switching (table on/off, grip change, knocks, a slide): the stream
    (piecewise-linear drive, exact tolerance) against lsim of fingertip and object with the
    modal load as a second input (linear over each ramp, constant after), states carried."""
    model = BoxModel(np.linspace(700, 15000, 16), "wood", seed=4)
    act, mic = _fingers()
    pressed = (Contact(act.position_m, act.normal, 25.0, 0.5), Contact(mic.position_m, mic.normal, 25.0, 0.8))
    tab = tuple(Contact([x, 0.0, -H], [0, 0, -1], 1.5, 0.4) for x in (-0.08, 0.0, 0.08))
    rng = np.random.default_rng(5)
    exc = Excitation.linear_sweep()
    tip = FingertipModel()
    sched = []
    for k in range(120):
        fingers = pressed if 40 <= k < 70 else (act, mic)
        others = tab if (k // 15) % 2 == 0 else ()
        x = -0.05 + 0.0004 * k if k >= 80 else -0.05                # sliding from step 80
        f = 0.0 if k < 20 else (30.0 if k == 20 else 3.0 + rng.uniform(0, 0.5 if k >= 80 else 0.0))
        loads = ContactLoads([[x, 0.0, -H]], [[0, 0, -1]], [[0.4 * f if k >= 80 else 0.0, 0.0, f]],
                             sliding=[k >= 80])
        loads = ContactLoads(loads.positions_m, loads.normals, loads.forces_n, loads.sliding, impact=[k == 20])
        sched.append((int(rng.integers(60, 110)), GraspState(model, *fingers, others, loads=loads, object_key="b")))
    passive = PassiveSound(rise_time_s=1.5e-4, roughness=0.3, seed=2)
    stream = AcousticStream(exc, tip, tolerance=sensors.ContactTolerance.exact(), bandlimited=False,
                            passive=passive)
    y = np.concatenate([stream.advance(n, g) for n, g in sched]).astype(float) / mic_gain()
    # reference: the same roughness draws (one per read of a sliding contact, in order)
    gen = np.random.default_rng(2)
    p_all = [modal_load(model, g.loads, gen, 0.3) for _, g in sched]
    p_abs = [p[0] for p in p_all]
    base = p_abs[0]
    n_tot = sum(n for n, _ in sched)
    e_loop = tip.actuator_force_n * np.resize(exc.signal, n_tot + 1)
    Af, Bf, Cf = tip.state_space()
    r = len(model.angular_frequencies_rad_s)
    x_tip, x_obj = np.zeros(8), np.zeros(2 * r)
    ref = np.zeros(n_tot)
    s, p_prev, fluct_prev = 0, np.zeros(r), p_all[0][2]
    k_rise = round(1.5e-4 * FS)
    for (n, g), (pa, impacts, fluct) in zip(sched, p_all):
        p_new = pa - base
        sharp = impacts + fluct - fluct_prev
        t = np.arange(n + 1) / FS
        _, f, xt = ss.lsim((Af, Bf[:, None], Cf[None], np.zeros((1, 1))), e_loop[s:s + n + 1], t, X0=x_tip)
        x_tip = xt[-1]
        fast = np.clip(np.arange(n + 1) / min(k_rise, n), 0, 1)[:, None]
        slow = (np.arange(n + 1) / n)[:, None]
        P = p_prev[None] + fast * sharp[None] + slow * (p_new - p_prev - sharp)[None]
        if np.array_equal(p_new, p_prev):
            P = np.tile(p_prev, (n + 1, 1))
        C = sensors.modal_damping_matrix(model, [c for c in g.damping_contacts() if c.force_n > 0])
        A, B, Cm = _object_ss(model, C, g.actuator, g.mic)
        _, yy, xo = ss.lsim((A, B, Cm, np.zeros((1, 1 + r))), np.column_stack([f, P]), t, X0=x_obj)
        ref[s:s + n] = yy[:n]
        x_obj, p_prev, fluct_prev, s = xo[-1], p_new, fluct, s + n
    scale = np.abs(ref).max()
    assert np.abs(y - ref).max() <= 1e-6 * scale


def test_loads_need_displacement_or_velocity_output():
    with pytest.raises(ValueError):
        AcousticStream(Excitation.impulse(), output="acceleration", passive=PassiveSound())
    with pytest.raises(ValueError):
        PassiveSound(rise_time_s=-1.0)
    with pytest.raises(ValueError):
        ContactLoads(np.zeros((2, 3)), np.zeros((1, 3)), np.zeros((2, 3)))
