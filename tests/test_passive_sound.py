"""Passive sound (issue 26, item 4): contact force changes and slides excite the object.

References are independent of the code under test: the closed-form response of damped
oscillators to a force ramp (modal superposition, written here), and scipy.signal.lsim of
the object's and the fingertip's state spaces (built here) with the contact loads as a second
input, segment by segment with the states carried.  Each runs with both contact models: with
springs the loads act on the coupled modes of each contact set (``contact_modal_model``),
and at a change of contact set the state is carried relative to the load's static state.
"""

import numpy as np
import pytest
import scipy.signal as ss

import sensors
from sensors import Contact, Excitation, FingertipModel, GraspState
from sensors.synthesis.microphone import mic_gain
from sensors.synthesis.modal_system import CONTACT_MODELS, ModalSystem, contact_modal_model, transfer_state
from sensors.synthesis.passive import ContactLoads, PassiveSound
from sensors.synthesis import stream as stream_module
from sensors.synthesis.stream import AcousticStream
from synthesis_fakes import BoxModel

FS = 44100
H = 0.01


# The hand-made box has no elastic constants (no Hertz springs): table contacts with given
# springs, so that the modes change with the table contact (the pads' springs do not change).
_TABLE_SPRINGS = {"normal_stiffness_n_per_m": 3e6, "tangential_stiffness_n_per_m": 1e6}


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


def _grasp_modes(model, act, mic, others=(), contact_model="damping"):
    """The modes a grasp's system is in: the model's, or with the contacts' springs (the
    default fingertip pads' on the fingertips, as the stream adds them)."""
    tip = FingertipModel()
    contacts = [tip.pad(c) for c in (act, mic) if c is not None] + [c for c in others if c.force_n > 0]
    return contact_modal_model(model, contacts, contact_model), contacts


@pytest.mark.parametrize("contact_model", CONTACT_MODELS)
@pytest.mark.parametrize("impact,rise_time_s", [(True, 2e-4), (True, 1e-3), (False, 2e-4)])
def test_impact_matches_modal_superposition(box, impact, rise_time_s, contact_model):
    """A 12 N knock under the grasped box (an impact: over the rise time; a persisting
    contact: over the span): the stream's extra output (passive on minus off) equals the
    closed-form sum over modes of the damped oscillators' ramp responses (with springs: the
    modes coupled by the fingertip pads' springs, Rayleigh-damped at their own frequencies)."""
    act, mic = _fingers()
    exc = Excitation.linear_sweep()
    before = GraspState(box, act, mic, loads=_knock(0.0), object_key="box")
    after = GraspState(box, act, mic, loads=_knock(12.0, impact=impact), object_key="box")
    n0, n1 = 441, 8820
    passive = PassiveSound(rise_time_s=rise_time_s)
    on = AcousticStream(exc, method="diagonal", passive=passive, contact_model=contact_model)
    off = AcousticStream(exc, method="diagonal", contact_model=contact_model)
    y_on = np.concatenate([on.synthesize(n0, before), on.synthesize(n1, after)])
    y_off = np.concatenate([off.synthesize(n0, before), off.synthesize(n1, after)])
    got = (y_on - y_off)[n0:]
    # reference: modes j, force F at p: modal force phi_j = F . U_j(p); output o_j = n_mic . U_j(mic)
    loads = _knock(12.0)
    modes, _ = _grasp_modes(box, act, mic, contact_model=contact_model)
    assert (modes is box) == (contact_model == "damping")
    U = modes.mode_shapes_at(np.vstack([loads.positions_m, mic.position_m]))
    phi = loads.forces_n[0] @ U[0]
    o = mic.normal @ U[1]
    w = modes.angular_frequencies_rad_s
    zeta = (box.material.alpha + box.material.beta * w ** 2) / (2 * w)
    tau = (round(rise_time_s * FS) if impact else n1) / FS
    t = np.arange(n1) / FS
    ref = sum(o[j] * phi[j] * _ramp_response(w[j], zeta[j], t, tau) for j in range(len(w)))
    assert np.abs(ref).max() > 0.1 * np.abs(y_off).max()      # not negligible next to the drive
    assert np.abs(got - ref).max() <= 1e-7 * np.abs(ref).max()
    assert on.metadata["passive"]["rise_time_s"] == rise_time_s


@pytest.mark.parametrize("contact_model", CONTACT_MODELS)
def test_constant_loads_make_no_sound_and_resting_objects_do_not_ring(box, contact_model):
    act, mic = _fingers()
    exc = Excitation.impulse()
    g = GraspState(box, act, mic, loads=_knock(5.0))
    same = GraspState(box, act, mic, loads=_knock(5.0))            # a new read, the same loads
    on = AcousticStream(exc, method="diagonal", passive=PassiveSound(), contact_model=contact_model)
    off = AcousticStream(exc, method="diagonal", contact_model=contact_model)
    a = np.concatenate([on.synthesize(500, g), on.synthesize(700, same)])
    b = np.concatenate([off.synthesize(500, g), off.synthesize(700, same)])
    assert np.array_equal(a, b)


def test_a_held_load_makes_no_sound_when_the_contact_springs_change(box):
    """A knock that stays (a constant load) while the table's springs come and go: with
    springs each contact set has its own modes and static deflection under the load; the
    state is carried relative to it, so the passive part of the output (on minus off) is the
    static deflection alone, no ringing (as with damping only, where nothing changes).  The
    table contacts carry no load of their own here (its forces are not in ``loads``)."""
    act, mic = _fingers()
    tab = tuple(Contact([x, 0.0, -H], [0, 0, -1], 1.5, 0.4, **_TABLE_SPRINGS) for x in (-0.08, 0.08))
    exc = Excitation.impulse()
    knock, held = _knock(0.0), _knock(12.0)
    sched = [(300, GraspState(box, act, mic, loads=knock, object_key="b")),
             (31000, GraspState(box, act, mic, loads=_knock(12.0, impact=True), object_key="b"))]   # the knock rings down
    for k in range(6):
        sched.append((441 + 37 * k, GraspState(box, act, mic, tab if k % 2 == 0 else (), loads=held, object_key="b")))
    for contact_model in CONTACT_MODELS:
        on = AcousticStream(exc, method="diagonal", passive=PassiveSound(rise_time_s=0.0), contact_model=contact_model)
        off = AcousticStream(exc, method="diagonal", contact_model=contact_model)
        d = on.synthesize(sched) - off.synthesize(sched)
        s = sum(n for n, _ in sched[:2])
        for n, g in sched[2:]:
            # the static deflection of this contact set's modes under the knock (closed form)
            modes, _ = _grasp_modes(box, act, mic, g.others, contact_model)
            U = modes.mode_shapes_at(np.vstack([held.positions_m, mic.position_m]))
            w = np.asarray(modes.angular_frequencies_rad_s)
            static = np.sum((held.forces_n[0] @ U[0]) * (mic.normal @ U[1]) / w ** 2)
            assert np.abs(d[s:s + n] - static).max() <= 1e-6 * abs(static)
            s += n


@pytest.mark.parametrize("contact_model", CONTACT_MODELS)
def test_knocks_ring_down_without_growth(box, contact_model):
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
    on = AcousticStream(exc, method="diagonal", passive=PassiveSound(roughness=0.0), contact_model=contact_model)
    off = AcousticStream(exc, method="diagonal", contact_model=contact_model)
    d = on.synthesize(spans) - off.synthesize(spans)
    rest = on.synthesize(FS, hold) - off.synthesize(FS, hold)
    w = _grasp_modes(box, act, mic, contact_model=contact_model)[0].angular_frequencies_rad_s
    slowest = np.min((box.material.alpha + box.material.beta * w ** 2) / 2)
    env = [np.abs(rest[i:i + 441] - rest[-1]).max() for i in range(0, FS - 441, 441)]
    bound = np.abs(d).max() * (10 * np.exp(-slowest * np.arange(len(env)) * 0.01) + 1e-14)   # + rounding
    assert np.all(np.isfinite(rest)) and np.all(env <= bound)
    assert env[-1] < 1e-12 * env[0]


def _object_ss(modes, C, act, mic):
    w = np.asarray(modes.angular_frequencies_rad_s, float)
    r = len(w)
    U = modes.mode_shapes_at(np.array([act.position_m, mic.position_m]))
    A = np.block([[np.zeros((r, r)), np.eye(r)], [-np.diag(w ** 2), -C]])
    B = np.zeros((2 * r, 1 + r))
    B[r:, 0] = -act.normal @ U[0]
    B[r:, 1:] = np.eye(r)                         # the modal load, one input per mode
    Cm = np.concatenate([mic.normal @ U[1], np.zeros(r)])[None]
    return A, B, Cm


def _read(loads, gen, roughness):
    """One contact read's forces (n, 3) with the roughness of its sliding contacts, xi F_t
    (xi ~ N(0, 1), one draw per read as the stream draws them), and its roughness alone."""
    F = np.array(loads.forces_n, float)
    slip = np.zeros_like(F)
    if loads.sliding.any():
        idx = np.flatnonzero(loads.sliding)
        n = loads.normals[idx]
        friction = F[idx] - np.sum(F[idx] * n, axis=1)[:, None] * n
        slip[idx] = (roughness * gen.standard_normal(idx.size))[:, None] * friction
    return F + slip, slip


def _project(modes, loads, forces, keep):
    """sum_c U_k(x_c) . F_c for the kept modes k (the others are not simulated)."""
    U = modes.mode_shapes_at(loads.positions_m)
    p = np.einsum("nd,ndr->r", forces, U)
    return np.where(np.isin(np.arange(p.size), keep), p, 0.0)


class _Kept:
    """The modes ``keep`` of a modal model."""

    def __init__(self, modes, keep):
        self.modes, self.keep = modes, keep
        self.angular_frequencies_rad_s = np.asarray(modes.angular_frequencies_rad_s)[keep]

    def mode_shapes_at(self, points_m):
        return self.modes.mode_shapes_at(points_m)[..., self.keep]


@pytest.fixture(scope="module")
def bar():
    return sensors.ModalModel.bar(0.2, 2 * H, 2 * H, sensors.MATERIALS["steel"], progress=False)


def _switching_schedule(model):
    """120 spans (60-110 samples) of contacts and loads switching: the table on and off, the
    grip changing, a knock (an impact) and a slide with roughness."""
    act, mic = _fingers()
    pressed = tuple(Contact(c.position_m, c.normal, 25.0, mu, **_TABLE_SPRINGS) for c, mu in ((act, 0.5), (mic, 0.8)))
    tab = tuple(Contact([x, 0.0, -H], [0, 0, -1], 1.5, 0.4, **_TABLE_SPRINGS) for x in (-0.08, 0.0, 0.08))
    rng = np.random.default_rng(5)
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
    return sched


def _passive_stream(contact_model):
    """The stream of :func:`_switching_schedule`'s tests (piecewise-linear drive, exact tolerance)."""
    return AcousticStream(Excitation.linear_sweep(), FingertipModel(), tolerance=sensors.ContactTolerance.exact(),
                          bandlimited=False, passive=PassiveSound(rise_time_s=1.5e-4, roughness=0.3, seed=2),
                          contact_model=contact_model)


@pytest.mark.parametrize("merged", [True, False])
@pytest.mark.parametrize("model_name,contact_model", [("box", "damping"), ("box", "spring_damper"),
                                                      ("bar", "spring_damper")])
def test_stream_with_passive_sound_matches_segmentwise_lsim(model_name, contact_model, merged, request, monkeypatch):
    """Contacts and loads switching (table on/off, grip change, knocks, a slide): the stream
    (piecewise-linear drive, exact tolerance) against lsim of fingertip and object with the
    modal load as a second input (linear over each ramp, constant after), states carried.
    With springs each span runs in its contact set's modes (those below Nyquist, as the
    synthesis keeps them) with the loads projected onto them; where they change, the state
    relative to the load's static state x_eq = [p / w^2; 0] is carried by the M-projection of
    the scaled state (``transfer_state``) and the new set's x_eq under the same forces added.
    The FEM bar's coupled modes hold its rigid-body motion on the springs and the attachment
    modes of each contact: the loads act on those too.  Both syntheses of a span whose load
    changes (``stream.ONE_CONVOLUTION_PER_RUN``) meet the reference."""
    monkeypatch.setattr(stream_module, "ONE_CONVOLUTION_PER_RUN", merged)
    model = BoxModel(np.linspace(700, 15000, 16), "wood", seed=4) if model_name == "box" else request.getfixturevalue("bar")
    sched = _switching_schedule(model)
    exc, tip = Excitation.linear_sweep(), FingertipModel()
    stream = _passive_stream(contact_model)
    y = np.concatenate([stream.advance(sched[i:i + 8]) for i in range(0, len(sched), 8)]).astype(float) / mic_gain()
    # reference: the same roughness draws (one per read of a sliding contact, in order)
    gen = np.random.default_rng(2)
    reads = [(g.loads, *_read(g.loads, gen, 0.3)) for _, g in sched]
    n_tot = sum(n for n, _ in sched)
    e_loop = tip.actuator_force_n * np.resize(exc.signal, n_tot + 1)
    Af, Bf, Cf = tip.state_space()
    x_tip, x_obj, modes, w_old, keep_old = np.zeros(8), None, None, None, None
    ref = np.zeros(n_tot)
    s = 0
    k_rise = round(1.5e-4 * FS)
    switches = 0
    for i, (n, g) in enumerate(sched):
        span_modes, contacts = _grasp_modes(model, g.actuator, g.mic, g.others, contact_model)
        w = np.asarray(span_modes.angular_frequencies_rad_s, float)
        keep = np.flatnonzero(w < np.pi * FS)
        both = np.concatenate([keep, w.size + keep])

        def load(j, m=span_modes, kp=keep):   # read j's modal load relative to the first read
            return _project(m, reads[j][0], reads[j][1], kp) - _project(m, reads[0][0], reads[0][1], kp)

        p_prev = load(max(i - 1, 0))
        if x_obj is None:
            x_obj = np.zeros(2 * w.size)
        elif span_modes is not modes:        # plain [q; q'] here, the transfer takes [w q; q']
            switches += 1
            p_old = load(i - 1, modes, keep_old)
            dev = x_obj - np.concatenate([np.where(p_old != 0, p_old / w_old ** 2, 0.0), np.zeros(w_old.size)])
            xs = transfer_state(np.concatenate([w_old * dev[:w_old.size], dev[w_old.size:]]), modes, span_modes)
            x_obj = np.concatenate([xs[:w.size] / w + np.where(p_prev != 0, p_prev / w ** 2, 0.0), xs[w.size:]])
        modes, w_old, keep_old = span_modes, w, keep
        p_new = load(i)
        impacts = _project(span_modes, reads[i][0], np.where(reads[i][0].impact[:, None], reads[i][0].forces_n, 0.0), keep)
        sharp = impacts + _project(span_modes, reads[i][0], reads[i][2], keep) - (
            _project(span_modes, reads[i - 1][0], reads[i - 1][2], keep) if i else 0.0)
        t = np.arange(n + 1) / FS
        _, f, xt = ss.lsim((Af, Bf[:, None], Cf[None], np.zeros((1, 1))), e_loop[s:s + n + 1], t, X0=x_tip)
        x_tip = xt[-1]
        fast = np.clip(np.arange(n + 1) / min(k_rise, n), 0, 1)[:, None]
        slow = (np.arange(n + 1) / n)[:, None]
        P = p_prev[None] + fast * sharp[None] + slow * (p_new - p_prev - sharp)[None]
        if i == 0 or np.array_equal(p_new, p_prev):
            P = np.tile(p_new, (n + 1, 1))
        C = sensors.modal_damping_matrix(span_modes, contacts)[np.ix_(keep, keep)]
        A, B, Cm = _object_ss(_Kept(span_modes, keep), C, g.actuator, g.mic)
        _, yy, xo = ss.lsim((A, B, Cm, np.zeros((1, 1 + keep.size))), np.column_stack([f, P[:, keep]]), t,
                            X0=x_obj[both])
        ref[s:s + n] = yy[:n]
        x_obj = np.zeros_like(x_obj)
        x_obj[both] = xo[-1]
        s += n
    assert switches == (0 if contact_model == "damping" else 9)
    scale = np.abs(ref).max()
    assert np.abs(y - ref).max() <= 1e-6 * scale


def test_loads_need_displacement_or_velocity_output():
    with pytest.raises(ValueError):
        AcousticStream(Excitation.impulse(), output="acceleration", passive=PassiveSound())
    with pytest.raises(ValueError):
        PassiveSound(rise_time_s=-1.0)
    with pytest.raises(ValueError):
        ContactLoads(np.zeros((2, 3)), np.zeros((1, 3)), np.zeros((2, 3)))


def test_ramp_particular_solves_the_affine_equations():
    """x_p = alpha + beta t solves x' = A x + [0; p(t)] for a load ramping p0 -> p1 over tau:
    A beta + [0; (p1 - p0) / tau] = 0 and A alpha + [0; p0] = beta (the state matrix of six
    damped modes, checked by products with A, independent of the LU solves); equal loads give
    the equilibrium (beta = 0)."""
    import scipy.linalg as sla

    from sensors.synthesis.modal_system import modal_state_matrix
    from sensors.synthesis.passive import ramp_particular

    rng = np.random.default_rng(3)
    w = 2 * np.pi * np.linspace(800.0, 9000.0, 6)
    C = np.diag(0.02 * w) + 5.0 * np.outer(rng.random(6), rng.random(6))
    A = modal_state_matrix(w, C)
    lu = sla.lu_factor(A)
    p0, p1, tau = rng.standard_normal(6), rng.standard_normal(6), 2e-4
    alpha, beta = ramp_particular(lu, p0, p1, tau)
    load = lambda p: np.concatenate([np.zeros(6), p])  # noqa: E731
    scale = np.abs(A).max() * np.abs(alpha).max() + np.abs(p0).max()
    assert np.abs(A @ beta + load((p1 - p0) / tau)).max() < 1e-12 * np.abs(A).max() * np.abs(beta).max()
    assert np.abs(A @ alpha + load(p0) - beta).max() < 1e-12 * scale
    eq, zero = ramp_particular(lu, p0, p0, 0.0)
    assert not np.any(zero) and np.abs(A @ eq + load(p0)).max() < 1e-12 * scale


@pytest.mark.parametrize("model_name,contact_model", [("box", "damping"), ("bar", "spring_damper")])
def test_merged_load_ramp_equals_the_two_piece_synthesis(model_name, contact_model, request, monkeypatch):
    """Spans in a row on one system synthesized with one drive convolution, each piece's start
    (a new read, the end of an impact's ramp) a state jump (the default), equal the pieces
    synthesized one after the other (the reference path, ``ONE_CONVOLUTION_PER_RUN = False``)
    to rounding: 1e-12 of the largest sample over 120 switching spans (the time-domain sums
    round at ~1e-15 per step)."""
    model = BoxModel(np.linspace(700, 15000, 16), "wood", seed=4) if model_name == "box" else request.getfixturevalue("bar")
    sched = _switching_schedule(model)
    out, calls = {}, {}
    response = ModalSystem.response

    def counted(self, *args, **kwargs):
        calls[merged] += 1
        return response(self, *args, **kwargs)

    monkeypatch.setattr(ModalSystem, "response", counted)
    for merged in (True, False):
        monkeypatch.setattr(stream_module, "ONE_CONVOLUTION_PER_RUN", merged)
        stream, calls[merged] = _passive_stream(contact_model), 0
        # the physics steps of an env step come in one call: 8 spans each
        out[merged] = np.concatenate([stream.synthesize(sched[i:i + 8]) for i in range(0, len(sched), 8)])
    scale = np.abs(out[False]).max()
    assert scale > 0
    assert np.abs(out[True] - out[False]).max() <= 1e-12 * scale
    assert calls[True] < calls[False] / 2          # spans on one system share a convolution
