"""A grasped object touching another (sensors.modal.touching): the modes the synthesis hears are
those of both bodies coupled through the contact, checked against a full FEM of the two bars
joined by the spring (scikit-fem, independent assembly), and stress-tested with a partner
10^4 times heavier (passive, the same response as a dense reference, and the grounded-spring
limit it must approach)."""

from __future__ import annotations


import numpy as np
import pytest

from sensors import Contact, ModalSystem
from sensors.materials import scaled_material
from sensors.modal import TouchingObjects, TouchingPartner, with_material
from sensors.modal.coupled_bodies import CoupledSizeError
from sensors.synthesis.modal_system import contact_modal_model, modal_state_energy

from test_contact_stiffness import BAR, FMAX_HZ, FS, dense_response, full_fem_two_bars, lowest_hz, bar, check_shifts, reference, vertex  # noqa: F401

H = BAR["height_m"]
DOWN, UP = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 1.0])
K_LINK = (1e7, 5e6)        # the contact between the bars [N/m], normal and tangential
K_TABLE = (2e6, 1e6)       # the lower bar on the table
K_PAD = (2e6, 0.0)         # a fingertip pad on the grasped bar


def two_bars(reference, partner_model, contact_x_m=0.05, pad_x_m=-0.03, table_x_m=(-0.08, 0.08), name=None):
    """The grasped bar A resting on bar B (B 25 mm below, frames aligned) at ``contact_x_m``, A
    held by two pads on its sides at ``pad_x_m``, B on the table at two points of its bottom
    face. Returns the pads, the partner B and the springs' vertices for the full FEM."""
    V = reference[2]
    va, pa = vertex(reference, contact_x_m, 2, -1)                       # bottom of A
    vb = int(np.argmin(np.linalg.norm(V - (pa + [0, 0, H]), axis=1)))   # top of B (B frame)
    assert np.allclose(V[vb] - [0, 0, H], pa)
    pads = [vertex(reference, pad_x_m, 1, s) for s in (1, -1)]
    table = [vertex(reference, x, 2, -1) for x in table_x_m]
    pad_contacts = [Contact(p, [0.0, s, 0.0], 5.0, 0.5, *K_PAD) for (_, p), s in zip(pads, (1, -1))]
    link = Contact(pa, DOWN, 5.0, 0.5, *K_LINK, counter_material="aluminium")
    ground = [Contact(p, DOWN, 5.0, 0.5, *K_TABLE) for _, p in table]
    partner = TouchingPartner(partner_model, np.eye(3), [0.0, 0.0, -H], (link,), tuple(ground), name=name)
    springs = {"pads": [(v, 1, *K_PAD) for v, _ in pads], "link": (va, vb), "table": [v for v, _ in table]}
    return pad_contacts, partner, springs


def test_coupled_grasp_matches_full_fem_of_both_bars(bar, reference):
    pads, partner, springs = two_bars(reference, bar)
    true = lowest_hz(*full_fem_two_bars(reference, springs["pads"], springs["table"], [(*springs["link"], K_LINK)], K_TABLE))
    modes = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    free = np.sort(np.concatenate([bar.frequencies_hz, bar.frequencies_hz]))
    check_shifts(free, modes.frequencies_hz, true[true > 1.0])
    # the microphone on A hears B's modes too: without the partner, A alone has fewer modes in band
    alone = contact_modal_model(bar, pads + list(partner.contacts))
    assert modes.n_modes > alone.n_modes


def test_the_coupled_size_is_bounded_with_a_clear_error(bar, reference):
    pads, partner, _ = two_bars(reference, bar)
    with pytest.raises(CoupledSizeError, match=r"about \d+ coordinates.*MAX_COUPLED_COORDINATES.*max_frequency_hz"):
        contact_modal_model(TouchingObjects(bar, [partner], max_coordinates=30), pads)


def test_very_different_bodies_passive_dense_reference_and_grounded_limit(bar, reference):
    """A partner 10^4 times heavier and stiffer (the same frequencies): the grasped bar's
    modes approach those with the contact as a grounded spring; the coupled grasp's system
    is passive and equals the dense continuous-time reference."""
    heavy = with_material(bar, scaled_material(bar.material, modulus_scale=1e4, density_scale=1e4))
    pads, partner, _ = two_bars(reference, heavy)
    group = TouchingObjects(bar, [partner])
    modes = contact_modal_model(group, pads)
    grounded = contact_modal_model(bar, pads + list(partner.contacts))
    # every mode of A held by the grounded contact has a coupled mode within 0.5 % (the heavy
    # partner adds its own modes, heard only faintly through the contact)
    for f in grounded.frequencies_hz[grounded.frequencies_hz < 6000]:
        assert np.min(np.abs(modes.frequencies_hz - f)) <= 5e-3 * f, f
    _, pd = vertex(reference, 0.04, 1, 1)
    _, pm = vertex(reference, 0.04, 1, -1)
    drive, mic = (pd, np.array([0.0, 1.0, 0.0])), (pm, np.array([0.0, -1.0, 0.0]))
    sysm = ModalSystem.build(group, FS, drive[0], drive[1], mic[0], mic[1], pads, keep_all_modes=True)
    assert sysm.modes is modes
    assert np.abs(np.linalg.eigvals(sysm.transition_matrix())).max() <= 1.0 + 1e-12
    u = np.random.default_rng(0).standard_normal(300)
    y = sysm.response(u)
    ref = dense_response(modes, pads, u, drive, mic)
    assert np.max(np.abs(y - ref)) <= 1e-6 * np.max(np.abs(ref))
    # free ring-down from a displaced, moving state: the energy never grows
    x = np.full(2 * sysm.n_modes, 1e-3)
    e = [modal_state_energy(x)]
    for _ in range(50):
        x = sysm.final_state(np.zeros(2), x)
        e.append(modal_state_energy(x))
    assert np.all(np.diff(e) <= 1e-12 * e[0])


def test_state_transfer_keeps_the_partners_energy_and_never_adds(bar, reference):
    """Switching the grasped bar's contacts while it stays on the partner: the partner's motion
    carries over (a switch to the same contacts, rebuilt, keeps the energy exactly), and a
    switch to other contacts never adds energy."""
    from sensors.modal.touching import CoupledGraspModes
    from sensors.synthesis.modal_system import transfer_state

    pads, partner, _ = two_bars(reference, bar)
    group = TouchingObjects(bar, [partner])
    a = CoupledGraspModes(group, pads)
    a_again = CoupledGraspModes(group, pads)
    b = CoupledGraspModes(group, pads[:1])
    x = np.random.default_rng(2).standard_normal(2 * a.n_modes)
    e = modal_state_energy(x)
    assert modal_state_energy(transfer_state(x, a, a_again)) == pytest.approx(e, rel=1e-9)
    xb = transfer_state(x, a, b)
    assert modal_state_energy(xb) <= e * (1 + 1e-12)
    assert modal_state_energy(transfer_state(xb, b, a)) <= modal_state_energy(xb) * (1 + 1e-12)
    # the partner's share is kept: more than the grasped bar's own coordinates would carry
    only_grasped = x.reshape(2, -1)
    T0 = a_again.V.T @ a.V
    assert modal_state_energy(np.concatenate([T0 @ only_grasped[0], T0 @ only_grasped[1]])) < e * (1 - 1e-3)


def test_link_rows_evaluated_together_equal_each_link_alone(bar, reference):
    """The coupled stiffness takes every link's Ritz rows from one evaluation per body; each
    equals the link's difference written out from its two bodies' Ritz bases at its point
    alone (its own point location), bit for bit."""
    pads, partner, _ = two_bars(reference, bar)
    extra = Contact(partner.contacts[0].position_m + [0.004, 0.003, 0.0], DOWN, 3.0, 0.5, *K_LINK,
                    counter_material="aluminium")
    partner = TouchingPartner(partner.model, partner.rotation, partner.translation_m,
                              (*partner.contacts, extra), partner.grounded)
    modes = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    A = modes.assembly
    assert len(A.links) >= 5
    for link, together in zip(A.links, A.link_differences()):
        alone = np.zeros_like(together)
        for side, sign in ((link.body_a, 1.0), (link.body_b, -1.0)):
            if side is not None:
                _, R, t = A.bodies[side]
                point = R.T @ (np.asarray(link.point_m) - t)
                alone[:, A.rows(side)] += sign * R @ A.parts[side].ritz_at(point[None])[0]
        assert np.array_equal(together, alone)
        assert np.array_equal(A.link_difference(link), alone)


def test_a_bar_lying_along_another_merges_its_attachment_points_and_matches_full_fem(bar, reference):
    """Bar A lying along bar B: a link at each of A's 36 bottom-face vertices (108 constrained
    directions on each bar, above MAX_ATTACHMENT_VECTORS: a ValueError before). Each body's
    attachment modes come at merged points, every link still acting at its own point: the
    coupled frequencies against the full FEM of both bars with all 36 links (scikit-fem), each
    shift within 10 % (measured: at most 6.3 % of a shift and 0.6 % of a frequency; with an
    attachment mode at every link, above the limit, 0.01 Hz)."""
    from sensors.modal import static_correction

    V = reference[2]
    bottom = np.flatnonzero(np.isclose(V[:, 2], -H / 2))
    top = [int(np.argmin(np.linalg.norm(V - (V[v] + [0, 0, H]), axis=1))) for v in bottom]
    assert np.allclose(V[top] - [0, 0, H], V[bottom])
    k_link = (K_LINK[0] / 8, K_LINK[1] / 8)      # a face of contacts, each a share of one stiff contact
    links = tuple(Contact(V[v], DOWN, 1.0, 0.5, *k_link, counter_material="aluminium") for v in bottom)
    assert 3 * len(links) > static_correction.MAX_ATTACHMENT_VECTORS
    pad_vertices, pads_at = zip(*[vertex(reference, -0.03, 1, s) for s in (1, -1)])
    pads = [Contact(p, [0.0, s, 0.0], 5.0, 0.5, *K_PAD) for p, s in zip(pads_at, (1, -1))]
    table = [vertex(reference, x, 2, -1) for x in (-0.08, 0.08)]
    ground = tuple(Contact(p, DOWN, 5.0, 0.5, *K_TABLE) for _, p in table)
    partner = TouchingPartner(bar, np.eye(3), [0.0, 0.0, -H], links, ground)
    modes = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    for part in modes.assembly.parts:        # bounded: merged attachment points
        assert part.attachment.size <= static_correction.MAX_ATTACHMENT_VECTORS
    pad_springs = [(v, 1, *K_PAD) for v in pad_vertices]
    true = lowest_hz(*full_fem_two_bars(reference, pad_springs, [v for v, _ in table],
                                        [(va, vb, k_link) for va, vb in zip(bottom, top)], K_TABLE))
    free = np.sort(np.concatenate([bar.frequencies_hz, bar.frequencies_hz]))
    check_shifts(free, modes.frequencies_hz, true[true > 1.0], rtol=0.1)
    band = true[(true > 1.0) & (true < 0.6 * FMAX_HZ)]
    assert np.max(np.abs(modes.frequencies_hz[:band.size] / band - 1.0)) <= 0.01
