"""Stable-Baselines3 feature extractors for the acoustic observations.

Each network derives its layers from the observation space it is given, so it fits whatever
shape the env's ``acoustic`` options produce:

* :class:`FeatureCNN` (a small 1-D CNN): the 140 spectral features, shape ``(140,)``, or a
  history of frames, ``(history, 140)`` (the frames are its input channels);
* :class:`SpectrogramCNN` (a small 2-D CNN): a spectrogram or mel image, 2-D (the envs'
  ``acoustic={"features": "spectrogram" | "mel"}`` give ``(frames, bins)``; the convolutions
  treat both axes alike, so ``(bins, frames)`` fits too), or a history of them, 3-D (the
  history is its input channels);
* :class:`AcousticExtractor`: a ``Dict`` observation; the acoustic keys go through one of
  the two (chosen from their shape, see :func:`audio_net_kind`), every other key is
  flattened, and the results are concatenated (SB3's ``CombinedExtractor`` pattern).

Usage::

    PPO("MultiInputPolicy", env,
        policy_kwargs=dict(features_extractor_class=AcousticExtractor,
                           features_extractor_kwargs=dict(audio_features_dim=64)))

Inputs are used as the env gives them: choose ``acoustic={"feature_scale": "db"}`` (levels of
tens) rather than the raw amplitudes (1e-7 to 1e-4), or set ``normalize=True`` to standardize
each sample of the acoustic input (this drops its absolute level, which carries damping).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import torch
from gymnasium import spaces
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from sensors.task import N_FEATURES

__all__ = ["AUDIO_KEYS", "AcousticExtractor", "FeatureCNN", "SpectrogramCNN", "audio_net_kind"]

#: Observation keys :class:`AcousticExtractor` sends through an audio network by default
#: (those the observation has).
AUDIO_KEYS = ("acoustic", "spectrogram", "mel")


def _box_shape(space: spaces.Space, ndims: Iterable[int], name: str) -> tuple[int, ...]:
    if not isinstance(space, spaces.Box):
        raise TypeError(f"{name} takes a Box observation space, got {type(space).__name__}")
    if len(space.shape) not in tuple(ndims):
        raise ValueError(f"{name} takes a Box of {' or '.join(map(str, ndims))} dimensions, got shape {space.shape}")
    return tuple(int(n) for n in space.shape)


def _flat_size(net: nn.Module, shape: tuple[int, ...]) -> int:
    """Output size of ``net`` for one input of ``shape`` (run once on zeros)."""
    with torch.no_grad():
        return int(net(torch.zeros((1, *shape))).shape[1])


class _Standardize(nn.Module):
    """Zero mean, unit variance per sample over all its entries (no learnt parameters)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        flat = x.flatten(1)
        mean = flat.mean(dim=1).view(-1, *([1] * (x.dim() - 1)))
        std = flat.std(dim=1, unbiased=False).view(-1, *([1] * (x.dim() - 1)))
        return (x - mean) / (std + 1e-8)


class FeatureCNN(BaseFeaturesExtractor):
    """A small 1-D CNN over the frequency axis of spectral feature vectors.

    Args:
        observation_space: Box of shape ``(n_bins,)`` (one frame: 140 features) or
            ``(history, n_bins)`` (the last frames, oldest first: input channels).
        features_dim: size of the output.
        channels: output channels of the two convolutions (stride 2 each: 140 bins -> 35).
        normalize: standardize each sample before the convolutions.
    """

    def __init__(self, observation_space: spaces.Box, features_dim: int = 64, channels: tuple[int, int] = (16, 32),
                 normalize: bool = False) -> None:
        shape = _box_shape(observation_space, (1, 2), "FeatureCNN")
        super().__init__(observation_space, features_dim)
        self.in_shape = (1, shape[0]) if len(shape) == 1 else shape
        c0, c1 = channels
        self.cnn = nn.Sequential(
            _Standardize() if normalize else nn.Identity(),
            nn.Conv1d(self.in_shape[0], c0, kernel_size=7, stride=2, padding=3), nn.ReLU(),
            nn.Conv1d(c0, c1, kernel_size=5, stride=2, padding=2), nn.ReLU(),
            nn.Flatten())
        self.linear = nn.Sequential(nn.Linear(_flat_size(self.cnn, self.in_shape), features_dim), nn.ReLU())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.linear(self.cnn(observations.reshape(-1, *self.in_shape)))


class SpectrogramCNN(BaseFeaturesExtractor):
    """A small 2-D CNN over a time-frequency image.

    Args:
        observation_space: Box of shape ``(frames, bins)`` or ``(history, frames, bins)`` (the
            history as input channels); the two image axes may come in either order.
        features_dim: size of the output.
        channels: output channels of the two 3 x 3 convolutions (stride 2 each).
        pooled: the feature maps are average-pooled to ``pooled`` (freq, time) cells before the
            linear layer, so its size does not grow with the image.
        normalize: standardize each sample before the convolutions.
    """

    def __init__(self, observation_space: spaces.Box, features_dim: int = 128, channels: tuple[int, int] = (16, 32),
                 pooled: tuple[int, int] = (4, 4), normalize: bool = False) -> None:
        shape = _box_shape(observation_space, (2, 3), "SpectrogramCNN")
        super().__init__(observation_space, features_dim)
        self.in_shape = (1, *shape) if len(shape) == 2 else shape
        c0, c1 = channels
        self.cnn = nn.Sequential(
            _Standardize() if normalize else nn.Identity(),
            nn.Conv2d(self.in_shape[0], c0, kernel_size=3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(c0, c1, kernel_size=3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(pooled), nn.Flatten())
        self.linear = nn.Sequential(nn.Linear(_flat_size(self.cnn, self.in_shape), features_dim), nn.ReLU())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.linear(self.cnn(observations.reshape(-1, *self.in_shape)))


def audio_net_kind(shape: tuple[int, ...], n_bins: int = N_FEATURES) -> str:
    """``"features"`` (:class:`FeatureCNN`) or ``"spectrogram"`` (:class:`SpectrogramCNN`) for
    an acoustic entry of ``shape``: 1-D is a feature frame; 2-D whose last axis holds ``n_bins``
    (140) is a history of frames, any other 2-D a time-frequency image; 3-D a history of images."""
    if len(shape) == 1 or (len(shape) == 2 and shape[-1] == n_bins):
        return "features"
    if len(shape) in (2, 3):
        return "spectrogram"
    raise ValueError(f"no audio network for an entry of shape {shape}: expected (bins,), (history, bins), "
                     "(freq, time) or (history, freq, time)")


_NETS = {"features": FeatureCNN, "spectrogram": SpectrogramCNN}


class AcousticExtractor(BaseFeaturesExtractor):
    """Dict observations: acoustic entries through an audio network, the rest flattened.

    Args:
        observation_space: a ``Dict`` of Box entries.
        audio_keys: keys sent through an audio network (default: those of :data:`AUDIO_KEYS`
            the space has); each gets its own network.
        audio_net: ``"auto"`` (by shape, :func:`audio_net_kind`), ``"features"`` or
            ``"spectrogram"``, or a mapping key -> one of these.
        audio_features_dim: output size of each audio network.
        normalize: passed to the audio networks.
        net_kwargs: further keyword arguments of the audio networks (``channels``, ...).
    """

    def __init__(self, observation_space: spaces.Dict, audio_keys: Iterable[str] | None = None,
                 audio_net: str | Mapping[str, str] = "auto", audio_features_dim: int = 64,
                 normalize: bool = False, net_kwargs: Mapping | None = None) -> None:
        if not isinstance(observation_space, spaces.Dict):
            raise TypeError(f"AcousticExtractor takes a Dict observation space, got {type(observation_space).__name__}")
        keys = [k for k in AUDIO_KEYS if k in observation_space.spaces] if audio_keys is None else list(audio_keys)
        unknown = [k for k in keys if k not in observation_space.spaces]
        if unknown:
            raise KeyError(f"audio_keys {unknown} are not in the observation space; its keys: "
                           f"{list(observation_space.spaces)}")
        extractors: dict[str, nn.Module] = {}
        total = 0
        for key, space in observation_space.spaces.items():
            if key in keys:
                kind = audio_net.get(key, "auto") if isinstance(audio_net, Mapping) else audio_net
                if kind == "auto":
                    kind = audio_net_kind(tuple(space.shape))
                if kind not in _NETS:
                    raise ValueError(f"audio_net for {key!r} must be 'auto', 'features' or 'spectrogram', got {kind!r}")
                net = _NETS[kind](space, audio_features_dim, normalize=normalize, **dict(net_kwargs or {}))
                total += net.features_dim
            else:
                net = nn.Flatten()
                total += get_flattened_obs_dim(space)  # SB3 one-hot encodes Discrete entries
            extractors[key] = net
        super().__init__(observation_space, features_dim=total)
        self.audio_keys = tuple(keys)
        self.extractors = nn.ModuleDict(extractors)

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.cat([net(observations[key]) for key, net in self.extractors.items()], dim=1)
