"""Bad input raises clear errors; fast paths return the same result as the full path."""

import numpy as np
import pytest

from sensors.modal.contact import Contact
from sensors.modal.damping import modal_damping_matrix
from sensors.synthesis.modal_system import ModalSystem, modal_response
from synthesis_fakes import BoxModel, grasp, lsim_reference


@pytest.fixture(scope="module")
def model():
    return BoxModel(np.linspace(900, 12000, 10), "abs")


def test_contact_validation():
    Contact([0, 0, 0], [0, 0, 1], 1.0, 0.5)
    with pytest.raises(ValueError, match="unit vector"):
        Contact([0, 0, 0], [0, 0, 2], 1.0, 0.5)
    with pytest.raises(ValueError, match="force_n"):
        Contact([0, 0, 0], [0, 0, 1], -1.0, 0.5)
    with pytest.raises(ValueError, match="friction"):
        Contact([0, 0, 0], [0, 0, 1], 1.0, -0.1)
    with pytest.raises(ValueError, match="finite"):
        Contact([0, np.nan, 0], [0, 0, 1], 1.0, 0.5)
    with pytest.raises(ValueError, match="force_n"):
        Contact([0, 0, 0], [0, 0, 1], np.inf, 0.5)
    with pytest.raises(ValueError, match="3-vectors"):
        Contact([0, 0], [0, 0, 1], 1.0, 0.5)
    a = Contact([0.1, 0, 0], [0, 0, 1], 2.0, 0.5)
    assert a == Contact.from_dict(a.to_dict()) and hash(a) == hash(Contact.from_dict(a.to_dict()))
    assert a != Contact([0.1, 0, 0], [0, 0, 1], 2.5, 0.5)


def test_nan_force_raises(model):
    dp, dn, mp, mn = grasp(model)
    u = np.ones(100)
    u[50] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        modal_response(model, u, 44100, dp, dn, mp, mn)


def test_non_unit_drive_normal_raises(model):
    dp, dn, mp, mn = grasp(model)
    with pytest.raises(ValueError, match="unit vector"):
        modal_response(model, np.ones(10), 44100, dp, 2 * dn, mp, mn)


def test_contact_far_off_surface_raises(model):
    dp, dn, mp, mn = grasp(model)
    far = Contact([0.0, 0.05, 0.0], [0, 1, 0], 10.0, 0.5)  # 40 mm above the +y face
    with pytest.raises(ValueError, match="mm from the object surface"):
        modal_damping_matrix(model, [far])
    with pytest.raises(ValueError, match="mm from the object surface"):
        modal_response(model, np.ones(10), 44100, dp, dn, mp, mn, [far])
    with pytest.raises(ValueError, match="drive/mic point"):
        modal_response(model, np.ones(10), 44100, dp + [0, 0.01, 0], dn, mp, mn)
    # the zero-force fast path validates too
    with pytest.raises(ValueError, match="mm from the object surface"):
        modal_response(model, np.zeros(10), 44100, dp, dn, mp, mn, [far])


def test_bad_options_raise(model):
    dp, dn, mp, mn = grasp(model)
    for kw in ({"method": "magic"}, {"output": "pressure"}, {"hold": "cubic"}):
        with pytest.raises(ValueError):
            modal_response(model, np.ones(10), 44100, dp, dn, mp, mn, **kw)
    with pytest.raises(ValueError, match="schedule"):
        modal_response(model, np.ones(10), 44100, dp, dn, mp, mn, [(0.1, [])])


def test_damping_matrix_definition(model):
    """C_m against a direct loop over contacts of the formula (Zheng & James 2011)."""
    dp, dn, mp, mn = grasp(model)
    cs = [Contact(dp, dn, 40.0, 0.3), Contact(mp, mn, 40.0, 1.4), Contact([0.1, 0.0, 0.002], [1, 0, 0], 3.0, 0.0)]
    C = modal_damping_matrix(model, cs)
    w = model.angular_frequencies_rad_s
    ref = np.diag(model.material.alpha + model.material.beta * w**2)
    for c in cs:
        U = model.mode_shapes_at(c.position_m[None])[0]
        W = c.friction * np.eye(3) + (1 - c.friction) * np.outer(c.normal, c.normal)
        ref = ref + model.material.gamma * c.force_n * U.T @ W @ U
    assert np.allclose(C, ref, rtol=1e-12, atol=0)
    assert np.all(np.linalg.eigvalsh(C) >= -1e-12 * np.abs(C).max())


def test_fast_paths_change_nothing(model):
    dp, dn, mp, mn = grasp(model)
    cs = [Contact(dp, dn, 40.0, 0.5), Contact(mp, mn, 40.0, 0.5)]
    assert np.array_equal(modal_response(model, np.zeros(500), 44100, dp, dn, mp, mn, cs), np.zeros(500))
    # every mode is reached and seen here, so nothing is dropped (dropping an unreachable
    # mode is checked in test_unreachable_mode_dropped_exactly)
    sysm = ModalSystem.build(model, 44100, dp, dn, mp, mn, cs)
    assert len(sysm.kept) == len(model.angular_frequencies_rad_s)
    u = np.random.default_rng(1).normal(size=3000)
    y_all = sysm.response(u)
    # modes above a cut-off that is above every mode: identical result
    y_cut = modal_response(model, u, 44100, dp, dn, mp, mn, cs, max_frequency_hz=15000.0)
    assert np.array_equal(y_all, y_cut)


class _Masked(BoxModel):
    """BoxModel whose last mode is zero on the half-space x > 0 (where the grasp is)."""

    def mode_shapes_at(self, points_m):
        U = super().mode_shapes_at(points_m)
        p = np.atleast_2d(points_m)
        U[p[:, 0] > 0, :, -1] = 0.0
        return U


def test_unreachable_mode_dropped_exactly():
    m = _Masked(np.linspace(900, 12000, 10), "abs")
    dp, dn, mp, mn = grasp(m)
    cs = [Contact(dp, dn, 40.0, 0.5), Contact(mp, mn, 40.0, 0.5), Contact([-0.05, 0.01, 0.0], [0, 1, 0], 5.0, 0.5)]
    sysm = ModalSystem.build(m, 44100, dp, dn, mp, mn, cs)
    # the last mode is neither driven nor seen, but the contact at x < 0 couples it to
    # modes that are: it changes the response and must be kept
    assert len(sysm.kept) == 10
    cs2 = cs[:2]
    sysm2 = ModalSystem.build(m, 44100, dp, dn, mp, mn, cs2)
    assert len(sysm2.kept) == 9  # decoupled and unreachable: dropped
    u = np.random.default_rng(2).normal(size=2000)
    for sysm_, cs_ in ((sysm, cs), (sysm2, cs2)):
        ref, _ = lsim_reference(m, modal_damping_matrix(m, cs_), u, 44100, dp, dn, mp, mn)
        assert np.max(np.abs(sysm_.response(u) - ref)) <= 1e-9 * np.max(np.abs(ref))
