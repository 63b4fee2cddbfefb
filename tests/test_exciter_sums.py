"""Phase-0 states from the exciter period's geometric sums (``sensors.synthesis.exciter_sums``)
against the sampled periodic steady state (``DiscreteSystem.periodic_state``: one period
propagated from rest, solved for the periodic state), and the drive's separation check."""

import numpy as np
import pytest

from sensors import Excitation
from sensors.synthesis import AcousticStream, FingertipModel
from sensors.synthesis import drive_spectrum as drive_module
from sensors.synthesis.exciter_sums import ExciterSums, SteadyDrive
from sensors.synthesis.lti import DiscreteSystem, lti_system


def modal_bank(seed: int, n_modes: int, sample_rate_hz: float = 44100.0) -> DiscreteSystem:
    """Lightly damped oscillators (100 Hz - 16 kHz, damping ratio 1e-4 - 2e-2), random input
    and output weights: an object's modes as the modal synthesis sees them."""
    rng = np.random.default_rng(seed)
    wn = 2 * np.pi * np.sort(rng.uniform(100.0, 16000.0, n_modes))
    zeta = rng.uniform(1e-4, 2e-2, n_modes)
    A = np.zeros((2 * n_modes, 2 * n_modes))
    A[0::2, 1::2] = np.eye(n_modes)
    A[1::2, 0::2] = -np.diag(wn ** 2)
    A[1::2, 1::2] = -np.diag(2 * zeta * wn)
    B = np.zeros(2 * n_modes)
    B[1::2] = rng.standard_normal(n_modes)
    C = np.zeros(2 * n_modes)
    C[0::2] = rng.standard_normal(n_modes) * 1e3
    return lti_system(A, B, C, 0.0, sample_rate_hz)


def in_coords(system: DiscreteSystem, state: np.ndarray) -> np.ndarray:
    return np.concatenate([p.to_coords(state[p.idx]) for p in system.parts])


@pytest.mark.parametrize("period_samples", [22050, 997])
def test_sums_give_the_sampled_periodic_state(period_samples):
    rng = np.random.default_rng(3)
    u = rng.standard_normal(period_samples)
    system = modal_bank(4, 30)
    want = in_coords(system, system.periodic_state(u))
    got = np.concatenate([ExciterSums(u).start(p) for p in system.parts])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.abs(want).max())


@pytest.mark.parametrize("excitation", ["linear", "impulse", "exponential"])
@pytest.mark.parametrize("mass_kg", [0.03, 0.4, 2.5])
def test_object_state_under_the_drive_without_its_samples(excitation, mass_kg):
    """The object's phase-0 state under the drive's steady output (the cascade through the
    drive's modes) equals the sampled periodic state under that output's period, which the
    drive's own discretised system gives (``periodic_response``)."""
    ex = Excitation.by_name(excitation)
    tip = FingertipModel(object_mass_kg=mass_kg, grip_force_n=0.0)
    systems = AcousticStream(ex, tip).drive.systems(tip)
    fe = tip.actuator_force_n * np.asarray(systems.period)
    act, _ = tip.modes(ex.sample_rate_hz)
    sums = ExciterSums(fe)
    drive = SteadyDrive(sums, act, sums.start(act))
    y = systems.drive.act.periodic_response(fe)
    assert abs(drive.first_output - y[0]) <= 1e-12 * np.abs(y).max()
    obj = modal_bank(5, 40)
    want = in_coords(obj, obj.periodic_state(y))
    got = np.concatenate([drive.start(p) for p in obj.parts])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


@pytest.mark.parametrize("excitation", ["linear", "impulse"])
@pytest.mark.parametrize("mass_kg", [0.03, 2.5])
def test_separation_check_decides_as_the_exact_lowest_force(excitation, mass_kg):
    """The bound known without the period never exceeds the exact lowest force, and
    ``separates`` decides every grip force as the exact lowest force does (the reference's)."""
    ex = Excitation.by_name(excitation)
    tip = FingertipModel(object_mass_kg=mass_kg, grip_force_n=0.0)
    fast = drive_module.drive_spectrum(AcousticStream(ex, tip), tip, True)
    assert fast.steady is not None
    exact = fast.lowest_dynamic_n                           # runs the period
    assert fast.lowest_bound_n <= exact < 0
    for grip in (0.5 * -exact, 1.5 * -exact, 0.5 * -fast.lowest_bound_n, 2.0 * -fast.lowest_bound_n):
        fresh = drive_module.drive_spectrum(AcousticStream(ex, tip), tip, True)
        assert fresh.separates(grip) == (grip + exact < 0)


@pytest.mark.parametrize("excitation", ["linear", "impulse"])
def test_window_spectra_under_the_drive_against_the_sampled_chain(excitation):
    """Independent of every closed form: the drive's first-order-hold run from rest over two
    looped periods, the object's run under it, the DFT of each window at the feature bins;
    against the window spectra from the drive's sums (no period passed)."""
    from sensors.signals.features import feature_frequencies_hz
    from sensors.synthesis.window_spectra import window_spectra

    ex = Excitation.by_name(excitation)
    tip = FingertipModel(object_mass_kg=0.7, grip_force_n=0.0)
    stream = AcousticStream(ex, tip)
    bins = np.round(feature_frequencies_hz() * ex.period_s).astype(int)
    drive = drive_module.drive_spectrum(stream, tip, True, bins)
    assert drive.steady is not None
    obj = modal_bank(6, 25)
    got = window_spectra(obj, None, drive.transient, bins, 2, input_spectrum=drive.bin_spectrum,
                         input_start=drive.steady)
    systems = stream.drive.systems(tip)
    force = systems.drive.act.response(np.tile(tip.actuator_force_n * np.asarray(systems.period), 2))
    y = obj.response(force)
    want = np.fft.rfft(y.reshape(2, -1), axis=1)[:, bins]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())
