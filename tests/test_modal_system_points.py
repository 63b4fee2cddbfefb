"""One surface check and one mode-shape evaluation per contact system
(``sensors.synthesis.modal_system.ONE_POINT_PASS``, ``sensors.modal.spring_modes.REUSE_SPRING_ROWS``).

A point's distance to the surface and its mode shapes do not depend on the other points asked
with it, so the fast path gives the same bytes as the reference path (a check and a shape
evaluation per consumer).  Both are held against an independent transfer function: the
dense state matrix of the reference path's shapes and damping, solved directly at the feature
frequencies (no eigen-decomposition)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from sensors._infra.lru import clear_all

from sensors import Contact, ModalModel, ModalSystem
from sensors.modal.damping import OffSurfaceError, modal_damping_matrix
from sensors.synthesis import modal_system
from sensors.synthesis.modal_system import contact_modal_model, modal_state_matrix

import sensors.modal.spring_modes  # noqa: F401  (the module, not the function sensors.modal exports)

spring_module = sys.modules["sensors.modal.spring_modes"]
BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)
FS = 44100
FEATURES_HZ = np.arange(3000.0, 10000.0, 50.0)


@pytest.fixture(scope="module")
def bar():
    return ModalModel.bar(**BAR, material="aluminium", resolution=0.008, cache=False, max_frequency_hz=12000.0)


def grasp(x=0.021):
    """Pads on the side faces (drive and mic points), two table contacts 1 mm apart (one
    merged spring), a far table contact, and one without force (no spring, no damping)."""
    h = 0.0125
    return [Contact([x, h, 0.001], [0, 1.0, 0], 8.0, 0.6),
            Contact([x, -h, 0.001], [0, -1.0, 0], 8.0, 0.6),
            Contact([-0.09, 0.004, -h], [0, 0, -1.0], 0.9, 0.4),
            Contact([-0.089, 0.004, -h], [0, 0, -1.0], 0.7, 0.4),
            Contact([0.09, -0.004, -h], [0, 0, -1.0], 1.1, 0.4),
            Contact([0.05, 0.0, -h], [0, 0, -1.0], 0.0, 0.4)]


@pytest.fixture
def paths(monkeypatch):
    def use(fast: bool):
        monkeypatch.setattr(modal_system, "ONE_POINT_PASS", fast)
        monkeypatch.setattr(spring_module, "REUSE_SPRING_ROWS", fast)
        clear_all()
    return use


def build(bar, contacts, **kw):
    c = contacts
    return ModalSystem.build(bar, FS, c[0].position_m, c[0].normal, c[1].position_m, c[1].normal, c, **kw)


def parts_bytes(system):
    return [np.concatenate([np.atleast_1d(x).ravel() for x in (p.lam, p.g, p.co, p.G0, p.G1)]).tobytes()
            for p in system.parts]


@pytest.mark.parametrize("method", ["exact", "diagonal"])
def test_one_point_pass_gives_the_reference_bytes(bar, paths, method):
    contacts = grasp()
    paths(False)
    ref = build(bar, contacts, method=method)
    paths(True)
    fast = build(bar, contacts, method=method)
    assert len(ref.modes.springs) == 4              # the two close table contacts merged
    assert np.array_equal(ref.kept, fast.kept)
    assert parts_bytes(fast) == parts_bytes(ref)
    assert np.array_equal(fast.frequency_response(FEATURES_HZ), ref.frequency_response(FEATURES_HZ))


def test_spring_rows_are_the_rows_evaluated_anew(bar, paths):
    paths(True)
    modes = contact_modal_model(bar, grasp())
    pts = np.array([p for p, _, _, _ in modes.springs])
    others = np.array([[0.0, 0.0125, 0.0], pts[1]])            # a new point and a spring point
    ask = np.concatenate([pts[::-1], others])
    kept = modes.ritz_at(ask)
    spring_module.REUSE_SPRING_ROWS = False
    try:
        anew = modes.ritz_at(ask)
    finally:
        spring_module.REUSE_SPRING_ROWS = True
    assert np.array_equal(kept, anew)


def test_against_the_dense_transfer_function(bar, paths):
    """The fast system's transfer function at the feature frequencies against C (j w - A)^-1 B
    of the dense state matrix, from shapes and damping the reference path evaluates per
    consumer (``modal_damping_matrix``, ``mode_shapes_at``): 1e-9 of its largest value."""
    contacts = grasp(-0.03)
    paths(True)
    fast = build(bar, contacts, max_frequency_hz=FS / 2)
    paths(False)
    modes = contact_modal_model(bar, contacts)
    w = np.asarray(modes.angular_frequencies_rad_s)
    kept = np.flatnonzero(w < 2 * np.pi * FS / 2)
    C = modal_damping_matrix(modes, contacts)[np.ix_(kept, kept)]
    U = modes.mode_shapes_at(np.array([contacts[0].position_m, contacts[1].position_m]))[:, :, kept]
    b, o = -contacts[0].normal @ U[0], contacts[1].normal @ U[1]
    A = modal_state_matrix(w[kept], C)
    r = kept.size
    B = np.concatenate([np.zeros(r), b])
    Cout = np.concatenate([o / w[kept], np.zeros(r)])
    H = np.array([Cout @ np.linalg.solve(2j * np.pi * f * np.eye(2 * r) - A, B) for f in FEATURES_HZ])
    got = fast.frequency_response(FEATURES_HZ)
    assert np.abs(got - H).max() <= 1e-9 * np.abs(H).max()


@pytest.mark.parametrize("fast", [False, True])
def test_off_surface_points_raise_as_before(bar, paths, fast):
    paths(fast)
    contacts = grasp()
    off = Contact([0.0, 0.0, -0.03], [0, 0, -1.0], 1.0, 0.4)       # 17.5 mm below the bar
    with pytest.raises(OffSurfaceError, match="^contact at"):
        build(bar, contacts + [off])
    c = contacts
    with pytest.raises(OffSurfaceError, match="^drive/mic point at"):   # checked first, as before
        ModalSystem.build(bar, FS, [0.0, 0.0, 0.03], c[0].normal, c[1].position_m, c[1].normal, c + [off])
