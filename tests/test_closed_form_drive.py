"""The closed-form fingertip drive and the factored window spectra against their reference paths
(``sensors.synthesis.drive_spectrum.CLOSED_FORM_DRIVE``, ``sensors.synthesis.window_spectra.
FACTORED_WINDOWS`` False) and against independent time-domain runs.

- The drive from rest: the reference's steady period (``SteadyState``: FFTs of the period-aliased
  impulse response), transient and separation bound; and, independently, the first-order-hold
  run of the drive over two periods from rest (``DiscreteSystem.response``: power sums and a
  convolution), which must equal steady period + transient sample by sample.
- The window spectra: both evaluations against the sampled response of a random system.
- The features of a grasp through ``simulate_features``: both paths agree to 1e-9 relative.
"""

import mujoco
import numpy as np
import pytest

from sensors import Excitation
from sensors.synthesis import AcousticStream, FingertipModel, simulate_features
from sensors.synthesis import drive_spectrum as drive_module
from sensors.synthesis import window_spectra as window_module
from sensors.synthesis.lti import DiscreteSystem, lti_system
from sensors.signals.features import feature_frequencies_hz
from sensors.synthesis.window_spectra import Exponentials, window_spectra

# the feature frequencies as DFT bins of the default 0.5 s loop at 44.1 kHz (whole bins)
FEATURE_BINS = np.round(feature_frequencies_hz() * 0.5).astype(int)


@pytest.fixture
def reference_drive(monkeypatch):
    def set_reference(on: bool):
        monkeypatch.setattr(drive_module, "CLOSED_FORM_DRIVE", not on)
    return set_reference


def test_drive_modes_are_the_discretised_systems():
    """``FingertipModel.modes`` (the closed form's lean eigen-solve) against ``discretised``:
    the same poles, and the same sampled response of both outputs to a random force."""
    tip = FingertipModel(object_mass_kg=0.4, grip_force_n=0.0)
    act, mic = tip.modes(44100)
    systems = tip.discretised(44100)
    np.testing.assert_allclose(np.sort_complex(act.lam), np.sort_complex(systems.act.parts[0].lam), rtol=1e-13)
    u = np.random.default_rng(2).standard_normal(3000)
    for part, system in ((act, systems.act), (mic, systems.mic)):
        lean = DiscreteSystem([part], 8, 44100, "foh").response(u)
        want = system.response(u)
        np.testing.assert_allclose(lean, want, rtol=0, atol=1e-12 * np.abs(want).max())


def _both_drives(set_reference, excitation, tip):
    out = []
    for reference in (True, False):
        set_reference(reference)
        out.append(drive_module.drive_spectrum(AcousticStream(excitation, tip), tip, True, FEATURE_BINS))
    return out


@pytest.mark.parametrize("excitation", ["linear", "impulse", "exponential"])
@pytest.mark.parametrize("mass_kg", [0.03, 0.4, 2.5])
def test_closed_form_drive_equals_the_reference(reference_drive, excitation, mass_kg):
    ex = Excitation.by_name(excitation)
    assert ex.period_samples == 22050 and ex.sample_rate_hz == 44100
    tip = FingertipModel(object_mass_kg=mass_kg, grip_force_n=0.0)
    ref, fast = _both_drives(reference_drive, ex, tip)
    assert ref.bin_spectrum is None and fast.bin_spectrum is not None
    scale = np.abs(ref.period).max()
    np.testing.assert_allclose(fast.period, ref.period, rtol=0, atol=1e-11 * scale)
    # the transient: the same decaying modes (numpy's eigen-solve may order them otherwise)
    n = np.arange(0, 3000, 7)
    want_tr = np.array([ref.transient.at(k) for k in n])
    np.testing.assert_allclose([fast.transient.at(k) for k in n], want_tr, rtol=0, atol=1e-11 * np.abs(want_tr).max())
    np.testing.assert_allclose(np.sort_complex(fast.transient.log_pole), np.sort_complex(ref.transient.log_pole),
                               rtol=1e-12)
    assert abs(fast.transient.bound() - ref.transient.bound()) <= 1e-11 * ref.transient.bound()
    assert abs(fast.lowest_dynamic_n - ref.lowest_dynamic_n) <= 1e-11 * scale
    # the spectrum at the bins in closed form against the FFT of the reference's period
    want = np.fft.rfft(ref.period)[FEATURE_BINS]
    np.testing.assert_allclose(fast.bin_spectrum, want, rtol=1e-11, atol=1e-13 * np.abs(want).max())


@pytest.mark.parametrize("mass_kg", [0.03, 2.5])
def test_closed_form_drive_is_the_run_from_rest(reference_drive, mass_kg):
    """Independent: the drive's first-order-hold run over two looped periods from rest equals
    its steady period plus its transient at every sample."""
    ex = Excitation.by_name("linear")
    tip = FingertipModel(object_mass_kg=mass_kg, grip_force_n=0.0)
    _, fast = _both_drives(reference_drive, ex, tip)
    stream = AcousticStream(ex, tip)
    systems = stream.drive.systems(tip)
    fe = tip.actuator_force_n * np.asarray(systems.period)
    run = systems.drive.act.response(np.tile(fe, 2))
    n = np.arange(len(run))
    closed = np.tile(fast.period, 2) + np.array([fast.transient.at(k) for k in n])
    np.testing.assert_allclose(closed, run, rtol=0, atol=1e-10 * np.abs(run).max())
    mic = systems.drive.mic.response(np.tile(fe, 2))
    assert fast.lowest_dynamic_n <= min(run.min(), mic.min()) + 1e-12


def test_periodic_start_equals_the_propagated_state():
    rng = np.random.default_rng(1)
    n = 10
    A = rng.standard_normal((n, n)) * 2000.0 - 3000.0 * np.eye(n)
    part = lti_system(A, rng.standard_normal(n), rng.standard_normal(n), 0.0, 44100).parts[0]
    u = rng.standard_normal(22050)
    want = part.periodic_vector(part.propagate(None, np.concatenate([u, u[:1]])), len(u))
    np.testing.assert_allclose(part.periodic_start(u), want, rtol=0, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("factored", [True, False])
@pytest.mark.parametrize("from_rest", [True, False])
def test_window_spectra_both_evaluations_against_the_sampled_response(monkeypatch, factored, from_rest):
    monkeypatch.setattr(window_module, "FACTORED_WINDOWS", factored)
    rng = np.random.default_rng(0)
    n, P, W = 6, 400, 3
    A = rng.standard_normal((n, n)) * 2000.0 - 3000.0 * np.eye(n)
    system = lti_system(A, rng.standard_normal(n), rng.standard_normal(n), 0.3, 44100)
    period = rng.standard_normal(P)
    transient = Exponentials(np.array([0.5 - 0.1j, 0.5 + 0.1j, 0.7 + 0j]),
                             np.array([-0.01 + 0.2j, -0.01 - 0.2j, -0.003 + 0j]))
    bins = np.arange(1, P // 2, 7)
    if from_rest:
        u = np.tile(period, W) + np.array([transient.at(k) for k in range(W * P)])
        y = system.response(u)
    else:                                   # settled: start in the periodic steady state
        transient = Exponentials.none()
        x0 = system.periodic_state(period)
        y = system.response(np.tile(period, W), x0)
    want = np.fft.rfft(y.reshape(W, P), axis=1)[:, bins]
    got = window_spectra(system, period, transient, bins, W, from_rest=from_rest)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    spectrum = np.fft.rfft(period)[bins]
    given = window_spectra(system, period, transient, bins, W, from_rest=from_rest, input_spectrum=spectrum)
    np.testing.assert_allclose(given, got, rtol=1e-13, atol=1e-13 * np.abs(got).max())


@pytest.fixture(scope="module")
def grasp():
    from aas_gym.grasp import planar_grasp
    from aas_gym.scene import build_scene
    from aas_gym.sim_sensor import SimAcousticSensor

    model = build_scene(["aluminium_bar"])
    data = mujoco.MjData(model)
    planar_grasp(model, data, "aluminium_bar", 0.03, 40.0)
    sensor = SimAcousticSensor(model, data)
    body, act, mic, others = sensor.grasp_contacts()
    return sensor.modal_model(body), act, mic, others


@pytest.mark.parametrize("excitation", ["linear", "impulse"])
@pytest.mark.parametrize("flags", ["all", "exciter_sums"])
def test_features_through_both_paths(grasp, monkeypatch, excitation, flags):
    """The fast paths against their references: every flag (``all``), or the exciter sums alone."""
    model, act, mic, others = grasp
    ex = Excitation.by_name(excitation)
    out = []
    for fast in (False, True):
        monkeypatch.setattr(drive_module, "EXCITER_SUMS", fast)
        if flags == "all":
            monkeypatch.setattr(drive_module, "CLOSED_FORM_DRIVE", fast)
            monkeypatch.setattr(window_module, "FACTORED_WINDOWS", fast)
        obs = simulate_features(model, ex, 1.0, act, mic, others, fingertip=FingertipModel(object_mass_kg=0.21))
        assert obs.metadata["features_path"] == "closed_form"
        out.append(obs.features(average=False))
    np.testing.assert_allclose(out[1], out[0], rtol=1e-9, atol=0)
