"""FillLevel-v0 in a multi-object scene: a filled container (a wet model without a mesh) that
touches another object vibrates with it (``sensors.modal.coupled_bodies``) through its wet modes
without static correction, as it does alone on its grasp springs; it used to fail at the first
reset ("a FilledModalModel has no mesh")."""

import gymnasium as gym
import numpy as np

import aas_gym  # noqa: F401  (registers the envs)
from sensors.modal import touching


def test_a_filled_container_touching_another_object_is_heard(monkeypatch):
    built = []
    original = touching.CoupledBodies.__init__

    def counting(self, bodies, *args, **kwargs):
        built.append([type(b[0]).__name__ for b in bodies])
        return original(self, bodies, *args, **kwargs)

    monkeypatch.setattr(touching.CoupledBodies, "__init__", counting)
    env = gym.make("aas_gym/FillLevel-v0", scene="multi", disable_env_checker=True)
    for seed in range(2):
        obs, info = env.reset(seed=seed)
        assert info["grasp_success"], seed
        a = obs["acoustic"]
        assert np.isfinite(a).all() and a.min() > 0, seed
    assert any("FilledModalModel" in names for names in built), built   # the coupled path ran
    env.close()
