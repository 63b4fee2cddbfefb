"""The corruption pipeline on a stream (issue 32): chunk by chunk gives exactly what the
whole stream at once gives, stage by stage against the whole-recording stages
(``sensors.signals.corruption``); background noise, which a stream of unknown length cannot
draw at once, block by block; and the streamed envs observe the corrupted stream, seeded."""

from __future__ import annotations

import copy
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import aas_gym  # noqa: F401  (registers the envs)
from sensors.signals import (NOISE_BLOCK_S, BackgroundNoise, Clipping, CorruptedStream, CorruptionPipeline, DCOffset,
                             DroppedBuffers, GainDrift, Latency, StreamCorruptor, spectral_features)

FS = 44100

STAGES = [GainDrift(gain_std_db=3.0, drift_db_per_s=2.0), DCOffset(offset_fs=0.01, offset_std_fs=0.02),
          Latency(latency_s=0.01, jitter_s=0.02), DroppedBuffers(probability=0.4, buffer_samples=700),
          Clipping(full_scale=0.4)]


def _chunked(process, x: np.ndarray, seed: int) -> np.ndarray:
    """``x`` through ``process`` in random chunks (0 to 3000 samples, empty ones included)."""
    sizes = np.random.default_rng(seed).integers(0, 3000, 200)
    bounds = np.minimum(np.concatenate([[0], np.cumsum(sizes)]), x.size)
    out = [process(x[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
    if bounds[-1] < x.size:
        out.append(process(x[bounds[-1]:]))
    return np.concatenate(out)


def _signal(n: int = 3 * FS + 123) -> np.ndarray:
    return 0.3 * np.random.default_rng(7).standard_normal(n)


@pytest.mark.parametrize("stage", STAGES, ids=lambda s: type(s).__name__)
@pytest.mark.parametrize("chunk_seed", [0, 1])
def test_each_stage_chunked_equals_its_whole_recording_form(stage, chunk_seed):
    x = _signal()
    corruptor = StreamCorruptor(CorruptionPipeline((stage,)), FS, np.random.default_rng(5))
    got = _chunked(corruptor.process, x, chunk_seed)
    # the whole-recording stage with the stage's own generator (spawned first from the same seed)
    want = stage.apply(x, FS, np.random.default_rng(5).spawn(1)[0])
    assert np.array_equal(got, want)
    assert not np.array_equal(got, x)


def test_latency_delays_across_chunks_with_silence_first():
    stage = Latency(latency_s=0.05)  # 2205 samples: longer than most chunks
    x = _signal() + 1.0  # no sample is 0
    got = _chunked(StreamCorruptor(CorruptionPipeline((stage,)), FS, np.random.default_rng(0)).process, x, 3)
    assert not got[:2205].any() and np.array_equal(got[2205:], x[:-2205])


def test_dropped_buffers_lie_on_the_absolute_grid():
    x = _signal() + 1.0
    got = _chunked(StreamCorruptor(CorruptionPipeline((DroppedBuffers(0.5, 441),)), FS,
                                   np.random.default_rng(2)).process, x, 4)
    n = x.size // 441 * 441
    blocks_x, blocks = x[:n].reshape(-1, 441), got[:n].reshape(-1, 441)
    dropped = ~blocks.any(axis=1)
    assert np.array_equal(blocks[~dropped], blocks_x[~dropped]) and 0.3 < dropped.mean() < 0.7


@pytest.mark.parametrize("source", ["white", "motor"])
def test_background_noise_streams_in_blocks_the_same_whatever_the_chunks(source):
    stage = BackgroundNoise(level_dbfs=-20.0, source=source)
    pipeline = CorruptionPipeline((stage,))
    zeros = np.zeros(int(2.5 * NOISE_BLOCK_S * FS))
    one_call = StreamCorruptor(pipeline, FS, np.random.default_rng(9)).process(zeros)
    chunked = _chunked(StreamCorruptor(pipeline, FS, np.random.default_rng(9)).process, zeros, 5)
    assert np.array_equal(chunked, one_call)
    assert np.array_equal(one_call, StreamCorruptor.whole(pipeline, zeros, FS, np.random.default_rng(9)))
    block = int(NOISE_BLOCK_S * FS)
    # each block is a fresh draw of the whole-recording stage over the block's length
    g = np.random.default_rng(9).spawn(1)[0]
    for k in range(2):
        assert np.array_equal(one_call[k * block:(k + 1) * block], stage.apply(np.zeros(block), FS, g))
        assert np.sqrt(np.mean(one_call[k * block:(k + 1) * block] ** 2)) == pytest.approx(0.1, rel=1e-9)
    assert not np.allclose(one_call[:100], one_call[block:block + 100])


def test_pipeline_chunked_equals_whole_and_period_features_are_of_the_corrupted_stream():
    stages = (BackgroundNoise(level_dbfs=-40.0, source="room"),) + tuple(STAGES)
    x = _signal()
    P = 22050
    stream = CorruptedStream(CorruptionPipeline(stages), FS, np.random.default_rng(1), P, 0.5)
    got, feats = [], []
    sizes = np.random.default_rng(6).integers(1, 5000, 400)
    pos = 0
    for n in sizes:
        if pos >= x.size:
            break
        got.append(stream.process(x[pos:pos + n]))
        pos += n
        feats.append((stream.latest_features_period, stream.latest_features()))
    got = np.concatenate(got)
    want = StreamCorruptor.whole(CorruptionPipeline(stages), x, FS, np.random.default_rng(1))
    assert np.array_equal(got, want)
    for k, f in feats:
        if k < 0:
            assert f is None
        else:
            assert np.array_equal(f, spectral_features(want[k * P:(k + 1) * P], FS, period_s=0.5))
    assert feats[-1][0] == x.size // P - 1


# --- the streamed envs --------------------------------------------------------------------------
CORRUPTION = [{"kind": "background_noise", "level_dbfs": -50.0, "source": "motor"},
              {"kind": "gain_drift", "gain_std_db": 1.0, "drift_db_per_s": 0.5},
              {"kind": "dc_offset", "offset_std_fs": 1e-3}, {"kind": "clipping", "full_scale": 1.0},
              {"kind": "dropped_buffers", "probability": 0.05}, {"kind": "latency", "jitter_s": 0.005}]


def _episode(env, seed, n_steps=25):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(n_steps):
        out.append(env.step(0)[0])
    return out


def test_streamed_contact_formation_is_corrupted_seeded_and_passes_check_env():
    clean = gym.make("aas_gym/ContactFormation-v0").unwrapped
    noisy = gym.make("aas_gym/ContactFormation-v0", acoustic={"corruption": CORRUPTION}).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(noisy, skip_render_check=True)
    a = _episode(noisy, 3)
    noisy.reset(seed=3)
    expected = copy.deepcopy(noisy.stream_corruption)  # the corruption as the stream starts
    b = _episode(noisy, 3)
    c = _episode(clean, 3)
    for oa, ob in zip(a, b):  # a seed reproduces the corrupted stream bit for bit
        assert all(np.array_equal(oa[k], ob[k]) for k in oa)
    # the corrupted observation is the clean stream through the pipeline, chunk by chunk
    for oc, on in list(zip(c, b))[1:]:
        assert np.array_equal(oc["tcp"], on["tcp"])  # the clean episode is unchanged
        audio = expected.process(oc["audio"].astype(np.float64)).astype(np.float32)
        assert np.array_equal(on["audio"], audio)
        f = expected.latest_features()
        assert np.array_equal(on["acoustic"], noisy.acoustic.scale_features(np.zeros(140) if f is None else f))
    assert expected.latest_features_period >= 0 and not np.array_equal(b[-1]["acoustic"], c[-1]["acoustic"])
    assert not np.array_equal(_episode(noisy, 4)[-1]["audio"], b[-1]["audio"])


def test_streamed_acoustic_grasp_with_corruption_passes_check_env():
    env = gym.make("aas_gym/AcousticGrasp-v0", acoustic={"cadence": "stream", "corruption": CORRUPTION}).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.stream_corruption is not None and not obs["audio"].any()


def test_a_streamed_probe_hears_its_hold_corrupted_from_a_fresh_stream():
    """Probe envs stream each probe's hold anew: the hold's audio is the clean hold through a
    new corrupted stream spawned from the episode's corruption generator."""
    acoustic = {"cadence": "stream", "duration_s": 0.5}
    clean = gym.make("aas_gym/ObjectRecognition-v0", acoustic=acoustic).unwrapped
    noisy = gym.make("aas_gym/ObjectRecognition-v0", acoustic=dict(acoustic, corruption=CORRUPTION)).unwrapped
    action = np.array([-1.0, 0.2, 0.0, 0.0], np.float32)  # a probe (command <= 0) with the linear chirp
    clean.reset(seed=2)
    noisy.reset(seed=2)
    expected = noisy.acoustic.corrupted_stream(copy.deepcopy(noisy.corruption_rng))
    oc, on = clean.step(action)[0], noisy.step(action)[0]
    assert oc["audio"].any()                               # the probe held and recorded
    assert np.array_equal(on["audio"], expected.process(oc["audio"].astype(np.float64)).astype(np.float32))
    assert np.array_equal(on["acoustic"], noisy.acoustic.scale_features(expected.latest_features()))
    assert not np.array_equal(on["acoustic"], oc["acoustic"])
