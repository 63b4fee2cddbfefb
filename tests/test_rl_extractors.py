"""``aas_gym.rl``: the feature extractors fit the observation shapes they are given, and PPO
learns with them on the envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

pytest.importorskip("stable_baselines3")
import torch  # noqa: E402

import aas_gym  # noqa: E402,F401  (registers the envs)
from aas_gym.rl import AcousticExtractor, FeatureCNN, SpectrogramCNN, audio_net_kind  # noqa: E402

torch.set_num_threads(1)


def _box(*shape):
    return spaces.Box(-np.inf, np.inf, shape, np.float32)


@pytest.mark.parametrize("net, shape", [(FeatureCNN, (140,)), (FeatureCNN, (4, 140)), (FeatureCNN, (8, 37)),
                                        (SpectrogramCNN, (64, 21)), (SpectrogramCNN, (3, 128, 44)),
                                        (SpectrogramCNN, (5, 2))])
def test_extractor_output_shape(net, shape):
    extractor = net(_box(*shape), features_dim=24)
    x = torch.as_tensor(np.random.default_rng(0).normal(size=(5, *shape)), dtype=torch.float32)
    y = extractor(x)
    assert tuple(y.shape) == (5, 24) and extractor.features_dim == 24
    # samples are independent: one sample alone gives its row of the batch
    np.testing.assert_allclose(extractor(x[2:3]).detach().numpy(), y[2:3].detach().numpy(), rtol=1e-5, atol=1e-6)


def test_wrong_rank_is_refused():
    with pytest.raises(ValueError, match="shape"):
        FeatureCNN(_box(2, 3, 4))
    with pytest.raises(ValueError, match="shape"):
        SpectrogramCNN(_box(140))


def test_audio_net_kind_by_shape():
    assert audio_net_kind((140,)) == "features"
    assert audio_net_kind((6, 140)) == "features"
    assert audio_net_kind((64, 32)) == "spectrogram"
    assert audio_net_kind((2, 64, 32)) == "spectrogram"


@pytest.mark.parametrize("acoustic, kind", [({}, FeatureCNN), ({"history": 3}, FeatureCNN),
                                            ({"features": "mel"}, SpectrogramCNN),
                                            ({"features": "spectrogram", "history": 2}, SpectrogramCNN)])
def test_extractor_fits_every_acoustic_option_of_the_envs(acoustic, kind):
    env = gym.make("aas_gym/GraspPosition-v0", acoustic=acoustic)
    try:
        space = env.observation_space
        ex = AcousticExtractor(space, audio_features_dim=16)
        assert isinstance(ex.extractors["acoustic"], kind)
        batch = {k: torch.as_tensor(np.stack([space[k].sample() for _ in range(3)]), dtype=torch.float32)
                 for k in space.spaces}
        assert tuple(ex(batch).shape) == (3, ex.features_dim)
    finally:
        env.close()


def test_combined_extractor_routes_the_acoustic_key_and_flattens_the_rest():
    space = spaces.Dict({"tcp": _box(4), "acoustic": _box(3, 40, 16), "n": spaces.Discrete(3)})
    ex = AcousticExtractor(space, audio_features_dim=10)
    assert isinstance(ex.extractors["acoustic"], SpectrogramCNN)
    assert ex.features_dim == 4 + 10 + 3  # Discrete(3): one-hot, as SB3 preprocesses it
    obs = {"tcp": torch.zeros(2, 4), "acoustic": torch.zeros(2, 3, 40, 16), "n": torch.zeros(2, 3)}
    assert tuple(ex(obs).shape) == (2, 17)
    with pytest.raises(KeyError, match="not in the observation space"):
        AcousticExtractor(space, audio_keys=["spectrogram"])


def test_ppo_learns_a_few_hundred_steps_with_the_extractor():
    from stable_baselines3 import PPO

    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"feature_scale": "db"})
    model = PPO("MultiInputPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu",
                policy_kwargs=dict(features_extractor_class=AcousticExtractor,
                                   features_extractor_kwargs=dict(audio_features_dim=32)))
    assert isinstance(model.policy.features_extractor.extractors["acoustic"], FeatureCNN)
    before = [p.detach().clone() for p in model.policy.features_extractor.parameters()]
    model.learn(total_timesteps=256)
    assert model.num_timesteps == 256
    after = list(model.policy.features_extractor.parameters())
    assert any(not torch.equal(a, b) for a, b in zip(before, after))  # the extractor was trained
    env.close()


def test_the_example_trains_with_the_extractor_and_logs_to_tensorboard(tmp_path):
    """examples/train_with_extractor.py at its smallest budget (one PPO rollout of 256 steps),
    run from a scratch folder with a relative ``--out``: the TensorBoard run (read back with
    TensorBoard's own reader) and the model land there, and nothing else is written."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    event_accumulator = pytest.importorskip("tensorboard.backend.event_processing.event_accumulator")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, str(root / "examples" / "train_with_extractor.py"), "--timesteps", "256",
                           "--out", "runs"], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
    events = list((tmp_path / "runs").glob("GraspPosition-v0_*/events.out.tfevents.*"))
    assert len(events) == 1 and (tmp_path / "runs" / "ppo_GraspPosition-v0.zip").stat().st_size > 0
    acc = event_accumulator.EventAccumulator(str(events[0].parent))
    acc.Reload()
    tags = set(acc.Tags()["scalars"])
    assert {"rollout/ep_rew_mean", "rollout/success_rate", "time/fps"} <= tags, tags
    assert acc.Scalars("rollout/ep_rew_mean")[-1].step == 256


@pytest.mark.parametrize("args, message", [(["--timesteps", "0"], "must be a positive integer"),
                                           (["--env", "GraspPositon-v0"], "invalid choice")])
def test_the_example_refuses_bad_arguments_before_training(tmp_path, args, message):
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, str(root / "examples" / "train_with_extractor.py"), *args, "--out", "runs"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 2 and message in proc.stderr and not list(tmp_path.iterdir())
