"""Contact sets from the unit-load store's node-pair products (``GRAM_PRODUCTS``, Psi never
formed) against the explicit Psi path: the reduced matrices, Psi at points and the state
transfer's Psi_b^T M Psi_a, written out with the assembled K and M (an independent reference
to the store's sums), 1e-9 relative."""

from __future__ import annotations

import numpy as np
import pytest

from sensors import Contact
from sensors._infra.lru import clear_all
from sensors.modal import static_correction
from sensors.modal.spring_modes import modal_transfer, spring_modes
from sensors.modal.static_correction import ContactFlexibility, UnitLoadStore, nodal_at

from test_contact_set_reuse import bar  # noqa: F401  (fixture: the aluminium bar of both files)



def grasp(x_m: float, table_force_n: float):
    return [Contact((x_m, 0.0125, 0.001), (0, 1.0, 0), 20.0, 0.5, 1.0),
            Contact((x_m, -0.0125, 0.001), (0, -1.0, 0), 20.0, 0.5, 1.0),
            Contact((0.097 - x_m, 0.01, -0.0125), (0, 0, -1.0), table_force_n, 0.5, 1.0),
            Contact((-0.097, -0.01, -0.0125), (0, 0, -1.0), table_force_n, 0.5, 1.0)]


def rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def paths(bar, contacts):
    fast = spring_modes(bar, contacts)
    with static_correction.reference_paths(reuse_unit_loads=True):
        reference = spring_modes(bar, contacts)
    return fast, reference


@pytest.mark.parametrize("capacity", [None, 24])
def test_gram_path_equals_the_explicit_psi_path(bar, capacity):
    """A grasp moving along the bar; with room for 24 nodes the store evicts nodes the earlier
    bases use (their rows and transfers are solved again, or fall back to Psi)."""
    clear_all()
    flex = static_correction.contact_flexibility(bar)
    if capacity is not None:
        flex.unit_loads = UnitLoadStore(flex, capacity=capacity)
    K, M = flex.K, flex.M
    previous = None
    for k in range(6):
        contacts = grasp(0.01 + 8e-3 * k, 4.0 + 0.5 * k)
        fast, reference = paths(bar, contacts)
        assert fast.attachment._psi is None                       # nothing n_dof-sized formed
        assert reference.attachment._psi is not None
        # basis-independent: the coupled frequencies of both paths
        assert rel(fast.frequencies_hz, reference.frequencies_hz) < 1e-9
        # the same basis: the implicit matrices against Psi formed and multiplied out with K and M
        pts = np.array([c.position_m for c in contacts] + [[0.03, 0.0, 0.0125]])
        rows = fast.ritz_at(pts)
        psi = fast.attachment.psi
        assert rel(fast.attachment.stiffness, psi.T @ (K @ psi)) < 1e-9
        assert np.allclose(psi.T @ (M @ psi), np.eye(psi.shape[1]), rtol=0, atol=1e-9)
        assert np.abs(fast.attachment.coupling).max() < 1e-9 * np.abs(fast.attachment.stiffness).max()
        P = nodal_at(bar, psi.reshape(-1, 3, psi.shape[1]), pts)
        assert rel(rows[..., -psi.shape[1]:], P) < 1e-9
        if previous is not None:
            prev_psi = previous.attachment.psi
            gram = fast.attachment.mass_product(previous.attachment)
            assert rel(gram, psi.T @ (M @ prev_psi)) < 1e-9
            # the whole state transfer against the explicit projection
            n_rigid, r, _ = fast.split
            T = modal_transfer(previous, fast)
            free = fast.V[:n_rigid + r].T @ previous.V[:n_rigid + r]
            explicit = free + fast.V[n_rigid + r:].T @ (psi.T @ (M @ prev_psi)) @ previous.V[n_rigid + r:]
            assert np.allclose(T, explicit, rtol=0, atol=1e-9)
        previous = spring_modes(bar, contacts)        # a fresh implicit basis for the next transfer
        assert previous is fast
    if capacity is not None:
        assert flex.unit_loads.slots.misses > capacity           # evictions happened
    clear_all()


def test_products_do_not_depend_on_the_order_nodes_came_in(bar):
    """The store's node-pair products are made one way for each pair: two stores filled node
    by node in opposite orders hold bit-for-bit the same products (a node's solve itself can
    differ in the last bits with the nodes solved beside it: the store is an LRU that
    ``clear_all`` empties)."""
    flex = ContactFlexibility(bar)
    nodes = np.array([5, 17, 40, 41, 150, 220])
    one, two = UnitLoadStore(flex, capacity=10), UnitLoadStore(flex, capacity=10)
    for n in nodes:
        one.columns(np.array([n]))
    for n in nodes[::-1]:
        two.columns(np.array([n]))
    cols_one, cols_two = one.columns(nodes), two.columns(nodes)
    assert not np.array_equal(cols_one, cols_two)                  # other slots, same products
    two.products(cols_two[:6], cols_two[6:])                       # some pairs made earlier, one way round
    one.products(cols_one[6:], cols_one[:9])
    assert np.array_equal(one.products(cols_one, cols_one), two.products(cols_two, cols_two))
    assert np.array_equal(one.relief_gram[cols_one], two.relief_gram[cols_two])
