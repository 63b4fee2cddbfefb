"""The closed-form sampled periodic steady state (sensors.synthesis.periodic_spectrum) against
the power-sum reference (``DiscreteSystem.periodic_response``), against an independent dense
(matrix-exponential) discretisation, and the GraspPosition-v0 features with either path."""

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from sensors._infra.lru import clear_all
from sensors.synthesis import feature_recording
from sensors.synthesis.fingertip import FingertipModel
from sensors.synthesis.lti import lti_system
from sensors.synthesis.periodic_spectrum import closed_form_periodic_supported, sampled_periodic_response

FS_HZ = 48000


def _drives(mass_kg):
    tip = FingertipModel(object_mass_kg=mass_kg)
    return tip, tip.discretised(FS_HZ)


@pytest.mark.parametrize("mass_kg", [0.02, 0.137, 1.3])
@pytest.mark.parametrize("P", [4800, 4801, 48000])
def test_closed_form_matches_power_sums(mass_kg, P):
    _, d = _drives(mass_kg)
    u = np.random.default_rng(P).standard_normal(P)
    U = np.fft.rfft(u)
    for system in (d.act, d.mic):
        assert closed_form_periodic_supported(system)
        ref = system.periodic_response(u, force_spectrum=U)
        new = sampled_periodic_response(system, U, P)
        assert np.max(np.abs(new - ref)) <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("mass_kg", [0.05, 0.5])
def test_closed_form_matches_dense_discretisation(mass_kg):
    """Independent reference: the dense part (augmented matrix exponential, no eigenvectors),
    its periodic response by its own power sums."""
    tip, d = _drives(mass_kg)
    A, B, C = tip.state_space()
    dense = lti_system(A, B, C, 0.0, FS_HZ, method="dense")
    assert dense.methods_used == ["dense"]
    P = 2400
    t = np.arange(P) / FS_HZ
    u = np.sin(2 * np.pi * 1000 * t) + 0.3 * np.sin(2 * np.pi * 7000 * t + 0.4)   # looped tones
    ref = dense.periodic_response(u)
    new = sampled_periodic_response(d.act, np.fft.rfft(u), P)
    assert np.max(np.abs(new - ref)) <= 1e-9 * np.max(np.abs(ref))


def _episode_features(seeds, mode, monkeypatch):
    monkeypatch.setattr(feature_recording, "DRIVE_STEADY_STATE", mode)
    clear_all()
    env = gym.make("aas_gym/GraspPosition-v0")
    try:
        return [np.asarray(env.reset(seed=s)[0]["acoustic"], dtype=float) for s in seeds]
    finally:
        env.close()


def test_grasp_position_features_either_path(monkeypatch):
    """Randomized episodes (a new object mass, so a new fingertip model, each): features of the
    closed form within 1e-9 relative of the reference path's."""
    seeds = [1, 2, 3, 4]
    fast = _episode_features(seeds, "closed_form", monkeypatch)
    ref = _episode_features(seeds, "reference", monkeypatch)
    for f, r in zip(fast, ref):
        assert f.shape == r.shape and np.all(np.isfinite(f))
        assert np.max(np.abs(f - r)) <= 1e-9 * np.max(np.abs(r))

