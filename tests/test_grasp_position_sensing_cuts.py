"""Exact per-episode cuts for GraspPosition-v0. The fingertip drive's microphone-side system built from the actuator side's eigen-solve
(``DiscreteSystem.with_output``) against solving it anew (the reference path, bit for bit) and
against the eigenvector-free discretisation (augmented matrix exponential, 1e-9 relative)."""

import numpy as np
import pytest

import sensors.synthesis.fingertip as fingertip
from sensors.synthesis.fingertip import FingertipModel
from sensors.synthesis.lti import lti_system

FS_HZ = 48000
TIPS = [FingertipModel(), FingertipModel(object_mass_kg=0.037), FingertipModel(object_mass_kg=0.41),
        FingertipModel(object_mass_kg=0.12, environment_stiffness_n_m=3e4, environment_damping_n_s_m=5.0)]


def _mic_row(tip: FingertipModel) -> np.ndarray:
    Cm = np.zeros(8)
    Cm[4], Cm[5], Cm[6], Cm[7] = tip.contact_stiffness_n_m, tip.contact_damping_n_s_m, \
        -tip.contact_stiffness_n_m, -tip.contact_damping_n_s_m
    return Cm


def _discretised(tip, shared: bool, monkeypatch):
    monkeypatch.setattr(fingertip, "SHARED_DRIVE_EIGENSOLVE", shared)
    return tip.discretised(FS_HZ)


@pytest.mark.parametrize("tip", TIPS)
def test_shared_eigensolve_gives_the_reference_numbers_bit_for_bit(tip, monkeypatch):
    fast, ref = _discretised(tip, True, monkeypatch), _discretised(tip, False, monkeypatch)
    u = np.random.default_rng(3).standard_normal(3000)
    period = u[:1000]
    for a, b in ((fast.act, ref.act), (fast.mic, ref.mic)):
        assert np.array_equal(a.response(u), b.response(u))
        assert np.array_equal(a.periodic_response(period), b.periodic_response(period))
        assert np.array_equal(a.periodic_response(period, bandlimited=True),
                              b.periodic_response(period, bandlimited=True))
        assert np.array_equal(a.periodic_state(period), b.periodic_state(period))
        assert np.array_equal(a.frequency_response([100.0, 1234.5, 9000.0]),
                              b.frequency_response([100.0, 1234.5, 9000.0]))
    # the outputs differ (the shared path did not hand back the actuator's row)
    assert not np.allclose(fast.mic.response(u), fast.act.response(u))


@pytest.mark.parametrize("tip", TIPS)
def test_mic_output_matches_the_matrix_exponential_discretisation(tip, monkeypatch):
    """Independent of the eigenvectors: the augmented matrix exponential (exact FOH)."""
    mic = _discretised(tip, True, monkeypatch).mic
    A, B, _ = tip.state_space()
    u = np.random.default_rng(7).standard_normal(4000)
    y = mic.response(u)
    dense = lti_system(A, B, _mic_row(tip), 0.0, FS_HZ, method="dense").response(u)
    assert np.max(np.abs(y - dense)) <= 1e-9 * np.max(np.abs(dense))
    period = u[:1000]
    yp = mic.periodic_response(period)
    dp = lti_system(A, B, _mic_row(tip), 0.0, FS_HZ, method="dense").periodic_response(period)
    assert np.max(np.abs(yp - dp)) <= 1e-9 * np.max(np.abs(dp))


def test_dense_part_with_output_matches_building_it_anew():
    tip = TIPS[0]
    A, B, C = tip.state_space()
    Cm = _mic_row(tip)
    shared = lti_system(A, B, C, 0.0, FS_HZ, method="dense").with_output(Cm)
    anew = lti_system(A, B, Cm, 0.0, FS_HZ, method="dense")
    assert shared.methods_used == ["dense"]
    u = np.random.default_rng(11).standard_normal(2000)
    assert np.array_equal(shared.response(u), anew.response(u))
    assert np.array_equal(shared.periodic_response(u[:500]), anew.periodic_response(u[:500]))
    assert np.allclose(shared.frequency_response([250.0, 4000.0]), anew.frequency_response([250.0, 4000.0]),
                       rtol=1e-12, atol=0)


def test_cross3_is_numpys_cross_bit_for_bit():
    """The spring tangents' cross product (``sensors.modal.spring_modes.cross3``) against
    ``np.cross`` and the determinant definition."""
    from sensors.modal.spring_modes import cross3

    rng = np.random.default_rng(5)
    for a, b in rng.standard_normal((2000, 2, 3)) * np.exp(rng.uniform(-20, 20, (2000, 2, 1))):
        c = cross3(a, b)
        assert np.array_equal(c, np.cross(a, b))
    e = np.eye(3)
    assert np.array_equal(cross3(e[0], e[1]), e[2]) and np.array_equal(cross3(e[1], e[2]), e[0])
    assert np.array_equal(cross3(e[0], (0.0, 1.0, 0.0)), e[2])
