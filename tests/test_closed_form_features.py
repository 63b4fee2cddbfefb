"""Closed-form features (``sensors.synthesis.simulate_features``) against the time-domain chain.

The reference synthesizes every sample (``AcousticStream.synthesize``: fingertip drive, modal
system, from rest or settled), adds the microphone's gain and the same seeded noise, and takes
``sensors.spectral_features``: an independent computation of the same recording.  The
recorded waveform of ``simulate_recording`` is float32; its rounding (5e-8 of the peak) is
the only difference left against it.
"""

import functools

import mujoco
import numpy as np
import pytest

from aas_gym.grasp import planar_grasp
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation, spectral_features
from sensors import synthesis
from sensors.synthesis import AcousticStream, GraspState, SynthesisCache, mic_gain

# The closed form follows the piecewise-linear drive ("foh"); with the band-limited drive (the
# default) simulate_features synthesizes (tests/test_bandlimited_drive.py covers that drive).
simulate_features = functools.partial(synthesis.simulate_features, bandlimited=False)
simulate_recording = functools.partial(synthesis.simulate_recording, bandlimited=False)

OBJECTS = ("aluminium_bar", "wood_bar", "abs_bar", "aluminium_tube")


@pytest.fixture(scope="module", params=OBJECTS)
def grasp(request):
    """(modal model, actuator contact, mic contact, table contacts) of a 40 N grasp 30 mm from
    the centre of the object lying on the table."""
    name = request.param
    model = build_scene([name])
    data = mujoco.MjData(model)
    planar_grasp(model, data, name, 0.03, 40.0)
    sensor = SimAcousticSensor(model, data)
    body, act, mic, others = sensor.grasp_contacts()
    assert others, "the object lies on the table: it has table contacts"
    return sensor.modal_model(body), act, mic, others


def time_domain_features(model, excitation, duration_s, act, mic, others, noise_std, seed, steady):
    """Features of the sample-by-sample chain in float64 (no float32 recording)."""
    n = len(excitation.loop(duration_s))
    stream = AcousticStream(excitation, carry_state=False, bandlimited=False)
    g = GraspState(model, act, mic, tuple(others))
    if steady:
        stream.settle(g)
    wave = mic_gain("displacement") * stream.synthesize(n, g)
    if noise_std > 0:
        wave = wave + noise_std * np.random.default_rng(seed).standard_normal(n)
    return spectral_features(wave, excitation.sample_rate_hz, period_s=excitation.period_s, average=False)


@pytest.mark.parametrize("excitation", ["linear", "impulse", "exponential"])
@pytest.mark.parametrize("with_others", [True, False])
@pytest.mark.parametrize("noise_std", [0.0, 1e-4])
@pytest.mark.parametrize("steady", [False, True])
def test_closed_form_equals_time_domain(grasp, excitation, with_others, noise_std, steady):
    model, act, mic, others = grasp
    others = others if with_others else ()
    ex = Excitation.by_name(excitation)
    fast = simulate_features(model, ex, 1.0, act, mic, others, noise_std=noise_std, rng=7, steady_state=steady)
    assert fast.metadata["features_path"] == "closed_form"
    got = fast.features(average=False)
    want = time_domain_features(model, ex, 1.0, act, mic, others, noise_std, 7, steady)
    assert got.shape == want.shape == (2, 140)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    # the float32 recording: equal up to its rounding, at most 2^-24 |x[n]| per sample, so per
    # window at most 2/P sum |x| 2^-24 on every feature (rigorous bound)
    rec = simulate_recording(model, ex, 1.0, act, mic, others, noise_std=noise_std, rng=7, steady_state=steady)
    ref = rec.features(average=False)
    P = ex.period_samples
    bound = 2.0 / P * np.abs(rec.waveform.astype(float)).reshape(2, P).sum(axis=1) * 2.0**-24 * 1.01
    assert np.all(np.abs(got - ref) <= bound[:, None] + 1e-6 * np.abs(want))


def test_same_seed_same_features_and_generator(grasp):
    """Reproducible bit for bit within the path, and the generator advances as the
    time-domain chain advances it (the next draws agree)."""
    model, act, mic, others = grasp
    ex = Excitation.by_name("linear")
    cache = SynthesisCache()
    r1, r2, r3 = (np.random.default_rng(3) for _ in range(3))
    a = simulate_features(model, ex, 1.0, act, mic, others, noise_std=1e-4, rng=r1, cache=cache).features()
    b = simulate_features(model, ex, 1.0, act, mic, others, noise_std=1e-4, rng=r2).features()
    assert np.array_equal(a, b)
    simulate_recording(model, ex, 1.0, act, mic, others, noise_std=1e-4, rng=r3)
    assert r1.random() == r3.random()


def test_nothing_grasped_is_noise_only():
    ex = Excitation.by_name("linear")
    fast = simulate_features(None, ex, 1.0, None, None, noise_std=1e-4, rng=5)
    ref = simulate_recording(None, ex, 1.0, None, None, noise_std=1e-4, rng=5).features()
    np.testing.assert_allclose(fast.features(), ref, rtol=1e-5)  # float32 recording of pure noise


def test_leak_takes_the_time_domain_chain(grasp):
    """A leak is aligned to the synthesized signal's excitation peak: features come from the
    samples (and say so)."""
    from sensors import LeakRecording

    model, act, mic, others = grasp
    ex = Excitation.by_name("linear")
    leak = LeakRecording(1e-3 * np.tile(ex.signal, 2).astype(np.float32), ex.sample_rate_hz, ex.to_dict(), {})
    fast = simulate_features(model, ex, 1.0, act, mic, others, leak=leak)
    assert fast.metadata["features_path"] == "time_domain"
    ref = simulate_recording(model, ex, 1.0, act, mic, others, leak=leak).features()
    assert np.array_equal(fast.features(), ref)


def test_window_spectra_of_any_lti_system():
    """The closed form needs only a system's poles, input and output vectors: a small random
    stable system with a direct term, driven by a periodic input plus decaying exponentials
    from rest, against its sampled response; a dense (matrix-exponential) system is refused."""
    from sensors.synthesis.lti import lti_system
    from sensors.synthesis.window_spectra import Exponentials, window_spectra

    rng = np.random.default_rng(0)
    n, P, W = 6, 400, 3
    A = rng.standard_normal((n, n)) * 2000.0 - 3000.0 * np.eye(n)
    B, C = rng.standard_normal(n), rng.standard_normal(n)
    system = lti_system(A, B, C, 0.3, 44100)
    period = rng.standard_normal(P)
    s = np.array([-0.01 + 0.2j, -0.01 - 0.2j, -0.003 + 0j])
    g = np.array([0.5 - 0.1j, 0.5 + 0.1j, 0.7 + 0j])
    transient = Exponentials(g, s)
    u = np.tile(period, W) + np.array([transient.at(k) for k in range(W * P)])
    y = system.response(u)
    bins = np.arange(1, P // 2, 7)
    want = np.fft.rfft(y.reshape(W, P), axis=1)[:, bins]
    got = window_spectra(system, period, transient, bins, W)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    dense = lti_system(A, B, C, 0.3, 44100, method="dense")
    assert window_spectra(dense, period, transient, bins, W) is None
