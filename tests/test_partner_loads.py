"""A passive load at a contact between the grasped bar and the bar it rests on acts on both
(sensors.synthesis.partner_loads): checked against the full FEM of the two bars joined by the
contact spring (scikit-fem, independent assembly, a direct solve per frequency with no modal
basis), and unchanged where there is no partner."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg

from sensors import Contact
from sensors.modal import TouchingObjects, TouchingPartner
from sensors.synthesis.modal_system import contact_modal_model
from sensors.synthesis.passive import ContactLoads, LoadRead, project_reads

from test_contact_stiffness import bar, reference, vertex  # noqa: F401  (fixtures)
from test_contact_stiffness import full_fem_two_bars
from test_touching_objects import K_LINK, K_TABLE
from test_touching_objects import two_bars as touching_two_bars

DOWN = np.array([0.0, 0.0, -1.0])

ETA = 0.02                                    # structural loss factor of both models: finite peaks
FORCE_N = np.array([0.3, -0.2, 1.0])          # on the grasped bar A at its contact with B (B pushes up)
FREQS_HZ = np.linspace(100.0, 5000.0, 150)


def two_bars(reference, partner_model, name="plinth"):
    """The two bars of test_touching_objects, A resting on B at x = 40 mm and held at x = -50 mm,
    B named (its loads are a partner's)."""
    return touching_two_bars(reference, partner_model, 0.04, -0.05, (-0.07, 0.09), name=name)


def _full_response(reference, springs, mic_vertex, mic_normal, on_partner: bool) -> np.ndarray:
    """Complex displacement at A's mic vertex along ``mic_normal`` per newton pattern
    ``FORCE_N`` at A's contact vertex (and -FORCE_N at B's, ``on_partner``): the full FEM of
    both bars with the pads, the link and the table as springs, K (1 + i eta) - w^2 M."""
    dofs = reference[3]
    n = reference[0].shape[0]
    va, vb = springs["link"]
    K2, M2 = full_fem_two_bars(reference, springs["pads"], springs["table"], [(va, vb, K_LINK)], K_TABLE)
    f = np.zeros(2 * n, complex)
    f[dofs[:, va]] += FORCE_N
    if on_partner:
        f[n + dofs[:, vb]] -= FORCE_N
    out = []
    for hz in FREQS_HZ:
        u = scipy.sparse.linalg.spsolve((1 + 1j * ETA) * K2 - (2 * np.pi * hz) ** 2 * M2, f)
        out.append(mic_normal @ u[dofs[:, mic_vertex]])
    return np.array(out)


def _modal_response(modes, loads, mic_point, mic_normal) -> np.ndarray:
    """The same by modal superposition of the coupled modes with the passive model's modal load."""
    p = LoadRead(loads).modal(modes)[0]
    o = mic_normal @ np.asarray(modes.mode_shapes_at(mic_point[None]), float)[0]
    w2 = np.asarray(modes.angular_frequencies_rad_s, float) ** 2
    return np.array([np.sum(o * p / ((1 + 1j * ETA) * w2 - (2 * np.pi * hz) ** 2)) for hz in FREQS_HZ])


def _rel_error(a, ref):
    return float(np.linalg.norm(a - ref) / np.linalg.norm(ref))


def test_a_partner_load_acts_on_both_bars_as_the_full_fem_says(bar, reference):
    pads, partner, springs = two_bars(reference, bar)
    modes = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    mv, mic = vertex(reference, 0.06, 2, +1)                  # top face of A
    up = np.array([0.0, 0.0, 1.0])
    link = partner.contacts[0]
    pair = ContactLoads([link.position_m], [link.normal], [FORCE_N], bodies=["plinth"])
    alone = ContactLoads([link.position_m], [link.normal], [FORCE_N])               # no body named
    ref_pair = _full_response(reference, springs, mv, up, on_partner=True)
    ref_alone = _full_response(reference, springs, mv, up, on_partner=False)
    got_pair = _modal_response(modes, pair, mic, up)
    got_alone = _modal_response(modes, alone, mic, up)
    e_pair, e_alone = _rel_error(got_pair, ref_pair), _rel_error(got_alone, ref_alone)
    print(f"modal vs full FEM, 100-5000 Hz: pair {e_pair:.2e}, A alone {e_alone:.2e}; "
          f"pair vs A alone {_rel_error(ref_alone, ref_pair):.2f}")
    assert e_pair < 1e-3 and e_alone < 1e-3
    # and the reaction matters: a load on A alone is another response
    assert _rel_error(got_alone, ref_pair) > 0.2


def test_nothing_changes_without_a_partner(bar, reference):
    """A load named after a body the grasp is not coupled to, on the coupled modes, and any load
    on modes without partners: the grasped object's own shapes, bit for bit."""
    pads, partner, _ = two_bars(reference, bar)
    coupled = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    grounded = contact_modal_model(bar, pads + list(partner.contacts))
    rng = np.random.default_rng(3)
    pts = np.array([c.position_m for c in partner.contacts] + [p.position_m for p in pads])
    nrm = np.array([c.normal for c in partner.contacts] + [p.normal for p in pads])
    F = rng.standard_normal(pts.shape)
    for modes, bodies in ((coupled, ["table", "finger", "finger"]), (grounded, ["plinth"] * 3), (bar, ["plinth"] * 3)):
        got = LoadRead(ContactLoads(pts, nrm, F, bodies=bodies)).modal(modes)[0]
        U = np.asarray(modes.mode_shapes_at(pts), float)
        np.testing.assert_array_equal(got, np.einsum("nd,ndr->r", F, U))
    with pytest.raises(ValueError, match="body names"):
        ContactLoads(pts, nrm, F, bodies=["plinth"])


def test_reads_projected_together_equal_each_projected_alone(bar, reference):
    """project_reads (the points of several reads through one load_shapes call, as a stream
    does at a new contact set) equals projecting each read by itself, to 1e-12 relative, on the
    coupled modes with partner, impact and sliding loads."""
    pads, partner, _ = two_bars(reference, bar)
    modes = contact_modal_model(TouchingObjects(bar, [partner]), pads)
    rng = np.random.default_rng(5)
    pts = np.array([c.position_m for c in partner.contacts] + [p.position_m for p in pads])
    nrm = np.array([c.normal for c in partner.contacts] + [p.normal for p in pads])
    reads = []
    for k, bodies in enumerate((["plinth", "finger", "finger"], ["table", "finger", "finger"], ["plinth"] * 3)):
        F = rng.standard_normal(pts.shape) + 2.0 * nrm
        loads = ContactLoads(pts[k % 2:], nrm[k % 2:], F[k % 2:], sliding=[True] * (3 - k % 2),
                             impact=[k == 1] * (3 - k % 2), bodies=bodies[k % 2:])
        reads.append(LoadRead(loads, np.random.default_rng(k), roughness=0.1))
    alone = [LoadRead(r.loads) for r in reads]
    for a, r in zip(alone, reads):
        a.slip_n = r.slip_n                                    # the same roughness draw
    project_reads(reads + [None, LoadRead(None)], modes)
    for a, r in zip(alone, reads):
        for got, ref in zip(r.modal(modes), a.modal(modes)):
            assert np.any(ref) or np.array_equal(got, ref)
            assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(ref)) + 0.0
