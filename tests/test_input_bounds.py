"""Bounded by construction (issue 31): every env, acoustic and dataset input is checked before
any work starts, and every cost the inputs set (samples, physics per step, grasps, worker
processes) is estimated and refused at construction with the limit and how to change it."""

from __future__ import annotations

import json
import warnings

import gymnasium as gym
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.cli import main
from aas_gym.experiments.config import DatasetConfig
from aas_gym.experiments.generate import load_dataset
from sensors.task import AcousticConfig

ENVS = ("AcousticGrasp-v0", "GraspPosition-v0", "ObjectRecognition-v0", "ContactFormation-v0", "FillLevel-v0")


def _make(name, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium's passive checker on observation dtypes
        return gym.make(f"aas_gym/{name}", **kw)


# --- 1. costs bounded before work starts --------------------------------------------------------
def test_an_hour_long_recording_is_refused_at_make_with_its_estimate():
    with pytest.raises(ValueError, match=r"158,760,000 samples.*limit 2,646,000.*GB.*max_samples"):
        _make("AcousticGrasp-v0", acoustic={"duration_s": 3600})
    # the limit is a setting one can raise, and does not change the config's identity
    longer = AcousticConfig(duration_s=61.0, max_samples=61 * 44100)
    assert longer.n_samples == 61 * 44100
    assert AcousticConfig(max_samples=10**9) == AcousticConfig()


def test_a_streamed_step_longer_than_the_limit_is_refused_at_make():
    with pytest.raises(ValueError, match=r"one streamed step \(frame_skip=500.*44,100 samples.*limit 30,000"):
        _make("AcousticGrasp-v0", acoustic={"cadence": "stream", "duration_s": 0.5, "max_samples": 30_000},
              frame_skip=500)
    with pytest.raises(ValueError, match=r"2000 s of physics per env step.*max_frame_skip"):
        _make("AcousticGrasp-v0", acoustic={"cadence": "stream"}, frame_skip=10**6)


# --- 2. types and values --------------------------------------------------------------------------
@pytest.mark.parametrize("fields, error, says", [
    ({"duration_s": True}, TypeError, "duration_s must be a number"),
    ({"enabled": "no"}, TypeError, "enabled must be True or False"),
    ({"waveform": "False"}, TypeError, "waveform must be True or False"),
    ({"noise_std": float("nan")}, ValueError, "noise_std must be finite"),
    ({"duration_s": float("inf")}, ValueError, "duration_s must be finite"),
    ({"max_samples": 2.5e6}, TypeError, "max_samples must be an integer"),
])
def test_acoustic_fields_refuse_bools_strings_and_non_finite_numbers(fields, error, says):
    with pytest.raises(error, match=says):
        AcousticConfig(**fields)
    with pytest.raises(error, match=says):  # the env takes the same dict
        AcousticConfig.coerce(fields)


@pytest.mark.parametrize("frame_skip, error", [(-2, ValueError), (0, ValueError), (True, TypeError),
                                               (2.5, TypeError)])
def test_frame_skip_is_a_positive_integer(frame_skip, error):
    with pytest.raises(error, match="frame_skip"):
        _make("GraspPosition-v0", frame_skip=frame_skip)


@pytest.mark.parametrize("name, kw, error", [
    ("GraspPosition-v0", {"n_positions": True}, TypeError),
    ("GraspPosition-v0", {"spacing_m": float("nan")}, ValueError),
    ("GraspPosition-v0", {"grip_force_n": True}, TypeError),
    ("GraspPosition-v0", {"objects": "wood_bar"}, TypeError),
    ("GraspPosition-v0", {"width": 4000}, ValueError),
    ("GraspPosition-v0", {"camera_name": "top"}, ValueError),
    ("ObjectRecognition-v0", {"probe_cost": float("nan")}, ValueError),
    ("ObjectRecognition-v0", {"max_position_m": "0.05"}, TypeError),
    ("ContactFormation-v0", {"plinths": "steel_bar"}, TypeError),
    ("FillLevel-v0", {"fill_fraction": True}, TypeError),
    ("FillLevel-v0", {"fill_range": (0.1, "0.5")}, TypeError),
    ("FillLevel-v0", {"liquids": "water"}, TypeError),
    ("FillLevel-v0", {"liquids": ("water", True), "task": "liquid"}, TypeError),
    ("AcousticGrasp-v0", {"randomization": {"damping_rel": float("nan")}}, ValueError),
    ("AcousticGrasp-v0", {"randomization": {"modulus_rel": True}}, TypeError),
    ("AcousticGrasp-v0", {"randomization": {"leak_scale": (2.0, 1.0)}}, ValueError),
])
def test_env_arguments_refuse_bools_strings_and_nan(name, kw, error):
    with pytest.raises(error, match=next(iter(kw)) if "randomization" not in kw else next(iter(kw["randomization"]))):
        _make(name, **kw)


@pytest.mark.parametrize("name, valid", [
    ("AcousticGrasp-v0", ["object"]),
    ("GraspPosition-v0", ["object", "position_index"]),
    ("ObjectRecognition-v0", ["label_index"]),
    ("ContactFormation-v0", ["object"]),
    ("FillLevel-v0", ["object", "fill_fraction", "liquid_index"]),
])
def test_reset_refuses_unknown_options_naming_the_valid_ones(name, valid):
    env = _make(name)
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['positon_index'\]; valid options: " +
                       str(valid).replace("[", r"\[").replace("]", r"\]")):
        env.reset(seed=0, options={"positon_index": 3})
    env.close()


# --- 3. the dataset configuration, the CLI and the dataset folder ---------------------------------
@pytest.mark.parametrize("fields, error, says", [
    ({"seed": -1}, ValueError, "seed must be an integer in"),
    ({"single_grasps": True}, TypeError, "single_grasps must be an integer"),
    ({"objects": ("",)}, ValueError, "objects must name at least one"),
    ({"objects": "wood_bar"}, TypeError, "objects must be a list or tuple"),
    ({"store_waveforms": "no"}, TypeError, "store_waveforms must be True or False"),
    ({"duration_s": 3600.0}, ValueError, "samples per recording"),
    ({"single_grasps": 10**9}, ValueError, "core-hours.*DatasetConfig.max_tasks"),
])
def test_dataset_config_refuses_what_would_fail_later(fields, error, says):
    with pytest.raises(error, match=says):
        DatasetConfig(**fields)


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err.strip()


def test_a_negative_seed_is_refused_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "d"
    code, err = _run(capsys, "generate", out, "--seed", "-1", "--quick", "--objects", "wood_bar")
    assert code == 2 and "--seed must be an integer in [0, inf], got -1" in err
    assert not out.exists()  # so the corrected command is not "another configuration"


@pytest.mark.parametrize("flag", ["--objects", "--excitations", "--scenes"])
def test_an_empty_name_list_is_refused_not_read_as_the_defaults(tmp_path, capsys, flag):
    for value in ("", "wood_bar,,steel_bar"):
        code, err = _run(capsys, "generate", tmp_path / "d", flag, value)
        assert code == 2 and f"{flag} {value!r} has an empty name" in err
    assert not (tmp_path / "d").exists()


def test_too_many_workers_are_refused_with_their_memory(tmp_path, capsys):
    # a misspelt object too: were --workers not checked first, this would fail on the object, not start work
    code, err = _run(capsys, "generate", tmp_path / "d", "--workers", "100000", "--objects", "wood_barr")
    assert code == 2 and "processes of ~350 MB" in err
    code, err = _run(capsys, "report", tmp_path, "--workers", "0")
    assert code == 2 and "--workers must be >= 1" in err


def test_a_truncated_manifest_is_named_with_its_remedy(tmp_path, capsys):
    out = tmp_path / "d"
    out.mkdir()
    manifest = out / ".dataset.json"
    manifest.write_text(json.dumps({"config": {"seed": 0}, "fingerprint": "ab", "n_shards": 1}, indent=2)[:40])
    code, err = _run(capsys, "generate", out, "--quick", "--objects", "wood_bar", "--scenes", "single")
    assert code == 2 and str(manifest) in err and "is damaged" in err and "--overwrite" in err
    code, err = _run(capsys, "report", out)
    assert code == 2 and str(manifest) in err and "--overwrite" in err
    with pytest.raises(ValueError, match="is damaged.*another folder"):
        load_dataset(out)
    manifest.write_text("[1, 2]")  # JSON, but no dataset's
    with pytest.raises(ValueError, match="not an aas-gym dataset manifest"):
        load_dataset(out)


@pytest.mark.parametrize("kw, error", [({"control_period_s": True}, TypeError), ({"control_period_s": 0.0}, ValueError),
                                       ({"max_episode_steps": True}, TypeError), ({"max_episode_steps": 2.5}, TypeError),
                                       ({"reset_duration_s": float("nan")}, ValueError),
                                       ({"home_tcp": [0.0, 0.1, 0.3]}, ValueError)])
def test_the_real_env_checks_its_numbers_like_the_simulated_ones(kw, error):
    from real import RealGraspEnv
    from test_real_env import CommandLog, Recorder

    with pytest.raises(error):
        RealGraspEnv(CommandLog(), Recorder(), **kw)
