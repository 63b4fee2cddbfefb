"""A randomized material seen through the nominal model (``sensors.with_material``) against a
model built in that material: the envs' per-episode material never needs a new FEM solve.

Scaling Young's modulus by a and the density by b scales K by a and M by b: the eigenvectors
stay, frequencies scale by sqrt(a / b), mass-normalised shapes by 1 / sqrt(b) and the static
flexibility (every attachment mode's unit-load solve) by 1 / a.  The envs' randomization draws
exactly these (``DomainRandomization.modulus_rel``, ``density_rel``, ``damping_rel``; Poisson's
ratio is never randomized), and the grasp's contact-spring modes come from the nominal model's
kept flexibility (``sensors.modal.spring_modes.flexible_base``).  The reference here is an
independent computation: the FEM model assembled and solved in the scaled material, its own
factorization for the attachment modes.
"""

import dataclasses

import numpy as np
import pytest

from sensors import Excitation, ModalModel
from sensors.materials import scaled_material
from sensors.modal import Contact, with_material
from sensors.modal import static_correction
from sensors.modal.spring_modes import spring_modes
from sensors.synthesis import FingertipModel, simulate_features

DIMS_M = (0.12, 0.02, 0.012)          # not square across: no repeated bending pairs
BUILD = dict(element="p2", element_size_m=0.006, cache=False, progress=False)
MAX_FREQUENCY_HZ = 30_000.0
SCALES = dict(damping_scale=1.04, modulus_scale=1.018, density_scale=0.992)   # within the envs' defaults


@pytest.fixture(scope="module")
def models():
    """(nominal model, its view in the scaled material, the model built in that material)."""
    base = ModalModel.bar(*DIMS_M, "aluminium", max_frequency_hz=MAX_FREQUENCY_HZ, **BUILD)
    material = scaled_material(base.material, **SCALES)
    view = with_material(base, material)
    # the same modes: the direct build's band reaches as far up as the view's
    direct = ModalModel.bar(*DIMS_M, material, max_frequency_hz=MAX_FREQUENCY_HZ * view.frequency_scale, **BUILD)
    assert direct.n_modes == view.n_modes == base.n_modes
    return base, view, direct


def grasp_contacts(x_m=0.025):
    """A 40 N pad grasp across the bar's width at ``x_m``, and the bar on a table (two
    contacts under it, Hertz springs from the force)."""
    w, h = DIMS_M[1] / 2, DIMS_M[2] / 2
    act = Contact([x_m, -w, 0.001], [0.0, -1.0, 0.0], 40.0, 0.8)
    mic = Contact([x_m, w, 0.001], [0.0, 1.0, 0.0], 40.0, 0.8)
    table = (Contact([-0.05, 0.003, -h], [0.0, 0.0, -1.0], 0.6, 0.5),
             Contact([0.045, -0.004, -h], [0.0, 0.0, -1.0], 0.6, 0.5))
    return act, mic, table


def test_view_modes_equal_the_direct_build(models):
    _, view, direct = models
    np.testing.assert_allclose(view.frequencies_hz, direct.frequencies_hz, rtol=1e-8)
    assert view.mass_kg == pytest.approx(direct.mass_kg, rel=1e-12)
    points = np.array([[0.025, -0.01, 0.001], [-0.05, 0.003, -0.006], [0.06, 0.0, 0.006]])
    # shapes up to each mode's sign
    a, b = view.mode_shapes_at(points), direct.mode_shapes_at(points)
    sign = np.sign(np.einsum("pxr,pxr->r", a, b))
    np.testing.assert_allclose(a * sign, b, rtol=0, atol=1e-6 * np.abs(b).max())


@pytest.mark.parametrize("reuse_unit_loads", [True, False])
def test_contact_spring_modes_equal_the_direct_build(models, reuse_unit_loads, monkeypatch):
    """The coupled modes of the grasp's springs (attachment modes from the nominal model's
    factorization, scaled) against those of the model built in the scaled material."""
    monkeypatch.setattr(static_correction, "REUSE_UNIT_LOADS", reuse_unit_loads)
    _, view, direct = models
    act, mic, table = grasp_contacts()
    tip = FingertipModel()
    contacts = (tip.pad(act), tip.pad(mic), *table)
    got, want = spring_modes(view, contacts), spring_modes(direct, contacts)
    assert got is not view and got.n_modes == want.n_modes
    np.testing.assert_allclose(got.frequencies_hz, want.frequencies_hz, rtol=1e-7)


@pytest.mark.parametrize("excitation", ["linear", "impulse"])
@pytest.mark.parametrize("contact_model", ["spring_damper", "damping"])
def test_features_equal_the_direct_build(models, excitation, contact_model):
    """The 140 features of a grasp (closed form, from rest, noise-free) within 1e-6 relative."""
    _, view, direct = models
    act, mic, table = grasp_contacts()
    ex = Excitation.by_name(excitation)
    got = simulate_features(view, ex, 1.0, act, mic, table, contact_model=contact_model).features()
    want = simulate_features(direct, ex, 1.0, act, mic, table, contact_model=contact_model).features()
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)


def test_poisson_ratio_is_not_a_rescaling(models):
    """A new Poisson ratio changes the shapes: the view refuses it (the envs never draw one)."""
    from sensors.modal.basis import MaterialView

    base, _, _ = models
    with pytest.raises(ValueError, match="Poisson"):
        MaterialView(base, dataclasses.replace(base.material, poisson_ratio=base.material.poisson_ratio + 0.02))
