"""Every deprecated spelling still works for one release: it warns (a DeprecationWarning that
names the new spelling and points at the caller's line) and behaves exactly as the new
spelling; the new spelling does not warn."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
import sensors
from sensors.synthesis import ContactTolerance, FingertipModel
from sensors.task import LEGACY_KEYWORDS, AcousticConfig

FAST = {"duration_s": 0.5}


def _leak_file(tmp_path):
    ex = sensors.Excitation.by_name("linear")
    return str(sensors.save_leak(tmp_path / "leak.npz", 1e-3 * np.tile(ex.signal, 2), ex.sample_rate_hz, ex))


# old keyword -> (its value, the same setting in the new spelling)
CASES = {
    "excitation": lambda tmp: ("impulse", {"excitation": "impulse"}),
    "duration_s": lambda tmp: (0.5, {"duration_s": 0.5}),
    "include_waveform": lambda tmp: (True, {"waveform": True}),
    "sense_mode": lambda tmp: ("every_step", {"cadence": "every_step"}),
    "leak": lambda tmp: (_leak_file(tmp), {"leak": _leak_file(tmp)}),
    "fingertip": lambda tmp: (FingertipModel(actuator_force_n=2.0), {"fingertip": FingertipModel(actuator_force_n=2.0)}),
    "stream_tolerance": lambda tmp: (ContactTolerance(force_rtol=0.2), {"stream_tolerance": ContactTolerance(force_rtol=0.2)}),
}


def test_every_legacy_keyword_has_a_case():
    assert set(CASES) == set(LEGACY_KEYWORDS)


def _make_quietly(env_id, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        return gym.make(env_id, disable_env_checker=True, **kwargs)


@pytest.mark.parametrize("old", sorted(CASES))
def test_env_keyword_warns_and_equals_the_acoustic_field(old, tmp_path):
    value, new = CASES[old](tmp_path)
    base = {} if old == "duration_s" else dict(FAST)
    if old == "stream_tolerance":
        base["cadence"] = "stream"
    with pytest.warns(DeprecationWarning, match=rf"GraspPositionEnv\({old}=\.\.\.\) is deprecated.*acoustic=") as rec:
        legacy = gym.make("aas_gym/GraspPosition-v0", disable_env_checker=True, acoustic=base or None, **{old: value})
    assert rec[0].filename == __file__  # the warning names the caller's line, not the package's
    modern = _make_quietly("aas_gym/GraspPosition-v0", acoustic={**base, **new})
    assert legacy.unwrapped.acoustic == modern.unwrapped.acoustic != AcousticConfig(**base)  # the keyword took
    assert legacy.observation_space == modern.observation_space
    # the same recording: the setting reached the simulated sensor alike
    a, _ = legacy.reset(seed=2)
    b, _ = modern.reset(seed=2)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])


def test_contact_formation_tolerance_keyword_and_its_default():
    from aas_gym.envs.contact_formation import MOVING_TOLERANCE

    quiet = _make_quietly("aas_gym/ContactFormation-v0", objects=["aluminium_bar"], plinths=["steel_bar"])
    assert quiet.unwrapped.acoustic.stream_tolerance == MOVING_TOLERANCE
    tol = ContactTolerance(force_rtol=0.3)
    with pytest.warns(DeprecationWarning, match=r"ContactFormationEnv\(stream_tolerance=\.\.\.\)"):
        env = gym.make("aas_gym/ContactFormation-v0", objects=["aluminium_bar"], plinths=["steel_bar"],
                       stream_tolerance=tol, disable_env_checker=True)
    assert env.unwrapped.acoustic.stream_tolerance == tol


def test_the_new_spelling_warns_nowhere():
    env = _make_quietly("aas_gym/AcousticGrasp-v0", acoustic=AcousticConfig(excitation="impulse", duration_s=0.5,
                                                                            waveform=True, cadence="every_step"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        env.reset(seed=0)
        env.step(env.action_space.sample())
        assert env.unwrapped.cadence == "every_step" and env.unwrapped.excitation.name == "impulse"


def test_env_properties_with_old_names_warn():
    env = _make_quietly("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "never", "waveform": True}).unwrapped
    with pytest.warns(DeprecationWarning, match="sense_mode is deprecated.*cadence"):
        assert env.sense_mode == env.cadence == "never"
    with pytest.warns(DeprecationWarning, match="include_waveform is deprecated.*acoustic.waveform"):
        assert env.include_waveform


def test_a_legacy_keyword_that_contradicts_acoustic_is_refused_and_an_unknown_one_too():
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="contradicts"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"excitation": "linear"}, excitation="impulse")
    with pytest.raises(TypeError, match="unexpected keyword argument 'sample_rate'"):
        gym.make("aas_gym/AcousticGrasp-v0", sample_rate=44100)
    with pytest.raises(TypeError, match="acoustic has no field"):
        gym.make("aas_gym/AcousticGrasp-v0", acoustic={"sense_mode": "never"})


def test_real_env_keywords_warn_and_equal_the_acoustic_fields():
    from real.env import RealGraspEnv
    from test_real_env import CommandLog, Recorder

    old = {"excitation": "impulse", "duration_s": 0.5, "include_waveform": True, "sense_mode": "every_step"}
    with pytest.warns(DeprecationWarning) as rec:
        a = RealGraspEnv(CommandLog(), Recorder(), **old)
    assert sorted(str(w.message).split("(")[1].split("=")[0] for w in rec) == sorted(old)
    assert all(w.filename == __file__ for w in rec)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        b = RealGraspEnv(CommandLog(), Recorder(), acoustic={"excitation": "impulse", "duration_s": 0.5,
                                                                 "waveform": True, "cadence": "every_step"})
    assert a.acoustic == b.acoustic and a.observation_space == b.observation_space
    with pytest.warns(DeprecationWarning, match="RealGraspEnv.sense_mode"):
        assert a.sense_mode == "every_step"
    with pytest.raises(TypeError, match="unexpected keyword argument 'leak'"):
        RealGraspEnv(CommandLog(), Recorder(), leak=None)


@pytest.mark.parametrize("name", ["spectral_features", "amplitude_spectrum"])
def test_fs_keyword_of_the_feature_functions(name):
    func = getattr(sensors, name)
    ex = sensors.Excitation.by_name("linear", sample_rate_hz=22050)
    with pytest.warns(DeprecationWarning, match=rf"{name}\(fs=\.\.\.\) is deprecated.*sample_rate_hz="):
        old = func(ex.signal, fs=22050)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        new = func(ex.signal, sample_rate_hz=22050)
    if name == "amplitude_spectrum":  # (frequencies, amplitude)
        old, new = np.concatenate(old), np.concatenate(new)
    np.testing.assert_array_equal(old, new)
    with pytest.raises(TypeError, match="both fs= and sample_rate_hz="):
        func(ex.signal, fs=22050, sample_rate_hz=22050)


def test_fs_keyword_of_segment_and_the_transformer():
    from sensors.signals.features import segment

    wave = np.arange(44100.0)
    with pytest.warns(DeprecationWarning, match=r"segment\(fs=\.\.\.\)"):
        old = segment(wave, fs=22050)
    np.testing.assert_array_equal(old, segment(wave, 22050))
    with pytest.warns(DeprecationWarning, match=r"SpectralFeatures.__init__\(fs=\.\.\.\)"):
        t = sensors.SpectralFeatures(fs=22050)
    assert t.get_params() == sensors.SpectralFeatures(sample_rate_hz=22050).get_params()
