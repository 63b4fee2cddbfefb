"""The unit-load store's cheaper projection (``SINGLE_ELASTIC_PROJECTION``: the rigid part
removed twice, the elastic part once) against the reference (both twice) and against an
independent solve, and a contact set located once (its springs' repeated points).

Tolerances: the two projections of one solve within 1e-12 of the reference's largest entry
(5e-14 measured on the paper's objects), the store's solves within 1e-9 of SciPy's and M-orthogonal to the kept modes to 1e-12 of their size; the coupled
frequencies and Ritz rows of a grasp within 1e-9 relative (the spring modes' own tolerance
against the direct solve, ``tests/test_unit_load_reuse.py``).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg

from sensors import Contact, ModalModel
from sensors._infra.lru import clear_all
from sensors.modal import static_correction
from sensors.modal.spring_modes import spring_modes
from sensors.modal.static_correction import ContactFlexibility


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(length_m=0.2, width_m=0.025, height_m=0.025, material="aluminium", resolution=0.008,
                          cache=False, max_frequency_hz=12000.0)


def grasp(x_m: float):
    return [Contact((x_m, 0.0125, 0.001), (0, 1.0, 0), 20.0, 0.5, 1.0),
            Contact((x_m, -0.0125, 0.001), (0, -1.0, 0), 20.0, 0.5, 1.0),
            Contact((0.097 - x_m, 0.01, -0.0125), (0, 0, -1.0), 3.0, 0.5, 1.0),
            Contact((-0.097, -0.01, -0.0125), (0, 0, -1.0), 3.0, 0.5, 1.0)]


def rel(a, b):
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_single_elastic_projection_equals_the_two_pass_one_and_an_independent_solve(bar, monkeypatch):
    flex = ContactFlexibility(bar)
    nodes = np.array([3, 57, 120, 211])
    rows = (3 * nodes[:, None] + np.arange(3)).ravel()
    F = np.zeros((flex.n_dof, rows.size))
    F[rows, np.arange(rows.size)] = 1.0
    # independent of the model's factorization: SciPy's sparse LU of K + sigma M
    raw = scipy.sparse.linalg.spsolve((flex.K + flex.sigma * flex.M).tocsc(), F)
    monkeypatch.setattr(static_correction, "SINGLE_ELASTIC_PROJECTION", False)
    reference = flex.unit_load_projected(raw.copy())
    monkeypatch.setattr(static_correction, "SINGLE_ELASTIC_PROJECTION", True)
    fast = flex.unit_load_projected(raw.copy())
    assert rel(fast, reference) < 1e-12
    scale = np.abs(fast).max()
    assert np.abs(flex.MU.T @ fast).max() < 1e-12 * scale
    assert np.abs(flex.MR.T @ fast).max() < 1e-12 * scale
    # the store's kept columns are made this way (with the model's own factorization: 1e-9 to
    # SciPy's, as in tests/test_unit_load_reuse.py; 1.1e-10 measured)
    store = flex.unit_loads
    cols = store.columns(nodes)
    assert rel(store.Y[:, cols], reference) < 1e-9


def test_spring_modes_with_either_projection_agree(bar, monkeypatch):
    out = {}
    for single in (False, True):
        clear_all()
        monkeypatch.setattr(static_correction, "SINGLE_ELASTIC_PROJECTION", single)
        out[single] = [spring_modes(bar, grasp(x)) for x in (0.0, 0.01, 0.03)]
    pts = np.array([[0.02, 0.0125, 0.0], [-0.05, 0.0, 0.0125]])
    for ref, fast in zip(out[False], out[True]):
        assert ref is not fast
        assert rel(fast.frequencies_hz, ref.frequencies_hz) < 1e-9
        assert rel(fast.ritz_at(pts), ref.ritz_at(pts)) < 1e-9
    clear_all()


def test_a_contact_set_islocated_once_per_point(bar):
    """Repeated runs of rows (a spring's three directions) located once give what locating
    every row gives, bit for bit, and the springs' own points are then kept in the locator."""
    clear_all()
    flex = ContactFlexibility(bar)
    springs = np.array([[0.01, 0.0125, 0.001], [0.01, -0.0125, 0.001], [-0.097, -0.01, -0.0125]])
    pts = np.repeat(springs, [3, 1, 3], axis=0)
    from sensors.mesh.locator import TetLocator

    fresh = TetLocator(bar.nodes_m, bar.elements)
    tet, bary = static_correction.located_once(bar.locator, pts)
    every_tet, every_bary = fresh.locate(pts)
    assert np.array_equal(tet, every_tet) and np.array_equal(bary, every_bary)
    hits = bar.locator._answers.hits
    bar.locator.locate(springs.copy())
    assert bar.locator._answers.hits == hits + 1
    # a single point and distinct points pass through unchanged
    assert np.array_equal(static_correction.located_once(bar.locator, springs)[0], fresh.locate(springs)[0])
    assert np.array_equal(static_correction.located_once(bar.locator, springs[:1])[0], fresh.locate(springs[:1])[0])
    del flex
