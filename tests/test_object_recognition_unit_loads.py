"""ObjectRecognition-v0's probe features through the kept unit-load solves (the default fast
path of ``sensors.modal.static_correction``) against the direct solve of every contact set
(``reference_paths()``: REUSE_UNIT_LOADS and GRAM_PRODUCTS off), and their independence from
what the store already held.

Probe positions are continuous, so every probe may load new nodes; most of a fresh process's
sensing time goes to their unit-load solves until each object's store holds the nodes its
grasp path touches (about 240 per model). Whatever the store held, a probe's features must
equal the direct solve within 1e-9 relative (the reuse sums the same span in another order)
and be bit for bit the same (the store's products are made in fixed-shape BLAS calls).

The env returns float32 features, where a difference of 1e-12 can flip one float32 ulp (up
to 6e-8 of a feature); so the comparison is of the float64 window amplitudes the closed form
computes (``sensors.synthesis.simulate_features``, recorded on their way into the env) and
the float32 observations to their rounding.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
import aas_gym.sim_sensor
from sensors._infra.lru import clear_all
from sensors.modal import static_correction

EXCITATION_ACTIONS = (-0.9, 0.0, 0.9)     # impulse, linear, exponential bins of the Box action


def probe_features(seed: int, episodes: int = 3, probes: int = 3):
    """``(observed, amplitudes)``: the ``acoustic`` observations (episodes * probes, 140,
    float32) of probes at seeded random positions and excitations, one env from
    ``reset(seed=seed + i)`` per episode, and the float64 window amplitudes behind them."""
    rng = np.random.default_rng(seed)
    env = gym.make("aas_gym/ObjectRecognition-v0")
    features, amplitudes = [], []
    simulate = aas_gym.sim_sensor.simulate_features

    def recorded(*args, **kwargs):
        observation = simulate(*args, **kwargs)
        amplitudes.append(np.array(observation.window_amplitudes, float))
        return observation

    aas_gym.sim_sensor.simulate_features = recorded
    try:
        for i in range(episodes):
            env.reset(seed=seed + i)
            for _ in range(probes):
                action = np.array([-1.0, rng.uniform(-1.0, 1.0), EXCITATION_ACTIONS[rng.integers(3)], 0.0],
                                  np.float32)
                obs, _, terminated, truncated, _ = env.step(action)
                assert not (terminated or truncated)
                features.append(np.asarray(obs["acoustic"], float))
    finally:
        aas_gym.sim_sensor.simulate_features = simulate
        env.close()
    assert len(amplitudes) == len(features)
    return np.stack(features), np.stack(amplitudes)


@pytest.fixture(scope="module")
def fast():
    clear_all()
    return probe_features(seed=11)


def test_features_equal_the_direct_solve(fast):
    clear_all()
    with static_correction.reference_paths():
        direct = probe_features(seed=11)
    clear_all()
    (observed, amplitudes), (observed_direct, amplitudes_direct) = fast, direct
    assert amplitudes.shape == amplitudes_direct.shape and np.all(np.isfinite(amplitudes))
    scale = np.max(np.abs(amplitudes_direct), axis=(1, 2), keepdims=True)
    assert np.all(scale > 0)
    assert np.max(np.abs(amplitudes - amplitudes_direct) / scale) < 1e-9
    # float32 observations: at most a rounding flip (6e-8 of a value), relative to the probe's largest
    observed_scale = np.max(np.abs(observed_direct), axis=1, keepdims=True)
    assert np.max(np.abs(observed.astype(float) - observed_direct) / observed_scale) < 1.2e-7


def test_features_do_not_depend_on_the_stores_history(fast):
    """Other probes first (their nodes kept, the store's slots and products in another order):
    the same probes give the same features bit for bit."""
    clear_all()
    probe_features(seed=23, episodes=2, probes=4)
    again = probe_features(seed=11)
    clear_all()
    assert np.array_equal(again[1], fast[1]) and np.array_equal(again[0], fast[0])
