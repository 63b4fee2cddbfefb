"""Attachment modes from kept unit-load solves (``sensors.modal.static_correction``) against
the direct solve of each contact set's loads and against an independent sparse solve.

The reuse is exact up to rounding (the same span, summed in another order): the tolerances
asserted are 1e-9 on the span, 1e-8 relative on the reduced stiffness's eigenvalues (its
K-free form rounds differently) and 1e-9 on the coupled frequencies.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg

from sensors import Contact, ModalModel
from sensors.modal import static_correction
from sensors.modal.spring_modes import spring_modes
from sensors.modal.static_correction import ContactFlexibility

BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


@pytest.fixture(scope="module")
def flex(bar):
    return ContactFlexibility(bar)


def grasp_contacts(rng, n_table=4):
    """Points and unit directions of a grasp-like contact set: two pads on the side faces at
    a random position along the bar, the bottom corners on the table; normal and two tangents
    at each point."""
    x = rng.uniform(-0.06, 0.06)
    z = rng.uniform(-0.005, 0.005)
    pts = [[x, 0.0125, z], [x, -0.0125, z]]
    normals = [[0, 1.0, 0], [0, -1.0, 0]]
    for sx, sy in [(1, 1), (1, -1), (-1, 1), (-1, -1)][:n_table]:
        pts.append([0.1 * sx, 0.0125 * sy, -0.0125])
        normals.append([0, 0, -1.0])
    return with_tangents(pts, normals)


def with_tangents(pts, normals):
    """Each point three times with its unit normal and two unit tangents: (points, directions)."""
    points, dirs = [], []
    for p, n in zip(pts, normals):
        n = np.asarray(n, float)
        t1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        t1 /= np.linalg.norm(t1)
        for d in (n, t1, np.cross(n, t1)):
            points.append(p)
            dirs.append(d)
    return np.array(points, float), np.array(dirs, float)


def span_residual(flex, A, B):
    """Largest M-norm of B's columns outside span(A) (A M-orthonormal), relative to B's."""
    res = B - A @ (A.T @ (flex.M @ B))
    num = np.sum(res * (flex.M @ res), axis=0)
    den = np.sum(B * (flex.M @ B), axis=0)
    return float(np.sqrt(np.max(num / den)))


def test_reuse_matches_direct_solve(flex):
    rng = np.random.default_rng(0)
    for _ in range(4):
        pts, dirs = grasp_contacts(rng)
        P0, K0, C0 = flex.attachment_modes(pts, dirs, reuse_unit_loads=False)
        P1, K1, C1 = flex.attachment_modes(pts, dirs, reuse_unit_loads=True)
        assert P0.shape == P1.shape
        # M-orthonormal, M-orthogonal to the rigid-body and elastic modes
        assert np.allclose(P1.T @ (flex.M @ P1), np.eye(P1.shape[1]), atol=1e-9)
        assert np.abs(flex.MR.T @ P1).max() < 1e-9 and np.abs(flex.MU.T @ P1).max() < 1e-9
        assert span_residual(flex, P0, P1) < 1e-9 and span_residual(flex, P1, P0) < 1e-9
        e0, e1 = np.linalg.eigvalsh(K0), np.linalg.eigvalsh(K1)
        assert np.max(np.abs(e1 - e0) / np.abs(e0)) < 1e-8


def test_unit_loads_against_an_independent_sparse_solve(bar, flex):
    """The attachment span from scipy's own sparse LU of K + sigma M (not the model's
    factorization), inertia relief and projections written out here."""
    rng = np.random.default_rng(1)
    pts, dirs = grasp_contacts(rng, n_table=1)
    P1, _, _ = flex.attachment_modes(pts, dirs, reuse_unit_loads=True)
    # the consistent loads by the element shape functions (sensors.fem.assembly)
    from sensors.fem.assembly import shape_functions

    tet, bary = bar.locator.locate(pts)
    N = shape_functions(bary, bar.element)
    F = np.zeros((flex.n_dof, len(pts)))
    for c, (nodes, w) in enumerate(zip(bar.elements[tet], N)):
        for j in range(3):
            F[3 * nodes + j, c] += w * dirs[c, j]
    F -= flex.MR @ (flex.R.T @ F)
    sigma = 1e-3 * float(bar.eigenvalues[0])
    X = scipy.sparse.linalg.splu((flex.K + sigma * flex.M).tocsc()).solve(F)
    for _ in range(2):
        X -= flex.R @ (flex.MR.T @ X)
        X -= flex.U @ (flex.MU.T @ X)
    assert span_residual(flex, P1, X) < 1e-8


def test_kept_solves_are_reused(bar):
    flex = ContactFlexibility(bar)
    rng = np.random.default_rng(2)
    pts, dirs = grasp_contacts(rng)
    first = flex.attachment_modes(pts, dirs)
    kept = len(flex.unit_loads.slots)
    assert kept > 0
    moved = pts.copy()
    moved[:6, 0] += 1e-6                               # the pads 1 um along the bar: the same elements
    again = flex.attachment_modes(moved, dirs)
    assert len(flex.unit_loads.slots) == kept and flex.unit_loads.slots.misses == kept
    direct = flex.attachment_modes(moved, dirs, reuse_unit_loads=False)
    assert np.max(np.abs(np.linalg.eigvalsh(again[1]) / np.linalg.eigvalsh(direct[1]) - 1)) < 1e-8
    assert first[0].shape == again[0].shape


def test_spring_modes_fast_and_reference_paths(bar):
    """The coupled frequencies of a grasp through both paths (the switch the benchmark uses)."""
    rng = np.random.default_rng(3)
    contacts = [Contact(p, n, 20.0, 0.5) for p, n in
                [([0.03, 0.0125, 0.0], [0, 1.0, 0]), ([0.03, -0.0125, 0.0], [0, -1.0, 0]),
                 ([0.1, 0.0125, -0.0125], [0, 0, -1.0]), ([-0.1, -0.0125, -0.0125], [0, 0, -1.0])]]
    contacts[0] = Contact(contacts[0].position_m + [rng.uniform(0, 1e-3), 0, 0], contacts[0].normal, 20.0, 0.5)
    fast = spring_modes(bar, contacts)
    with static_correction.reference_paths(gram_products=True):
        reference = spring_modes(bar, contacts)
    assert reference is not fast
    assert fast.frequencies_hz.shape == reference.frequencies_hz.shape
    assert np.max(np.abs(fast.frequencies_hz / reference.frequencies_hz - 1)) < 1e-9


def test_evicted_solves_are_solved_again_right(bar):
    """Room for 20 nodes: later contact sets (14-16 distinct nodes each, 36 in all) evict
    earlier nodes and take their slots; a set of more nodes than there is room for is solved
    directly."""
    from sensors.modal.static_correction import UnitLoadStore

    flex = ContactFlexibility(bar)
    flex.unit_loads = UnitLoadStore(flex, capacity=20)
    rng = np.random.default_rng(4)
    for _ in range(6):
        pts, dirs = grasp_contacts(rng)
        fast = flex.attachment_modes(pts, dirs)
        direct = flex.attachment_modes(pts, dirs, reuse_unit_loads=False)
        assert span_residual(flex, direct[0], fast[0]) < 1e-9
        assert np.max(np.abs(np.linalg.eigvalsh(fast[1]) / np.linalg.eigvalsh(direct[1]) - 1)) < 1e-8
    assert len(flex.unit_loads.slots) == 20 and flex.unit_loads.slots.misses > 20
    flex.unit_loads = UnitLoadStore(flex, capacity=8)
    pts, dirs = grasp_contacts(rng)
    fast, direct = flex.attachment_modes(pts, dirs), flex.attachment_modes(pts, dirs, reuse_unit_loads=False)
    assert len(flex.unit_loads.slots) == 0 and span_residual(flex, direct[0], fast[0]) < 1e-9


def test_slots_stay_distinct_and_hold_their_nodes_under_eviction_and_clearing(bar):
    """The store's slot bookkeeping: after evictions and after its LRU is emptied (as
    ``clear_all`` does), every kept node has its own slot, and that slot's columns are the
    node's own unit-load solves (an independent solve of the node's three unit loads)."""
    from sensors.modal.static_correction import UnitLoadStore

    flex = ContactFlexibility(bar)
    store = flex.unit_loads = UnitLoadStore(flex, capacity=20)
    rng = np.random.default_rng(5)

    def check():
        slots = list(store.slots.values())
        assert len(set(slots)) == len(slots)
        held = [(int(store.slot_node[k]), k) for k in slots]
        assert all(n in store.slots for n, _ in held)
        for n, k in held[:3]:
            F = np.zeros((flex.n_dof, 3))
            F[3 * n + np.arange(3), np.arange(3)] = 1.0
            Y = flex._projected(scipy.sparse.linalg.spsolve((flex.K + flex.sigma * flex.M).tocsc(), F).reshape(flex.n_dof, 3))
            assert np.max(np.abs(store.Y[:, 3 * k:3 * k + 3] - Y)) < 1e-9 * np.max(np.abs(Y))

    for _ in range(4):
        flex.attachment_modes(*grasp_contacts(rng))
    assert store.slots.misses > 20
    check()
    store.slots.clear()
    flex.attachment_modes(*grasp_contacts(rng))
    assert sorted(store.slots.values()) == list(range(len(store.slots)))   # lowest slots first
    check()


def test_implicit_rows_at_nodes_equal_the_formed_vectors(bar):
    """``AttachmentBasis.nodal`` of an implicit basis (rows made per node, kept) equals the
    rows of Psi formed explicitly, in any order and with repeats."""
    flex = ContactFlexibility(bar)
    pts, dirs = grasp_contacts(np.random.default_rng(6))
    basis = flex.attachment_basis(pts, dirs)
    assert basis._psi is None
    nodes_a = np.array([5, 17, 3, 17, 40])
    nodes_b = np.array([40, 2, 5, 99, 2])
    rows_a, rows_b, empty = basis.nodal(nodes_a), basis.nodal(nodes_b), basis.nodal(np.zeros(0, int))
    psi = basis.psi.reshape(-1, 3, basis.size)
    scale = np.max(np.abs(psi))
    assert np.max(np.abs(rows_a - psi[nodes_a])) < 1e-12 * scale
    assert np.max(np.abs(rows_b - psi[nodes_b])) < 1e-12 * scale
    assert empty.shape == (0, 3, basis.size)
