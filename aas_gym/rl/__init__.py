"""Reinforcement learning with the envs: Stable-Baselines3 feature extractors for the acoustic
observations (``aas_gym.rl.extractors``). Needs the ``rl`` extra (``pip install aas-gym[rl]``:
stable-baselines3, torch, tensorboard); ``import aas_gym`` does not load it."""

from aas_gym.rl.extractors import AUDIO_KEYS, AcousticExtractor, FeatureCNN, SpectrogramCNN, audio_net_kind

__all__ = ["AUDIO_KEYS", "AcousticExtractor", "FeatureCNN", "SpectrogramCNN", "audio_net_kind"]
