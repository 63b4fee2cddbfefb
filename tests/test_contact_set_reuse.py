"""What a new contact set reuses of earlier ones is exact: kept point locations, the kept
M Psi of a state transfer and the unit-load store against their direct computations
(independent of the caches: a fresh locator, an explicit sparse product, the direct solve)."""

from __future__ import annotations

import numpy as np
import pytest

from sensors import Contact, ModalModel
from sensors._infra.lru import clear_all
from sensors.mesh.locator import TetLocator
from sensors.modal import static_correction
from sensors.modal.spring_modes import modal_transfer, spring_modes

BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


def grasp(x_m: float, table_force_n: float):
    """Pads on the side faces at ``x_m``, two bottom corners on the table."""
    return [Contact((x_m, 0.0125, 0.0), (0, 1.0, 0), 20.0, 0.5, 1.0),
            Contact((x_m, -0.0125, 0.0), (0, -1.0, 0), 20.0, 0.5, 1.0),
            Contact((0.097, 0.01, -0.0125), (0, 0, -1.0), table_force_n, 0.5, 1.0),
            Contact((-0.097, -0.01, -0.0125), (0, 0, -1.0), table_force_n, 0.5, 1.0)]


def test_kept_locations_equal_a_fresh_locator(bar):
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (7, 3)) * [0.11, 0.015, 0.015]        # inside and outside the bar
    kept = bar.locator
    first = kept.locate(pts)
    again = kept.locate(pts.copy())
    fresh = TetLocator(bar.nodes_m, bar.elements).locate(pts)
    for a, b, c in zip(first, again, fresh):
        assert a is b                                                 # the same answer, kept
        assert np.array_equal(a, c)
        assert not a.flags.writeable                                  # nobody edits a kept answer
    d_kept = kept.closest_surface(pts)[2]
    d_fresh = TetLocator(bar.nodes_m, bar.elements).closest_surface(pts)[2]
    assert np.array_equal(d_kept, d_fresh)


def test_transfer_with_kept_mass_psi_equals_the_explicit_projection(bar):
    clear_all()
    a, b = spring_modes(bar, grasp(0.01, 4.0)), spring_modes(bar, grasp(0.0102, 6.0))
    T = modal_transfer(a, b)
    # Phi_b^T M Phi_a written out from the Ritz bases (free part: [R, U] orthonormal)
    M = a.geometry.M
    n_rigid, r, _ = a.split
    free = b.V[:n_rigid + r].T @ a.V[:n_rigid + r]
    psi = b.V[n_rigid + r:].T @ (b.psi.T @ (M @ a.psi)) @ a.V[n_rigid + r:]
    assert np.allclose(T, free + psi, rtol=0, atol=1e-12)
    assert a.mass_psi() is a.mass_psi()                               # made once


def test_store_path_equals_the_direct_solve_across_moving_contact_sets(bar):
    """A grasp creeping along the bar (the stream's new contact sets): coupled frequencies
    from the kept unit-load store against the direct solve of each set, 1e-9 relative."""
    clear_all()
    for k in range(5):
        contacts = grasp(0.01 + 2e-4 * k, 4.0 + 0.5 * k)
        fast = spring_modes(bar, contacts)
        with static_correction.reference_paths(gram_products=True):
            reference = spring_modes(bar, contacts)
        assert reference is not fast and fast.frequencies_hz.shape == reference.frequencies_hz.shape
        assert np.max(np.abs(fast.frequencies_hz / reference.frequencies_hz - 1)) < 1e-9
        # Psi^T K U is rounding (Psi is M-orthogonal to U): both paths far below the stiffness
        scale = np.abs(reference.attachment.stiffness).max()
        assert np.abs(fast.attachment.coupling).max() < 1e-9 * scale
        assert np.abs(reference.attachment.coupling).max() < 1e-9 * scale


def test_kept_transfers_equal_the_explicit_projection_back_and_forth(bar):
    """A grasp switching back and forth between two contact sets: every state transfer (the
    kept T after the first) equals the explicit Phi_to^T M Phi_from from the Ritz bases."""
    from sensors.synthesis.modal_system import transfer_state

    clear_all()
    a, b = spring_modes(bar, grasp(0.01, 4.0)), spring_modes(bar, grasp(0.0102, 6.0))
    M = a.geometry.M

    def explicit(fr, to):
        n_rigid, r, _ = fr.split
        return (to.V[:n_rigid + r].T @ fr.V[:n_rigid + r]
                + to.V[n_rigid + r:].T @ (to.psi.T @ (M @ fr.psi)) @ fr.V[n_rigid + r:])

    x = np.random.default_rng(1).standard_normal(2 * a.n_modes)
    first = None
    for _ in range(3):
        y = transfer_state(x, a, b)
        T = explicit(a, b)
        assert np.allclose(y, np.concatenate([T @ x[:a.n_modes], T @ x[a.n_modes:]]), rtol=0, atol=1e-12)
        first = y if first is None else first
        assert np.array_equal(y, first)                              # the kept T: the same bits
        back = transfer_state(y, b, a)
        Tb = explicit(b, a)
        assert np.allclose(back, np.concatenate([Tb @ y[:b.n_modes], Tb @ y[b.n_modes:]]), rtol=0, atol=1e-12)
