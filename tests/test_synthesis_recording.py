"""Fingertip drive model, leak file and alignment, and the full simulated recording."""

import numpy as np
import pytest

from sensors import AcousticObservation, Contact, Excitation, SynthesisCache
from sensors.synthesis.fingertip import FingertipModel
from sensors.signals.leak import align_leak, load_leak, save_leak
from sensors.synthesis.microphone import mic_gain
from sensors.synthesis.recording import simulate_recording
from synthesis_fakes import BoxModel, grasp

FS = 44100


def test_fingertip_linear_equals_one_sided_integrator_while_in_contact():
    ex = Excitation.linear_sweep()
    e = ex.loop(0.3)
    fm = FingertipModel()
    f, info = fm.contact_force(e, FS, return_info=True)
    assert not info["separated"] and info["min_contact_force_n"] > 0
    g, _, _ = fm.one_sided_forces(fm.actuator_force_n * e, FS)
    assert np.max(np.abs(f - g)) <= 1e-6 * np.max(np.abs(f))


def test_fingertip_internal_force_has_no_static_effect():
    """The exciter pushes its mass against its own housing: a constant exciter force is an
    internal force pair, so once settled it adds no force on the object."""
    fm = FingertipModel()
    f = fm.contact_force(np.ones(FS), FS)
    assert abs(f[-1]) < 1e-6 * np.max(np.abs(f))
    assert np.max(np.abs(f)) > 0.1  # but the switch-on transient does reach the object


def test_fingertip_separates_under_weak_grip():
    fm = FingertipModel(grip_force_n=0.5, actuator_force_n=5.0)
    e = Excitation.linear_sweep().loop(0.5)
    f, info = fm.contact_force(e, FS, return_info=True)
    assert info["separated"]
    assert np.all(np.isfinite(f))
    assert np.min(f) >= -0.5 - 1e-12  # total force f + F_g never pulls (one-sided)
    assert np.any(np.isclose(f, -0.5))  # and really lifts off somewhere


def test_fingertip_bad_parameters():
    with pytest.raises(ValueError):
        FingertipModel(grip_force_n=-1.0)
    with pytest.raises(ValueError):
        FingertipModel(object_mass_kg=0.0)
    for not_finite in (np.nan, np.inf, np.float64(np.nan)):
        with pytest.raises(ValueError):
            FingertipModel(contact_stiffness_n_m=not_finite)


def test_leak_roundtrip_and_alignment(tmp_path):
    ex = Excitation.linear_sweep()
    P = ex.period_samples
    rng = np.random.default_rng(0)
    kernel = rng.normal(size=40) * np.exp(-np.arange(40) / 8)
    one = np.convolve(np.tile(ex.signal, 3), kernel)[P:2 * P]  # periodic leak, aligned at 0
    delay = 1234
    rec = np.concatenate([np.zeros(delay), np.tile(one, 4)])[: 3 * P] * 0.05
    path = save_leak(tmp_path / "leak_linear", rec, FS, ex, {"device": "test"})
    leak = load_leak(path)
    assert leak.sample_rate_hz == FS and leak.metadata == {"device": "test"} and leak.matches(ex)
    np.testing.assert_allclose(leak.waveform, rec.astype(np.float32))
    out = align_leak(leak, ex, 5 * P, target_lag=0)
    ref = np.tile(one, 5) * 0.05
    lag0 = int(np.argmax(np.abs(np.correlate(np.tile(one, 2), ex.signal, "valid"))))
    np.testing.assert_allclose(out, np.roll(ref, -lag0), atol=1e-6)
    with pytest.raises(ValueError, match="not for this excitation"):
        align_leak(leak, Excitation.exponential_sweep(), P)


@pytest.fixture(scope="module")
def grasp_setup():
    m = BoxModel(np.linspace(1500, 20000, 40), "wood")
    dp, dn, mp, mn = grasp(m)
    return m, Contact(dp, dn, 40.0, 0.6), Contact(mp, mn, 40.0, 0.6)


def test_recording_chain(grasp_setup):
    m, act, mic = grasp_setup
    ex = Excitation.exponential_sweep()
    obs = simulate_recording(m, ex, 1.0, act, mic, noise_std=1e-3, rng=7)
    assert isinstance(obs, AcousticObservation)
    assert obs.waveform.dtype == np.float32 and len(obs.waveform) == FS
    assert obs.metadata["source"] == "sim" and obs.metadata["synthesized"]
    # deterministic under the seed; without noise (and with the piecewise-linear drive whose
    # convention contact_force and modal_response share) it is gain * modal response of the
    # fingertip force
    again = simulate_recording(m, ex, 1.0, act, mic, noise_std=1e-3, rng=7)
    assert np.array_equal(obs.waveform, again.waveform)
    clean = simulate_recording(m, ex, 1.0, act, mic, bandlimited=False)
    from sensors import modal_response
    f = FingertipModel().contact_force(ex.loop(1.0), FS)
    # the recording's fingertip contacts carry the pads' springs (FingertipModel.pad)
    pads = [FingertipModel().pad(act), FingertipModel().pad(mic)]
    y = modal_response(m, f, FS, act.position_m, act.normal, mic.position_m, mic.normal, pads)
    np.testing.assert_allclose(clean.waveform, (mic_gain() * y).astype(np.float32), rtol=1e-6, atol=1e-9)
    noise = obs.waveform - simulate_recording(m, ex, 1.0, act, mic).waveform
    assert 0.9e-3 < np.std(noise) < 1.1e-3


def test_no_finger_contact_is_noise_and_leak_only(grasp_setup, tmp_path):
    m, act, mic = grasp_setup
    ex = Excitation.impulse()
    leak_wave = np.roll(np.tile(np.exp(-np.arange(ex.period_samples) / 50.0), 3), 300) * 0.01
    path = save_leak(tmp_path / "leak.npz", leak_wave, FS, ex)
    obs = simulate_recording(m, ex, 0.5, None, mic, leak=path)
    assert not obs.metadata["synthesized"]
    expected = align_leak(load_leak(path), ex, ex.period_samples, target_lag=0)
    np.testing.assert_allclose(obs.waveform, expected, atol=1e-7)
    assert np.argmax(obs.waveform) == 0  # the leak's peak moved to the excitation's start
    lifted = Contact(act.position_m, act.normal, 0.0, 0.5)
    obs2 = simulate_recording(m, ex, 0.5, lifted, mic, noise_std=0.01, rng=1)
    assert abs(np.std(obs2.waveform) - 0.01) < 1e-3


@pytest.mark.parametrize("bandlimited", [False, True])
def test_steady_state_recording_matches_late_time_domain(grasp_setup, bandlimited):
    """To rounding with the piecewise-linear drive; the band-limited drive's time-domain runs
    differ from its exact steady state by the holds' images (sensors.synthesis.bandlimit)."""
    m, act, mic = grasp_setup
    ex = Excitation.linear_sweep()
    ss = simulate_recording(m, ex, 1.0, act, mic, steady_state=True, bandlimited=bandlimited)
    td = simulate_recording(m, ex, 3.0, act, mic, bandlimited=bandlimited)  # wood: transient gone after 2.5 s
    P = ex.period_samples
    np.testing.assert_allclose(td.waveform[-P:], ss.waveform[:P], rtol=0,
                               atol=(2e-3 if bandlimited else 1e-5) * np.abs(ss.waveform).max())


def test_synthesis_cache_reuses_a_grasp_and_stays_bounded(grasp_setup):
    """One grasp heard with two excitations builds its system once; ``maxsize`` bounds what
    is kept; cached and fresh recordings are the same samples."""
    m, act, mic = grasp_setup
    cache = SynthesisCache(maxsize=1)
    lin, imp = Excitation.linear_sweep(), Excitation.impulse()
    a = simulate_recording(m, lin, 0.3, act, mic, cache=cache)
    b = simulate_recording(m, imp, 0.3, act, mic, cache=cache)
    assert cache.systems.misses == 1 and cache.systems.hits == 1
    moved = Contact(act.position_m, act.normal, 30.0, act.friction)
    simulate_recording(m, lin, 0.3, moved, mic, cache=cache)
    assert cache.systems.misses == 2 and cache.systems.size == 1 and len(cache.forces) == 1
    assert np.array_equal(simulate_recording(m, lin, 0.3, act, mic, cache=cache).waveform, a.waveform)
    assert cache.systems.misses == 3          # evicted by the other grasp, built again
    assert np.array_equal(simulate_recording(m, imp, 0.3, act, mic).waveform, b.waveform)
    with pytest.raises(ValueError):
        SynthesisCache(maxsize=0)
