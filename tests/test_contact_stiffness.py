"""Contacts as springs (issue 26): Hertz/Mindlin stiffness against hand-computed textbook
values, and the coupled modes of the small aluminium bar held by grounded springs against an
independent full FEM with the springs (scikit-fem P2 on the same tet mesh, springs added to
its stiffness matrix at a mesh vertex).  Stress tests: 1e9 N/m, 20 contacts, contacts
switching every sample: no growth of energy and the same response as a dense reference
(``scipy.signal.lsim``, which integrates a piecewise-linear input exactly)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal
import scipy.sparse as sp
import scipy.sparse.linalg

import sensors
from sensors import MATERIALS, Contact, FingertipModel, Material, ModalModel, ModalSystem, contact_modes
from sensors.mesh.prisms import bar_mesh
from sensors.modal.contact_stiffness import (contact_stiffnesses_n_per_m, hertz_normal_stiffness_n_per_m,
                                             mindlin_tangential_stiffness_n_per_m)
from sensors.modal.static_correction import MAX_ATTACHMENT_VECTORS
from sensors.synthesis.modal_system import contact_modal_model, modal_state_matrix

BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)
RES = 0.5          # 1725 dof P2: the reference solve takes well under a second
FMAX_HZ = 12000.0
FS = 44100


# ----------------------------------------------------------------------------- contact mechanics


def test_hertz_and_mindlin_against_hand_computed_values():
    # Steel sphere (R = 10 mm) on a steel flat, F = 100 N, E = 210 GPa, nu = 0.3 (Johnson 1985):
    # E* = E / (2 (1 - nu^2)) = 1.15385e11 Pa, a = (3 F R / (4 E*))^(1/3) = 1.8663e-4 m,
    # k_n = 2 E* a = 4.3068e7 N/m; G = E / 2.6 = 8.0769e10 Pa, G* = G / (2 (2 - nu)) = 2.37557e10 Pa,
    # k_t = 8 G* a = 3.5468e7 N/m (k_t / k_n = 2 (1 - nu) / (2 - nu) = 0.82353).
    steel = Material("s", 7800.0, 210e9, 0.3, alpha=0.0, beta=0.0, gamma=0.0)
    kn = hertz_normal_stiffness_n_per_m(100.0, 0.01, steel, steel)
    kt = mindlin_tangential_stiffness_n_per_m(100.0, 0.01, steel, steel)
    assert kn == pytest.approx(4.3068e7, rel=2e-4)
    assert kt == pytest.approx(3.5468e7, rel=2e-4)
    assert kt / kn == pytest.approx(1.4 / 1.7, rel=1e-12)
    # k_n is the slope of Hertz's F(delta) = 4/3 E* sqrt(R) delta^(3/2) at the load's delta = a^2 / R
    e_star, R = 210e9 / (2 * 0.91), 0.01
    delta = (3 * 100.0 * R / (4 * e_star)) ** (2 / 3) / R
    F = lambda d: 4 / 3 * e_star * math.sqrt(R) * d ** 1.5  # noqa: E731
    assert F(delta) == pytest.approx(100.0, rel=1e-12)
    h = 1e-4 * delta
    assert kn == pytest.approx((F(delta + h) - F(delta - h)) / (2 * h), rel=1e-7)


def test_contact_stiffness_fields():
    c = Contact([0, 0, 0.0125], [0, 0, 1], 5.0, 0.5)
    kn, kt = contact_stiffnesses_n_per_m(c, "aluminium")
    # 5 N, R = 5 mm, aluminium on wood: the 2e5-3e6 N/m, tangential about 0.8 of it
    assert 2e5 < kn < 3e6 and 0.7 < kt / kn < 0.9
    assert contact_stiffnesses_n_per_m(Contact([0, 0, 0], [0, 0, 1], 5.0, 0.0), "aluminium")[1] == 0.0  # slides
    assert contact_stiffnesses_n_per_m(Contact([0, 0, 0], [0, 0, 1], 0.0, 0.5), "aluminium") == (0.0, 0.0)
    given = Contact([0, 0, 0], [0, 0, 1], 5.0, 0.5, 1e6, 0.0, radius_m=1e-3, counter_material="steel")
    assert contact_stiffnesses_n_per_m(given, "aluminium") == (1e6, 0.0)
    assert Contact.from_dict(given.to_dict()) == given and hash(Contact.from_dict(given.to_dict())) == hash(given)
    old = {"position_m": [0, 0, 0], "normal": [0, 0, 1], "force_n": 5.0, "friction": 0.5}
    assert Contact.from_dict(old) == Contact([0, 0, 0], [0, 0, 1], 5.0, 0.5)
    assert given != Contact([0, 0, 0], [0, 0, 1], 5.0, 0.5)
    with pytest.raises(ValueError):
        Contact([0, 0, 0], [0, 0, 1], 5.0, 0.5, normal_stiffness_n_per_m=-1.0)
    with pytest.raises(KeyError):
        Contact([0, 0, 0], [0, 0, 1], 5.0, 0.5, counter_material="unobtainium")


# ----------------------------------------------------------------------------- full-FEM reference


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=RES, cache=False, max_frequency_hz=FMAX_HZ)


@pytest.fixture(scope="module")
def reference():
    """scikit-fem's P2 K and M of the same tet mesh (independent assembly), its vertices and
    the dofs (x, y, z) of each vertex."""
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, MeshTet2, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    tm = bar_mesh(**BAR, resolution=RES)
    mesh = MeshTet2.from_mesh(MeshTet(tm.vertices_m.T.copy(), tm.tets.T.copy()))
    basis = Basis(mesh, ElementVector(ElementTetP2()))
    m = MATERIALS["aluminium"]
    E, nu, rho = m.youngs_modulus_pa, m.poisson_ratio, m.density_kg_m3
    K = asm(linear_elasticity(E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))), basis)

    @BilinearForm
    def mass(u, v, w):
        return rho * dot(u, v)

    return K.tocsr(), asm(mass, basis).tocsr(), tm.vertices_m, basis.nodal_dofs


def reference_hz(reference, springs, n=12):
    """Lowest n nonzero frequencies [Hz] of the full FEM with grounded springs
    [(vertex, normal axis, k_n, k_t)] (axis-aligned normals: the springs are diagonal)."""
    K, M, _, dofs = reference
    K = K.tolil()
    for v, axis, kn, kt in springs:
        for j in range(3):
            K[dofs[j, v], dofs[j, v]] += kn if j == axis else kt
    lam = scipy.sparse.linalg.eigsh(K.tocsc(), k=n + 6, M=M, sigma=-(2 * math.pi * 10) ** 2, which="LM",
                                    return_eigenvectors=False)
    f = np.sqrt(np.maximum(np.sort(lam), 0.0)) / (2 * math.pi)
    return f[f > 1.0]


def vertex(reference, x_m, face_axis, side):
    """The mesh vertex on the face (axis, +-1) nearest to x = x_m, on the face's centre line."""
    V = reference[2]
    h = {0: BAR["length_m"], 1: BAR["width_m"], 2: BAR["height_m"]}[face_axis] / 2
    on = np.flatnonzero(np.isclose(V[:, face_axis], side * h))
    other = [a for a in (1, 2) if a != face_axis]
    i = on[np.argmin(np.abs(V[on, 0] - x_m) + sum(np.abs(V[on, a]) for a in other))]
    return int(i), V[i]


def check_shifts(free_hz, coupled_hz, true_hz, band_hz=0.6 * FMAX_HZ, rtol=0.05):
    """Every true coupled mode in band: |f - f_true| <= rtol |f_true - f_free| (+ rounding), f_free
    the nearest free frequency (0 for suspension modes): the shift within rtol."""
    true_hz = true_hz[true_hz < band_hz]
    assert len(coupled_hz) >= len(true_hz)
    free = np.concatenate([[0.0], free_hz])
    for f_true, f in zip(true_hz, coupled_hz):
        shift = np.min(np.abs(f_true - free))
        assert abs(f - f_true) <= rtol * shift + 1e-6 * f_true, (f, f_true, shift)


@pytest.mark.parametrize("kn, kt", [(1e5, 0.0), (1e6, 0.0), (1e7, 0.0), (0.0, 1e7), (1e7, 1e7)])
def test_grounded_spring_matches_full_fem(bar, reference, kn, kt):
    v, p = vertex(reference, 0.05, 2, +1)
    c = Contact(p, [0, 0, 1], 5.0, 0.5, normal_stiffness_n_per_m=kn, tangential_stiffness_n_per_m=kt)
    modes = contact_modal_model(bar, [c])
    true = reference_hz(reference, [(v, 2, kn, kt)])
    check_shifts(bar.frequencies_hz, modes.frequencies_hz, true)
    # the point: the bar's first bending mode moves audibly at 1e7 N/m
    if kn == 1e7:
        assert np.abs(modes.frequencies_hz[None, :] - 3101.5).min() < 5.0
    # contact_modes: ascending, the same frequencies (light damping), and none without springs
    f, decay = contact_modes(bar, [c])
    assert np.all(np.diff(f) >= 0) and np.all(decay > 0)
    assert f[:len(true[true < 7e3])] == pytest.approx(true[true < 7e3], rel=1e-3)
    f0, _ = contact_modes(bar, [c], contact_model="damping")
    assert f0 == pytest.approx(bar.frequencies_hz, rel=1e-3)


def test_fingertip_pads_match_full_fem(bar, reference):
    """The two fingertip pads (FingertipModel's springs) on opposite faces of the bar."""
    tip = FingertipModel()
    va, pa = vertex(reference, 0.04, 1, +1)
    vm, pm = vertex(reference, 0.04, 1, -1)
    act = tip.pad(Contact(pa, [0, 1, 0], 40.0, 0.8))
    mic = tip.pad(Contact(pm, [0, -1, 0], 40.0, 0.8))
    kn, kt = tip.contact_stiffness_n_m, tip.contact_tangential_stiffness_n_m
    true = reference_hz(reference, [(va, 1, kn, kt), (vm, 1, kn, kt)])
    modes = contact_modal_model(bar, [act, mic])
    check_shifts(bar.frequencies_hz, modes.frequencies_hz, true)
    # the pads stiffen the bending pair (~3.09 kHz free): both move up
    pair = modes.frequencies_hz[(modes.frequencies_hz > 3000) & (modes.frequencies_hz < 3300)]
    assert len(pair) == 2 and np.all(pair > bar.frequencies_hz[:2] + 1.0)


# ----------------------------------------------------------------------------- stress tests


def dense_response(system_modes, contacts, u, drive, mic):
    """Reference: the continuous state space [w q; q'] of the coupled modes, integrated by lsim."""
    from sensors.modal.damping import modal_damping_parts

    w = system_modes.angular_frequencies_rad_s
    keep = w < math.pi * FS
    d, Q = modal_damping_parts(system_modes, contacts)
    C = (np.diag(d) + Q.T @ Q)[np.ix_(keep, keep)]
    w = w[keep]
    S = system_modes.mode_shapes_at(np.array([drive[0], mic[0]]))[:, :, keep]
    b, o = -drive[1] @ S[0], mic[1] @ S[1]
    A = modal_state_matrix(w, C)
    B = np.concatenate([np.zeros(w.size), b])[:, None]
    Cout = np.concatenate([o / w, np.zeros(w.size)])[None, :]
    t = np.arange(len(u)) / FS
    return scipy.signal.lsim((A, B, Cout, np.zeros((1, 1))), u, t, interp=True)[1]


def _surface_contacts(reference, n, k):
    """n contacts with normal and tangential springs k at vertices spread over the top and sides."""
    out = []
    for i in range(n):
        axis, side = [(2, 1), (1, 1), (1, -1), (2, -1)][i % 4]
        _, p = vertex(reference, -0.09 + 0.18 * i / max(n - 1, 1), axis, side)
        nrm = np.zeros(3)
        nrm[axis] = side
        out.append(Contact(p, nrm, 5.0, 0.5, normal_stiffness_n_per_m=k, tangential_stiffness_n_per_m=k))
    return out


@pytest.mark.parametrize("case", ["stiff_1e9", "twenty_contacts"])
def test_stress_passive_and_dense_reference(bar, reference, case):
    contacts = (_surface_contacts(reference, 1, 1e9) if case == "stiff_1e9"
                else _surface_contacts(reference, MAX_ATTACHMENT_VECTORS // 3, 1e7))
    _, pd = vertex(reference, 0.04, 1, 1)
    _, pm = vertex(reference, 0.04, 1, -1)
    drive, mic = (pd, np.array([0.0, 1.0, 0.0])), (pm, np.array([0.0, -1.0, 0.0]))
    sysm = ModalSystem.build(bar, FS, drive[0], drive[1], mic[0], mic[1], contacts)
    rho = np.abs(np.linalg.eigvals(sysm.transition_matrix())).max()
    assert rho <= 1.0 + 1e-12
    u = np.random.default_rng(0).standard_normal(400)
    y = sysm.response(u)
    ref = dense_response(sysm.modes, contacts, u, drive, mic)
    assert np.max(np.abs(y - ref)) <= 1e-6 * np.max(np.abs(ref))


def test_too_many_contacts_is_refused_with_the_limit(bar, reference):
    """The attachment solve refuses more directions than the limit, with the limit's name; the
    contact springs a grasp hands it are merged (nearby parallel springs) to fit it."""
    from sensors.modal.spring_modes import contact_springs
    from sensors.modal.static_correction import contact_flexibility

    contacts = _surface_contacts(reference, MAX_ATTACHMENT_VECTORS // 3 + 1, 1e7)
    points = np.array([c.position_m for c in contacts])
    dirs = np.array([c.normal for c in contacts])
    many = np.repeat(points, 3, axis=0), np.repeat(dirs, 3, axis=0)
    with pytest.raises(ValueError, match="MAX_ATTACHMENT_VECTORS"):
        contact_flexibility(bar).attachment_modes(*many)
    springs = contact_springs(bar, contacts)
    n_dirs = sum((kn > 0) + 2 * (kt > 0) for _, _, kn, kt in springs)
    assert n_dirs <= MAX_ATTACHMENT_VECTORS
    # the merged springs keep the total stiffness
    total = sum(kn for _, _, kn, _ in springs)
    assert total == pytest.approx(sum(kn for _, _, kn, _ in contact_springs(bar, contacts[:1])) * len(contacts),
                                  rel=0.5)
    contact_modal_model(bar, contacts)       # bounded: builds


def test_switching_every_sample_is_passive_and_matches_reference(bar, reference):
    """Contacts switching every sample (a spring set, another, none): the response equals the
    system-by-system evaluation with the same state transfer, and no step adds energy."""
    from sensors.synthesis.modal_system import modal_state_energy, transfer_state

    _, pd = vertex(reference, 0.04, 1, 1)
    _, pm = vertex(reference, 0.04, 1, -1)
    drive, mic = (pd, np.array([0.0, 1.0, 0.0])), (pm, np.array([0.0, -1.0, 0.0]))
    sets = [_surface_contacts(reference, 2, 1e7), _surface_contacts(reference, 3, 1e6)[1:], []]
    n = 60
    sched = [(i / FS, sets[i % 3]) for i in range(n)]
    u = np.random.default_rng(1).standard_normal(n)
    y = sensors.modal_response(bar, u, FS, drive[0], drive[1], mic[0], mic[1], sched)
    ref = np.zeros(n)
    x, modes = None, None
    for i in range(n):
        sysm = ModalSystem.build(bar, FS, drive[0], drive[1], mic[0], mic[1], sets[i % 3], keep_all_modes=True)
        x = np.zeros(2 * sysm.n_modes) if x is None else transfer_state(x, modes, sysm.modes)
        seg = u[i:i + 2] if i + 1 < n else u[i:i + 1]
        ref[i] = sysm.response(seg, x)[0]
        x = sysm.final_state(seg, x) if i + 1 < n else x
        modes = sysm.modes
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))
    # free ring-down switching every sample, from a displaced and moving state: every one-step
    # map is a contraction (spectral radius <= 1, each step's energy at most the previous) and
    # no switch adds energy (a contact forms unstretched, see transfer_state)
    x0, modes = None, None
    for i in range(60):
        sysm = ModalSystem.build(bar, FS, drive[0], drive[1], mic[0], mic[1], sets[i % 3], keep_all_modes=True)
        assert np.abs(np.linalg.eigvals(sysm.transition_matrix())).max() <= 1.0 + 1e-12
        if x0 is None:
            x0 = np.full(2 * sysm.n_modes, 1e-3)
        else:
            e_switch = modal_state_energy(x0)
            x0 = transfer_state(x0, modes, sysm.modes)
            assert modal_state_energy(x0) <= e_switch * (1 + 1e-12)
        before = modal_state_energy(x0)
        x0 = sysm.final_state(np.zeros(2), x0)
        assert modal_state_energy(x0) <= before * (1 + 1e-12)
        modes = sysm.modes


# ----------------------------------------------------------------------------- two bodies


def full_fem_two_bars(reference, pads, table, links, k_table=(0.0, 0.0)):
    """The full FEM of bar A and bar B (B's dofs after A's), both with ``reference``'s K and M:
    ``pads`` grounded springs on A [(vertex, normal axis, k_n, k_t)], ``table`` vertices of B
    on the table (springs ``k_table``: normal, tangential), ``links`` springs between them [(vertex of A, vertex of B, (k_n,
    k_t))], all with vertical or axis-aligned normals. Returns (K, M), sparse CSC."""
    K, M, _, dofs = reference
    n = K.shape[0]
    K2 = sp.block_diag([K, K]).tolil()
    for v, axis, kn, kt in pads:                                            # A's pads, grounded
        for j in range(3):
            K2[dofs[j, v], dofs[j, v]] += kn if j == axis else kt
    for v in table:                                                         # B on the table
        for j, k in ((0, k_table[1]), (1, k_table[1]), (2, k_table[0])):
            K2[n + dofs[j, v], n + dofs[j, v]] += k
    for va, vb, (kn, kt) in links:                                          # A -- B
        for j, k in ((0, kt), (1, kt), (2, kn)):
            a, b = dofs[j, va], n + dofs[j, vb]
            K2[a, a] += k
            K2[b, b] += k
            K2[a, b] -= k
            K2[b, a] -= k
    return K2.tocsc(), sp.block_diag([M, M]).tocsc()


def lowest_hz(K, M, k=30) -> np.ndarray:
    """The lowest ``k`` frequencies [Hz] of (K, M), rigid-body modes at ~0."""
    lam = scipy.sparse.linalg.eigsh(K, k=k, M=M, sigma=-(2 * math.pi * 10) ** 2, which="LM", return_eigenvectors=False)
    return np.sqrt(np.maximum(np.sort(lam), 0.0)) / (2 * math.pi)


def test_two_bars_joined_by_a_spring_match_full_fem(bar, reference):
    """Component mode synthesis (sensors.modal.coupled_bodies) of two free bars, the second
    stacked on the first (25 mm up), joined at one point by a spring of 1e7 N/m normal and
    5e6 N/m tangential, against the full FEM of both bars with the spring."""
    from sensors.modal.coupled_bodies import BodyLink, coupled_bodies

    V = reference[2]
    h = BAR["height_m"]
    va, pa = vertex(reference, 0.05, 2, +1)                       # top of bar A
    vb = int(np.argmin(np.linalg.norm(V - (pa - [0, 0, h]), axis=1)))  # bottom of bar B (B frame)
    assert np.allclose(V[vb] + [0, 0, h], pa)
    kn, kt = 1e7, 5e6
    true = lowest_hz(*full_fem_two_bars(reference, (), (), [(va, vb, (kn, kt))]), k=24)
    true = true[true > 1.0]
    link = BodyLink(0, 1, tuple(pa), (0.0, 0.0, 1.0), kn, kt)
    both = coupled_bodies([(bar, np.eye(3), np.zeros(3)), (bar, np.eye(3), np.array([0.0, 0.0, h]))], [link])
    free = np.sort(np.concatenate([bar.frequencies_hz, bar.frequencies_hz]))
    check_shifts(free, both.frequencies_hz, true)
    # the shapes: both bodies move in the coupled modes, mass-normalised over the assembly
    s0 = both.mode_shapes_at(0, pa[None])
    s1 = both.mode_shapes_at(1, (pa - [0, 0, h])[None])
    assert s0.shape == s1.shape == (1, 3, both.frequencies_hz.size)


# ----------------------------------------------------------------------------- the option, recorded


def test_contact_model_is_an_option_recorded_and_keyed(bar):
    from aas_gym.experiments.config import DatasetConfig
    from sensors import ContactTolerance, GraspState
    from sensors.task import AcousticConfig

    assert DatasetConfig().to_dict()["contact_model"] == "spring_damper"
    assert DatasetConfig(objects=("aluminium_bar",), contact_model="damping").fingerprint() != \
        DatasetConfig(objects=("aluminium_bar",)).fingerprint()
    with pytest.raises(ValueError):
        AcousticConfig(contact_model="glue")
    assert AcousticConfig(contact_model="damping") != AcousticConfig()
    act, mic = Contact([0.04, 0.0125, 0.0], [0, 1, 0], 40.0, 0.8), Contact([0.04, -0.0125, 0.0], [0, -1, 0], 40.0, 0.8)
    ex = sensors.Excitation.by_name("impulse")
    rec = {cm: sensors.simulate_recording(bar, ex, ex.period_s, act, mic, contact_model=cm)
           for cm in ("damping", "spring_damper")}
    assert {cm: r.metadata["contact_model"] for cm, r in rec.items()} == {"damping": "damping",
                                                                         "spring_damper": "spring_damper"}
    assert not np.allclose(rec["damping"].waveform, rec["spring_damper"].waveform)
    # a contact set with other springs is another system (cache keys)
    table = Contact([0.0, 0.0, -0.0125], [0, 0, -1], 5.0, 0.5)
    stiff = Contact([0.0, 0.0, -0.0125], [0, 0, -1], 5.0, 0.5, normal_stiffness_n_per_m=1e8)
    a, b = GraspState(bar, act, mic, (table,)), GraspState(bar, act, mic, (stiff,))
    assert not ContactTolerance().tables_match(a.contact_table(), b.contact_table())
    assert ContactTolerance().tables_match(a.contact_table(), GraspState(bar, act, mic, (table,)).contact_table())
