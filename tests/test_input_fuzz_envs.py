"""Property-based: the env constructors (through ``gymnasium.make``), ``AcousticConfig`` and
``DatasetConfig`` given booleans, strings, huge and tiny numbers, NaN and infinities either
build a valid object or raise a ``ValueError``/``TypeError`` naming the argument at fault;
never another exception, never a value silently taken for something else, never a cost that
is not bounded (issue 31). No env is reset here: construction is what is checked."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.envs.base import AasEnv
from aas_gym.experiments.config import DatasetConfig
from sensors.task import AcousticConfig

#: Values every argument is tried with: the kinds of input that slipped through before.
ODD = st.one_of(
    st.booleans(),
    st.sampled_from(["", "no", "False", "0", "1", "nan", "linear", "single", "wood_bar"]),
    st.sampled_from([0, -1, -(10**6), 10**6, 10**12, 10**30, 2**63]),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e-9, 0.5, 2.5, 1e9, 1e300]),
    st.sampled_from([math.nan, math.inf, -math.inf]),
    st.none(),
    st.just(()),
    st.just(["wood_bar"]),
)

FUZZ = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None)


def _clear_refusal(exc: BaseException, names) -> None:
    """A refusal is a ValueError or TypeError whose message names one of ``names``."""
    assert isinstance(exc, (ValueError, TypeError)), f"raw {type(exc).__name__}: {exc}"
    text = str(exc)
    assert any(n in text for n in names), f"message names none of {sorted(names)}: {text}"


ACOUSTIC_VALID = {"enabled": st.booleans(), "waveform": st.booleans(),
                  "cadence": st.sampled_from(["action", "every_step", "never"]),
                  "feature_scale": st.sampled_from(["linear", "db", "normalized"]),
                  "noise_std": st.floats(0, 1e-3), "duration_s": st.floats(0.5, 3.0),
                  "excitation": st.sampled_from(["impulse", "linear", "exponential"]),
                  "max_samples": st.integers(1, 10**7)}


#: gymnasium.make itself calls ``render_mode.endswith`` (an AttributeError for a non-string,
#: before the env sees it) and formats a warning with ``msg % args`` (a TypeError for a
#: render_mode holding "%"): render_mode is fuzzed with strings without "%" only.
_ONLY_VALID_OR_STRINGS = {"render_mode"}


def _fields(valid: dict) -> st.SearchStrategy[dict]:
    """A dict of some of the fields, each either valid or odd."""
    return st.fixed_dictionaries({}, optional={
        k: st.one_of(v, st.text(max_size=8).filter(lambda t: "%" not in t) if k in _ONLY_VALID_OR_STRINGS else ODD) for k, v in valid.items()})


def _check_acoustic(config: AcousticConfig) -> None:
    assert type(config.enabled) is bool and type(config.waveform) is bool
    assert math.isfinite(config.duration_s) and config.duration_s >= config.excitation.period_s
    assert math.isfinite(config.noise_std) and config.noise_std >= 0
    assert type(config.max_samples) is int and config.n_samples <= config.max_samples


@FUZZ
@given(_fields(ACOUSTIC_VALID))
def test_acoustic_config_builds_valid_or_refuses_clearly(fields):
    try:
        config = AcousticConfig(**fields)
    except Exception as exc:  # noqa: BLE001  (the property is about which exceptions)
        _clear_refusal(exc, set(fields) | {"excitation"})
        return
    _check_acoustic(config)


DATASET_VALID = {"objects": st.just(("wood_bar",)), "excitations": st.just(("linear",)),
                 "scenes": st.just(("single",)), "single_grasps": st.integers(0, 30),
                 "multi_grasps": st.integers(0, 30), "positions": st.integers(0, 13),
                 "position_step_m": st.floats(1e-4, 0.01), "position_repeats": st.integers(0, 5),
                 "duration_s": st.floats(0.5, 2.0), "grip_force_n": st.floats(1.0, 140.0),
                 "grasp_jitter_m": st.floats(0, 1e-3), "noise_std": st.floats(0, 1e-4),
                 "store_waveforms": st.booleans(), "seed": st.integers(0, 2**64), "shard_size": st.integers(1, 64)}


@FUZZ
@given(_fields(DATASET_VALID))
def test_dataset_config_builds_valid_or_refuses_clearly(fields):
    try:
        config = DatasetConfig(**fields)
    except Exception as exc:  # noqa: BLE001
        _clear_refusal(exc, set(fields) | {"object", "shape", "material", "configuration expands"})
        return
    for name in ("single_grasps", "multi_grasps", "positions", "position_repeats", "seed", "shard_size"):
        value = getattr(config, name)
        assert type(value) is int and value >= 0, (name, value)
    for name in ("duration_s", "grip_force_n", "position_step_m", "grasp_jitter_m", "noise_std"):
        assert math.isfinite(getattr(config, name)), name
    assert type(config.store_waveforms) is bool and config.shard_size >= 1
    assert config.n_tasks <= DatasetConfig.max_tasks and config.n_tasks == len(config.tasks())
    assert DatasetConfig.from_dict(config.to_dict()) == config


def _randomization_fields():
    return st.one_of(st.none(), st.just(False), _fields({"damping_rel": st.floats(0, 0.5),
                                                         "position_noise_m": st.floats(0, 1e-3),
                                                         "leak_scale": st.just((0.5, 1.5))}))


COMMON_VALID = {"frame_skip": st.integers(1, 50), "grip_force_n": st.floats(1.0, 140.0),
                "width": st.integers(1, 480), "height": st.integers(1, 480),
                "camera_name": st.sampled_from(["closeup", "overview", "workspace"]),
                "render_mode": st.sampled_from([None, "rgb_array"]),
                "randomization": _randomization_fields(),
                "acoustic": _fields({k: ACOUSTIC_VALID[k] for k in ("enabled", "waveform", "duration_s",
                                                                     "noise_std", "max_samples")})}
OWN_VALID = {
    "AcousticGrasp-v0": {"scene": st.sampled_from(["single", "multi"])},
    "GraspPosition-v0": {"n_positions": st.integers(1, 13), "spacing_m": st.floats(1e-4, 0.005),
                         "action_format": st.sampled_from(["normalized", "metres"])},
    "ObjectRecognition-v0": {"probe_cost": st.floats(0, 1), "max_position_m": st.floats(1e-3, 0.06),
                             "action_format": st.sampled_from(["box", "dict"])},
    "ContactFormation-v0": {"plinths": st.just(("steel_bar",))},
    "FillLevel-v0": {"fill_fraction": st.floats(0, 1), "fill_range": st.just((0.1, 0.8)),
                     "task": st.just("fill")},
}


@pytest.mark.parametrize("env_id", sorted(OWN_VALID))
def test_env_constructor_builds_valid_or_refuses_clearly(env_id):
    names = (set(COMMON_VALID) | set(OWN_VALID[env_id]) | set(ACOUSTIC_VALID)
             | {"objects", "excitation period", "damping_rel", "position_noise_m", "leak_scale"})

    @settings(FUZZ, max_examples=10)
    @given(_fields({**COMMON_VALID, **OWN_VALID[env_id]}))
    def check(kwargs):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # gymnasium's passive checker
                env = gym.make(f"aas_gym/{env_id}", **kwargs)
        except Exception as exc:  # noqa: BLE001
            _clear_refusal(exc, names)
            return
        base = env.unwrapped
        try:
            assert isinstance(base, AasEnv)
            assert type(base.frame_skip) is int and 1 <= base.frame_skip <= base.max_frame_skip
            assert not hasattr(base, "dt") or base.dt > 0  # the probe envs have no dt
            assert type(base.width) is int and type(base.height) is int and base.width >= 1 and base.height >= 1
            assert 0 < base.grip_force_n <= 140
            _check_acoustic(base.acoustic)
            assert base.observation_space.contains(base.observation_space.sample())  # the spaces build
        finally:
            env.close()

    check()
