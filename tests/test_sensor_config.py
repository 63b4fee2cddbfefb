"""The acoustic sensor as a robot-learning user configures it (issue 32): feature modes
(fft140, spectrogram, mel), history, update period and the corruption pipeline with its noise
library; each option's shapes, seeded determinism, check_env, and the same corruption on
``real.RealGraspEnv`` over the loopback as in simulation."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import aas_gym  # noqa: F401  (registers the envs)
from sensors.signals.corruption import (BackgroundNoise, Clipping, CorruptionPipeline, DCOffset, DroppedBuffers,
                                        GainDrift, Latency)
from sensors.signals.noise_library import NOISE_KINDS, load_noise_folder, noise_segment, synthesize_noise
from sensors.signals.spectrogram import (HOP_SAMPLES, N_FFT, hz_to_mel, mel_filterbank, mel_frequencies_hz,
                                         mel_to_hz, n_frames, spectrogram, spectrogram_frequencies_hz)
from sensors.task import AcousticConfig

FS = 44100


def _rng(seed=0):
    return np.random.default_rng(seed)


def _signal(n=FS, seed=0):
    return 0.3 * _rng(seed).standard_normal(n)


# --- each corruption's defining property ------------------------------------------------------
def test_clipping_bounds_the_samples_and_keeps_the_rest():
    x = 2.0 * _signal()
    y = Clipping(full_scale=0.5).apply(x, FS, _rng())
    assert y.max() == 0.5 and y.min() == -0.5
    inside = np.abs(x) < 0.5
    assert np.array_equal(y[inside], x[inside])


def test_dc_offset_moves_the_mean_by_the_offset():
    x = _signal()
    y = DCOffset(offset_fs=0.02).apply(x, FS, _rng())
    assert np.mean(y) - np.mean(x) == pytest.approx(0.02, abs=1e-12)
    drawn = [np.mean(DCOffset(offset_std_fs=0.01).apply(x, FS, _rng(s)) - x) for s in range(400)]
    assert np.std(drawn) == pytest.approx(0.01, rel=0.15) and abs(np.mean(drawn)) < 0.002


def test_dropped_buffers_are_whole_buffers_of_zeros():
    x = _signal() + 1.0  # no sample of the signal is 0
    stage = DroppedBuffers(probability=0.3, buffer_samples=441)
    y = stage.apply(x, FS, _rng(3))
    buffers_x, buffers_y = x.reshape(-1, 441), y.reshape(-1, 441)
    dropped = ~buffers_y.any(axis=1)
    assert np.array_equal(buffers_y[~dropped], buffers_x[~dropped])  # the rest untouched
    assert 0.15 < dropped.mean() < 0.45  # 100 buffers at p = 0.3
    assert not DroppedBuffers(probability=1.0).apply(x, FS, _rng()).any()
    assert np.array_equal(DroppedBuffers(probability=0.0).apply(x, FS, _rng()), x)


def test_latency_shifts_by_its_samples_and_jitter_stays_in_range():
    x = np.zeros(4000)
    x[100] = 1.0
    y = Latency(latency_s=0.01).apply(x, FS, _rng())
    assert int(np.argmax(y)) == 100 + 441 and y.size == x.size and not y[:541].any()
    shifts = {int(np.argmax(Latency(latency_s=0.01, jitter_s=0.002).apply(x, FS, _rng(s)))) - 100 for s in range(50)}
    assert min(shifts) >= 441 and max(shifts) <= 441 + 88 and len(shifts) > 10


def test_gain_drift_is_linear_in_db_within_its_slope():
    x = np.ones(FS)
    y = GainDrift(drift_db_per_s=2.0).apply(x, FS, _rng(5))
    db = 20 * np.log10(y)
    slope = np.polyfit(np.arange(FS) / FS, db, 1)[0]
    assert db[0] == pytest.approx(0.0, abs=1e-9) and abs(slope) <= 2.0 and abs(slope) > 0
    assert np.allclose(np.diff(db, 2), 0.0, atol=1e-9)  # a straight line in dB
    steady = GainDrift(gain_std_db=3.0).apply(x, FS, _rng(5))
    assert np.allclose(steady, steady[0]) and steady[0] != 1.0


@pytest.mark.parametrize("source", NOISE_KINDS)
def test_background_noise_adds_its_level(source):
    x = _signal()
    y = BackgroundNoise(level_dbfs=-40.0, source=source).apply(x, FS, _rng())
    rms = np.sqrt(np.mean((y - x) ** 2))
    assert 20 * np.log10(rms) == pytest.approx(-40.0, abs=1e-6)


# --- the noise library's documented spectra -------------------------------------------------------
def _band_psd(x, lo, hi):
    from scipy.signal import welch

    f, p = welch(x, FS, nperseg=8192)
    return float(np.mean(p[(f >= lo) & (f < hi)]))


def _band_ratio_db(psd, band, ref):
    """The documented PSD's mean over ``band`` relative to ``ref`` [dB], on a fine grid."""
    mean = [np.mean(psd(np.linspace(lo, hi, 1000))) for lo, hi in (band, ref)]
    return 10 * np.log10(mean[0] / mean[1])


@pytest.mark.parametrize("kind, psd", [
    ("white", lambda f: np.ones_like(f)),
    ("pink", lambda f: 1 / f),
    ("room", lambda f: 1 / f / (1 + (f / 4000) ** 2) ** 2),  # pink through a 2nd-order low-pass at 4 kHz
])
def test_synthesized_spectra_are_the_documented_ones(kind, psd):
    x = synthesize_noise(kind, 8 * FS, FS, _rng())
    ref = (250, 500)
    for band in ((1000, 2000), (4000, 8000), (8000, 16000)):
        measured = 10 * np.log10(_band_psd(x, *band) / _band_psd(x, *ref))
        assert measured == pytest.approx(_band_ratio_db(psd, band, ref), abs=0.5), band


def test_motor_noise_is_a_harmonic_series_plus_whine():
    from scipy.signal import welch

    x = synthesize_noise("motor", 4 * FS, FS, _rng(2))
    f, p = welch(x, FS, nperseg=16384)
    low = (f > 90) & (f < 310)
    f0 = f[low][np.argmax(p[low])]  # the fundamental is the strongest line in 100-300 Hz
    assert 100 <= f0 <= 300 * 1.01
    k2 = np.argmin(abs(f - 2 * f0))
    between = np.argmin(abs(f - 1.5 * f0))
    assert p[k2 - 2:k2 + 3].max() > 30 * p[between]  # a line at 2 f0, not between the harmonics
    assert _band_psd(x, 3000, 7000) > 10 * _band_psd(x, 11000, 20000)  # the 2-8 kHz whine


def test_a_folder_of_recordings_is_resampled_and_looped(tmp_path):
    from scipy.io import wavfile

    t = np.arange(22050) / 22050
    wavfile.write(tmp_path / "a.wav", 22050, (8000 * np.sin(2 * np.pi * 440 * t)).astype(np.int16))
    np.savez(tmp_path / "b.npz", waveform=0.1 * _signal(1000), sample_rate_hz=FS)
    recs = load_noise_folder(tmp_path, FS)
    assert [r.size for r in recs] == [FS, 1000]
    assert all(np.sqrt(np.mean(r ** 2)) == pytest.approx(1.0) for r in recs)
    seg = noise_segment(str(tmp_path), 5000, FS, _rng(1))  # longer than b.npz: looped
    assert seg.size == 5000 and np.sqrt(np.mean(seg ** 2)) == pytest.approx(1.0)
    with pytest.raises(FileNotFoundError):
        load_noise_folder(tmp_path / "missing", FS)


# --- the pipeline ----------------------------------------------------------------------------
def test_pipeline_composes_in_order_and_reads_dicts():
    x = _signal()
    a = CorruptionPipeline.coerce([{"kind": "dc_offset", "offset_fs": 0.5}, {"kind": "clipping", "full_scale": 0.6}])
    b = CorruptionPipeline((Clipping(0.6), DCOffset(0.5)))
    assert a.apply(x, FS, _rng()).max() == pytest.approx(0.6)       # offset, then clipped
    assert b.apply(x, FS, _rng()).max() == pytest.approx(1.1)       # clipped, then offset
    assert CorruptionPipeline.coerce(a.to_list()) == a
    with pytest.raises(ValueError, match="kind"):
        CorruptionPipeline.coerce([{"kind": "reverb"}])
    with pytest.raises(ValueError):
        DroppedBuffers(probability=1.5)


def test_bad_stage_values_are_refused_when_configured(tmp_path):
    """Before any recording: a misspelt noise kind, a missing or empty folder, a misspelt field."""
    (tmp_path / "empty").mkdir()
    for source, match in (("pinkk", "neither"), (str(tmp_path / "missing"), "neither"),
                          (str(tmp_path / "empty"), "no .wav or .npz")):
        with pytest.raises(ValueError, match=match):
            AcousticConfig(corruption=[{"kind": "background_noise", "source": source}])
        with pytest.raises(ValueError, match=match):
            gym.make("aas_gym/GraspPosition-v0", acoustic={"corruption": [{"kind": "background_noise", "source": source}]})
        with pytest.raises(ValueError, match=match):
            BackgroundNoise(-60.0, source)
    with pytest.raises(TypeError, match=r"no field\(s\) \['fullscale'\]; its fields: \['full_scale'\]"):
        AcousticConfig(corruption=[{"kind": "clipping", "fullscale": 0.5}])
    np.savez(tmp_path / "empty" / "n.npz", waveform=_signal(100), sample_rate_hz=FS)
    assert BackgroundNoise(-60.0, tmp_path / "empty").source == str(tmp_path / "empty")  # a folder with a recording


def test_pipeline_is_seeded_by_its_generator():
    p = CorruptionPipeline((BackgroundNoise(-50, "motor"), GainDrift(1.0, 1.0), DroppedBuffers(0.2), Latency(0, 0.01)))
    x = _signal()
    assert np.array_equal(p.apply(x, FS, _rng(1)), p.apply(x, FS, _rng(1)))
    assert not np.allclose(p.apply(x, FS, _rng(1)), p.apply(x, FS, _rng(2)))


# --- spectrogram and mel ---------------------------------------------------------------------
def test_spectrogram_axis_shape_and_amplitude():
    f = spectrogram_frequencies_hz(FS)
    assert f.size == 163 and f[0] >= 3000 and f[-1] < 10000 and np.allclose(np.diff(f), FS / N_FFT)
    assert n_frames(FS) == 1 + (FS - N_FFT) // HOP_SAMPLES == 85
    t = np.arange(FS) / FS
    s = spectrogram(0.25 * np.sin(2 * np.pi * f[40] * t), FS)
    assert s.shape == (85, 163) and np.allclose(s[:, 40], 0.25, rtol=1e-6)  # a sine on a bin reads its amplitude


def test_mel_filterbank_follows_the_htk_formula():
    assert hz_to_mel(1000.0) == pytest.approx(1000.0, abs=0.1)  # HTK: 1000 Hz is ~1000 mel
    assert hz_to_mel(700.0) == pytest.approx(2595 * np.log10(2))
    assert mel_to_hz(hz_to_mel(5432.1)) == pytest.approx(5432.1)
    centres = mel_frequencies_hz()
    assert centres.size == 64 and np.allclose(np.diff(hz_to_mel(centres)), (hz_to_mel(10000) - hz_to_mel(3000)) / 65)
    fb = mel_filterbank(FS, n_fft=1 << 16)  # fine bins: triangles sampled densely
    f = np.fft.rfftfreq(1 << 16, 1 / FS)
    for m in (0, 31, 63):
        support = f[fb[m] > 0]
        edges = mel_to_hz(hz_to_mel(3000) + (np.array([m, m + 2])) * (hz_to_mel(10000) - hz_to_mel(3000)) / 65)
        assert support[0] >= edges[0] and support[-1] <= edges[1]
        assert fb[m].max() == pytest.approx(1.0, abs=0.02) and f[np.argmax(fb[m])] == pytest.approx(centres[m], abs=1)
        # the triangle written from the HTK formula itself, edge to centre to edge
        mel = lambda hz: 2595 * np.log10(1 + hz / 700)  # noqa: E731
        hz = lambda m_: 700 * (10 ** (m_ / 2595) - 1)  # noqa: E731
        e0, c, e2 = hz(mel(3000) + np.array([m, m + 1, m + 2]) * (mel(10000) - mel(3000)) / 65)
        triangle = np.clip(np.where(f < c, (f - e0) / (c - e0), (e2 - f) / (e2 - c)), 0, None)
        assert np.allclose(fb[m], triangle, atol=1e-9)
    inner = (f >= centres[0]) & (f <= centres[-1])
    assert np.allclose(fb.sum(axis=0)[inner], 1.0)  # neighbouring triangles add to one
    assert (mel_filterbank(FS).sum(axis=1) > 0).all()  # no empty band at the default 1024 bins


# --- the options in the envs -------------------------------------------------------------------
def _make(env_id, **acoustic):
    return gym.make(env_id, acoustic=acoustic, randomization=False).unwrapped


@pytest.mark.parametrize("features, shape", [("fft140", (140,)), ("spectrogram", (85, 163)), ("mel", (85, 64))])
@pytest.mark.parametrize("history", [1, 3])
def test_feature_modes_and_history_have_fixed_shapes_and_pass_check_env(features, shape, history):
    env = _make("aas_gym/GraspPosition-v0", features=features, history=history, feature_scale="db")
    want = shape if history == 1 else (history, *shape)
    assert env.observation_space["acoustic"].shape == want
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # infinite Box bounds: features in dB have none
        check_env(env, skip_render_check=True)
    a, _ = env.reset(seed=4)
    b, _ = env.reset(seed=4)
    assert a["acoustic"].shape == want and env.observation_space.contains(a)
    assert np.array_equal(a["acoustic"], b["acoustic"])
    if history > 1:
        # the reset's recording last, the older frames silence (-60 dB, the scale's floor)
        assert np.all(a["acoustic"][:-1] == -60.0) and not np.all(a["acoustic"][-1] == -60.0)


@pytest.mark.parametrize("acoustic", [{"features": "spectrogram"}, {"features": "mel", "history": 2, "feature_scale": "db"},
                                      {"corruption": [{"kind": "clipping", "full_scale": 0.5}]}])
def test_stable_baselines3_check_env_accepts_the_options(acoustic):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sb3_checker.check_env(gym.make("aas_gym/GraspPosition-v0", acoustic=acoustic, randomization=False))


def test_history_is_oldest_first_and_shifts_by_one_frame():
    env = _make("aas_gym/AcousticGrasp-v0", cadence="every_step", history=3, duration_s=0.5, noise_std=1e-5)
    obs, _ = env.reset(seed=0)
    assert obs["acoustic"].shape == (3, 140) and not obs["acoustic"].any()
    frames = []
    for _ in range(4):
        obs, *_ = env.step(np.zeros(6, np.float32))
        frames.append(obs["acoustic"][-1].copy())
        assert env.observation_space.contains(obs)
    assert np.array_equal(obs["acoustic"], np.stack(frames[-3:]))  # the last three, oldest first
    assert len({f.tobytes() for f in frames}) == 4  # each step recorded anew (noise)


def test_update_period_holds_the_value_between_updates():
    env = _make("aas_gym/AcousticGrasp-v0", cadence="every_step", update_period_s=0.15, duration_s=0.5, noise_std=1e-5)
    assert env.acoustic_frames.steps_per_update == 3  # 0.15 s at dt = 0.05 s
    env.reset(seed=0)
    seen = [env.step(np.zeros(6, np.float32))[0]["acoustic"] for _ in range(7)]
    same = [np.array_equal(seen[i], seen[i - 1]) for i in range(1, 7)]
    assert same == [True, True, False, True, True, False]  # updates at steps 0, 3, 6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)


def test_streamed_history_and_update_period():
    """Streamed (ContactFormation-v0): ``audio`` and ``acoustic`` stacked, updated every
    other step (0.1 s at dt = 0.05 s), the history shifting by one frame at each update."""
    env = gym.make("aas_gym/ContactFormation-v0", acoustic={"history": 2, "update_period_s": 0.1}).unwrapped
    assert env.observation_space["audio"].shape == (2, 2205) and env.observation_space["acoustic"].shape == (2, 140)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    prev, _ = env.reset(seed=0)
    for i in range(6):
        obs, *_ = env.step(0)
        assert env.observation_space.contains(obs)
        if i % 2 == 0:  # an update: the newest frame moved one place back
            assert np.array_equal(obs["audio"][0], prev["audio"][1]) and obs["audio"][1].any()
        else:
            assert np.array_equal(obs["audio"], prev["audio"]) and np.array_equal(obs["acoustic"], prev["acoustic"])
        prev = obs


@pytest.mark.parametrize("period", ["0.05", "0.15", "0.07", "0.12", "0.03", "0.35"])
def test_update_schedule_keeps_the_period_in_simulated_time(period):
    """The steps that update, against exact rational arithmetic: the due times m * T fall in
    the steps floor(m * T / dt) (T = 0.07 s at dt = 0.05 s: steps 0, 1, 2, 4, 5, 7, 8, ...)."""
    from fractions import Fraction

    from sensors.task.frames import AcousticFrames

    dt, n_steps = "0.05", 400
    ratio = Fraction(period) / Fraction(dt)
    want = sorted({int(m * ratio) for m in range(int(n_steps / ratio) + 2)} & set(range(n_steps)))
    config = AcousticConfig(cadence="every_step", update_period_s=float(period))
    frames = AcousticFrames({"acoustic": np.zeros(1)}, 1, config.steps_per_update(float(dt)))
    for _ in range(2):  # a reset starts the schedule again
        frames.reset()
        assert [n for n in range(n_steps) if frames.due()] == want
    if ratio.denominator == 1:
        assert config.steps_per_update(float(dt)) == ratio  # every k-th step, a whole number


def test_a_period_that_is_no_multiple_of_dt_updates_at_its_mean_rate():
    env = _make("aas_gym/AcousticGrasp-v0", cadence="every_step", update_period_s=0.07, duration_s=0.5, noise_std=1e-5)
    env.reset(seed=0)
    seen = [env.step(np.zeros(6, np.float32))[0]["acoustic"] for _ in range(9)]
    same = [np.array_equal(seen[i], seen[i - 1]) for i in range(1, 9)]
    assert same == [False, False, True, False, False, True, False, False]  # updates at steps 0, 1, 2, 4, 5, 7, 8


def test_update_period_is_checked_against_the_cadence():
    with pytest.raises(ValueError, match="cadence"):
        AcousticConfig(update_period_s=0.1)  # cadence "action": the policy decides
    with pytest.raises(ValueError, match="probe"):
        _make("aas_gym/GraspPosition-v0", cadence="every_step", update_period_s=0.1)
    with pytest.raises(ValueError, match="stream"):
        AcousticConfig(cadence="stream", features="mel")


CORRUPTION = [{"kind": "background_noise", "level_dbfs": -80.0, "source": "motor"},
              {"kind": "gain_drift", "gain_std_db": 1.0, "drift_db_per_s": 0.5},
              {"kind": "dc_offset", "offset_std_fs": 1e-3}, {"kind": "clipping", "full_scale": 1.0},
              {"kind": "dropped_buffers", "probability": 0.05}, {"kind": "latency", "jitter_s": 0.005}]


def test_corruption_is_seeded_and_separate_from_the_clean_stream():
    clean = _make("aas_gym/GraspPosition-v0", waveform=True)
    noisy = _make("aas_gym/GraspPosition-v0", waveform=True, corruption=CORRUPTION)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(noisy, skip_render_check=True)
    c1, info_c = clean.reset(seed=1, options={"position_index": 4})
    n1, info_n = noisy.reset(seed=1, options={"position_index": 4})
    n1b, _ = noisy.reset(seed=1, options={"position_index": 4})
    n2, _ = noisy.reset(seed=2, options={"position_index": 4})
    c2, _ = clean.reset(seed=2, options={"position_index": 4})
    assert np.array_equal(n1["acoustic"], n1b["acoustic"])          # same seed, same corruption
    assert np.array_equal(c1["acoustic"], c2["acoustic"])           # the clean recording does not depend on it ...
    assert not np.allclose(n1["waveform"], n2["waveform"])           # ... the corruption does
    assert np.array_equal(c1["tcp"], n1["tcp"]) and info_c["grasp_position_m"] == info_n["grasp_position_m"]
    assert not np.array_equal(c1["waveform"], n1["waveform"])


# --- the same corruption on the rig ------------------------------------------------------------
def _loopback_available() -> bool:
    try:
        import pyaudio  # noqa: F401
    except ImportError:
        return False
    return Path("/usr/bin/pulseaudio").exists() or bool(os.environ.get("AAS_PULSE_BIN"))


@pytest.mark.audio
@pytest.mark.slow
@pytest.mark.xdist_group("real_audio")
@pytest.mark.skipif(not _loopback_available(), reason="needs PyAudio and PulseAudio (the loopback)")
def test_real_env_corrupts_as_the_simulation_over_the_loopback(audio_loopback):
    import real
    from aas_gym.robot import MujocoRobot
    from real.env import RealGraspEnv

    acoustic = {"duration_s": 0.5, "waveform": True, "features": "mel", "corruption": CORRUPTION}
    robot = MujocoRobot(randomization=False)
    sensor = real.RealAcousticSensor(real.PyAudioRig(output_gain=0.5, frames_per_buffer=4096, stall_timeout_s=5.0))
    env = RealGraspEnv(robot, sensor, acoustic=acoustic)
    sim = gym.make("aas_gym/AcousticGrasp-v0", acoustic=acoustic).unwrapped
    try:
        env.reset(seed=11)
        sim.reset(seed=11)
        # the same generator from the same seed in both envs ...
        assert env.corruption_rng.bit_generator.state == sim.corruption_rng.bit_generator.state
        obs, *_ = env.step(np.array([0, 0, 0, 0, 1, 1], np.float32))  # sense
        recording = env.last_recording  # what the loopback heard, clean
        assert recording.waveform.std() > 1e-3
        # ... and the simulation's pipeline on the same input gives the real env's observation
        expected = sim.acoustic.entries(recording, rng=sim.corruption_rng)
        assert obs["acoustic"].shape == (42, 64) and env.observation_space.contains(obs)
        assert np.array_equal(obs["acoustic"], expected["acoustic"])
        assert np.array_equal(obs["waveform"], expected["waveform"])
        assert not np.allclose(obs["waveform"][:recording.waveform.size], recording.waveform[:obs["waveform"].size])
    finally:
        env.close()
        robot.close()
        sim.close()
