"""Modal frequencies and decay rates from a recording.

The chain:

1. :func:`transfer_function` - the object's transfer function on the DFT grid of one loop
   period (2 Hz at the paper's 0.5 s): average the spectra of whole periods of the recording
   and divide by the known excitation, regularized (Tikhonov) where the excitation has no
   energy. The same division serves the impulse (flat spectrum) and the sweeps. Because
   every excitation loops, one period of the steady-state recording is the *circular*
   convolution of the excitation with the impulse response, and the DFT of a circularly
   wrapped sum of damped exponentials is exactly the sampled transfer function
   ``sum_m a_m / (1 - z_m e^(-j 2 pi k / P))``: no window, no leakage.
2. :func:`estimate_modes` - split the band into overlapping sub-bands, turn each into a short
   complex time signal (taper the bins, inverse DFT: a heterodyned, decimated impulse
   response), run TLS-ESPRIT on it with the model order chosen by BIC, fit amplitudes by
   least squares, and keep the modes that fall in the sub-band's centre. The taper makes
   the response of out-of-band modes smooth in frequency, i.e. short in time, so it is
   confined to the first and last few samples, which are skipped; the poles of in-band
   modes are untouched by a taper (it only rescales their amplitude).
3. Every kept mode carries standard deviations of its frequency and decay rate from the
   Fisher information of the fitted multi-mode model (so close modes that share energy get
   honest, larger error bars), and each sub-band reports how much of the signal the fit
   explains.

Conventions: a mode is ``a exp((-sigma + j 2 pi f) t)``; ``decay_rates_per_s`` are sigma in 1/s
(the modal model's ``(alpha + beta w^2) / 2``), frequencies in Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import scipy.linalg

from ..signals.excitation import Excitation
from ..signals.features import segment

__all__ = [
    "TransferFunction",
    "ModalEstimate",
    "BandFit",
    "transfer_function",
    "esprit",
    "estimate_modes",
    "estimate_modes_from_observation",
]


# -- transfer function ----------------------------------------------------------------------


@dataclass
class TransferFunction:
    """Transfer function from excitation to microphone on the DFT grid of one loop period.

    Attributes:
        frequencies_hz: bin frequencies, 0 .. sample_rate_hz/2 in steps of 1 / period.
        response: complex transfer function at those bins (0 where the excitation has no energy).
        noise_var: variance of ``response`` per bin from the spread between periods
            (``None`` with fewer than two periods).
        period_s: loop period (the length of the circular impulse response).
        n_periods: number of periods averaged.
        valid: bins where the excitation had enough energy to be trusted.
        top_hz: upper edge of the excitation's band (power within 30 dB of its peak): a
            sweep's end. Sub-bands are kept below it, since the transfer function drops to
            zero there and a sharp edge rings for a long time in a sub-band signal.
    """

    frequencies_hz: np.ndarray
    response: np.ndarray
    noise_var: np.ndarray | None
    period_s: float
    n_periods: int
    valid: np.ndarray
    top_hz: float = math.inf

    @property
    def bin_hz(self) -> float:
        """Bin spacing in Hz (1 / period)."""
        return 1.0 / self.period_s

    def impulse_response(self) -> np.ndarray:
        """The circular impulse response over one period (real, ``period_s * sample_rate_hz`` samples)."""
        n = 2 * (self.frequencies_hz.size - 1)
        return np.fft.irfft(self.response, n)


def transfer_function(
    waveform: np.ndarray,
    excitation: Excitation,
    *,
    start_s: float = 0.0,
    skip_periods: int | str = "auto",
    regularization: float = 1e-9,
    leak=None,
    leak_delay_samples: int = 0,
) -> TransferFunction:
    """Deconvolve a recording by its looping excitation, over one loop period.

    Args:
        waveform: microphone signal (one channel) at ``excitation.sample_rate_hz``.
        excitation: the looping excitation that was played.
        start_s: where the first excitation period starts in ``waveform`` (latency).
        skip_periods: periods to drop at the start. ``"auto"`` drops the first one when at
            least two are available: a recording that starts from rest is not yet periodic in
            its first period, and for a sweep that transient does not deconvolve into damped
            exponentials.
        regularization: Tikhonov weight relative to the excitation's peak power spectrum;
            bins with ``|X|^2`` below 100 times it are marked invalid.
        leak: the rig's idle recording for this excitation (``sensors.LeakRecording`` or a
            waveform at ``sample_rate_hz``), to be removed: its transfer function is deconvolved the same
            way, delayed by ``leak_delay_samples`` and subtracted (recorded at the same gain).
            A leak that starts after the excitation is not a sum of decaying modes from
            t = 0 (it switches on later) and would bias the modes under it.
        leak_delay_samples: where the leak sits in the recording relative to its own file.
            0 for the rig, whose leak files and recordings both start at the first
            excitation period; the simulator's shift is in the recording's metadata (see
            :func:`estimate_modes_from_observation`).
    """
    sample_rate_hz = excitation.sample_rate_hz
    windows = segment(waveform, sample_rate_hz, excitation.period_s, start_s)
    if skip_periods == "auto":
        skip = 1 if windows.shape[0] >= 2 else 0
    else:
        skip = int(skip_periods)
        if not 0 <= skip < windows.shape[0]:
            raise ValueError(f"skip_periods={skip} leaves no period out of {windows.shape[0]}")
    windows = windows[skip:]
    Y = np.fft.rfft(windows, axis=1)
    X = np.fft.rfft(excitation.signal)
    power = np.abs(X) ** 2
    lam = regularization * power.max()
    inverse = np.conj(X) / (power + lam)
    response = Y.mean(axis=0) * inverse
    if leak is not None:
        response = _remove_leak(response, leak, excitation, inverse, leak_delay_samples)
    noise_var = None
    if Y.shape[0] >= 2:
        noise_var = np.var(Y, axis=0, ddof=1) / Y.shape[0] * np.abs(inverse) ** 2
    freqs = np.fft.rfftfreq(windows.shape[1], 1.0 / sample_rate_hz)
    strong = np.flatnonzero(power >= 1e-3 * power.max())
    top_hz = float(freqs[strong[-1]]) if strong[-1] < freqs.size - 1 else math.inf
    return TransferFunction(freqs, response, noise_var, excitation.period_s, Y.shape[0], power > 100 * lam, top_hz)


def _remove_leak(response: np.ndarray, leak, excitation: Excitation, inverse: np.ndarray,
                 delay: int) -> np.ndarray:
    w = np.asarray(getattr(leak, "waveform", leak), dtype=float)
    rate = getattr(leak, "sample_rate_hz", excitation.sample_rate_hz)
    if rate != excitation.sample_rate_hz:
        raise ValueError(f"leak recorded at {rate} Hz, the recording at {excitation.sample_rate_hz} Hz")
    # the leak is periodic too: any whole periods of it will do, transient-free ones best
    windows = segment(w, excitation.sample_rate_hz, excitation.period_s, 0.0)
    if windows.shape[0] >= 2:
        windows = windows[1:]
    H_leak = np.fft.rfft(windows, axis=1).mean(axis=0) * inverse
    n = excitation.period_samples
    # the leak's lag in the recording, given by the caller: a circular delay, i.e. a phase ramp
    lag = int(delay) % n
    # unit gain: the leak path does not change with the grasp (a least-squares gain would be
    # pulled by the object's response, which correlates with the leak)
    k = np.arange(response.size)
    return response - H_leak * np.exp(-2j * np.pi * k * lag / n)


# -- ESPRIT -----------------------------------------------------------------------------------


def _hankel(x: np.ndarray, rows: int) -> np.ndarray:
    cols = x.size - rows + 1
    idx = np.arange(rows)[:, None] + np.arange(cols)[None, :]
    return x[idx]


def esprit(x: np.ndarray, order: int, *, rows: int | None = None, _svd=None) -> np.ndarray:
    """Signal poles of ``x[n] = sum_m a_m z_m^n + noise`` by TLS-ESPRIT.

    Args:
        x: complex (or real) samples, equally spaced.
        order: number of complex exponentials (a real damped sine needs two).
        rows: Hankel rows (default ``len(x) // 2``, near-optimal for accuracy).

    Returns:
        ``order`` complex poles ``z_m`` (per sample).
    """
    x = np.asarray(x, dtype=complex)
    rows = x.size // 2 if rows is None else int(rows)
    if _svd is None:
        U, _, _ = scipy.linalg.svd(_hankel(x, rows), full_matrices=False, lapack_driver="gesdd")
    else:
        U = _svd
    if not 1 <= order < min(rows, x.size - rows + 1):
        raise ValueError(f"order={order} must be >= 1 and below the Hankel size {rows} x {x.size - rows + 1}")
    Us = U[:, :order]
    # TLS solution of Us[:-1] Phi = Us[1:] (Roy & Kailath 1989).
    C = np.hstack([Us[:-1], Us[1:]])
    _, _, Vh = np.linalg.svd(C, full_matrices=False)
    V = Vh.conj().T
    V12, V22 = V[:order, order:], V[order:, order:]
    return np.linalg.eigvals(-V12 @ np.linalg.inv(V22))


def _vandermonde_fit(x: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.arange(x.size)[:, None]
    with np.errstate(over="ignore", invalid="ignore"):
        V = poles[None, :] ** n
    amps, *_ = np.linalg.lstsq(V, x, rcond=None)
    return amps, V @ amps


# -- sub-band estimation ---------------------------------------------------------------------


@dataclass
class BandFit:
    """Diagnostics of one sub-band fit.

    Attributes:
        f_lo_hz, f_hi_hz: the sub-band; modes are kept from its central part only.
        order: model order chosen by BIC.
        explained: fraction of the sub-band signal energy the fitted modes explain (1 - RSS/E).
        noise_var: residual variance per complex sample after the fit.
        expected_noise_var: the same predicted from the spread between periods (``None``
            with one period); a residual well above it means the modal model misses structure.
    """

    f_lo_hz: float
    f_hi_hz: float
    order: int
    explained: float
    noise_var: float
    expected_noise_var: float | None

    @property
    def fit_ok(self) -> bool:
        """The residual is no more than 4x the noise expected from the period spread."""
        if self.expected_noise_var is None or self.expected_noise_var <= 0:
            return self.explained > 0.5
        return self.noise_var <= 4.0 * self.expected_noise_var


@dataclass
class ModalEstimate:
    """Modes found in a recording, sorted by frequency.

    Attributes:
        frequencies_hz: damped natural frequencies [Hz].
        decay_rates_per_s: decay rates sigma [1/s] (amplitude ~ exp(-sigma t)).
        amplitudes: complex amplitude ``A`` of each mode in the impulse response per unit
            excitation, ``h(t) = sum Re(A exp((-sigma + j 2 pi f) t))``.
        frequency_std_hz, decay_rate_std_per_s: one-sigma uncertainty from the Fisher information
            of the fitted model (Cramer-Rao bound at the estimate) [Hz], [1/s].
        snr_db: mode energy over the residual noise in its sub-band [dB].
        bands: per-sub-band diagnostics.
    """

    frequencies_hz: np.ndarray
    decay_rates_per_s: np.ndarray
    amplitudes: np.ndarray
    frequency_std_hz: np.ndarray
    decay_rate_std_per_s: np.ndarray
    snr_db: np.ndarray
    bands: list[BandFit] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.frequencies_hz.size)

    @property
    def loss_factors(self) -> np.ndarray:
        """Modal loss factor eta = 2 sigma / omega (dimensionless)."""
        return 2.0 * self.decay_rates_per_s / (2 * np.pi * self.frequencies_hz)

    def select(self, mask: np.ndarray) -> ModalEstimate:
        """The subset of modes where ``mask`` is true (bands kept as they are)."""
        m = np.asarray(mask)
        return ModalEstimate(self.frequencies_hz[m], self.decay_rates_per_s[m], self.amplitudes[m],
                             self.frequency_std_hz[m], self.decay_rate_std_per_s[m], self.snr_db[m], self.bands)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly form (complex amplitudes as magnitude and phase)."""
        return {
            "frequencies_hz": self.frequencies_hz.tolist(),
            "decay_rates_per_s": self.decay_rates_per_s.tolist(),
            "amplitude_abs": np.abs(self.amplitudes).tolist(),
            "amplitude_phase_rad": np.angle(self.amplitudes).tolist(),
            "frequency_std_hz": self.frequency_std_hz.tolist(),
            "decay_rate_std_per_s": self.decay_rate_std_per_s.tolist(),
            "snr_db": self.snr_db.tolist(),
        }

    @staticmethod
    def concatenate(estimates: list[ModalEstimate]) -> ModalEstimate:
        """Pool several estimates (e.g. of several recordings) into one, sorted by frequency."""
        cat = {k: np.concatenate([getattr(e, k) for e in estimates]) if estimates else np.zeros(0)
               for k in ("frequencies_hz", "decay_rates_per_s", "amplitudes", "frequency_std_hz", "decay_rate_std_per_s", "snr_db")}
        order = np.argsort(cat["frequencies_hz"])
        return ModalEstimate(**{k: v[order] for k, v in cat.items()},
                             bands=[b for e in estimates for b in e.bands])


def _taper(n: int) -> np.ndarray:
    """sin^4 taper over a sub-band: zero with three zero derivatives at both ends, so the
    time kernel it convolves with falls off like 1/n^5 and out-of-band modes stay confined
    to the first few samples."""
    return np.sin(np.pi * (np.arange(n) + 0.5) / n) ** 4


def _fisher_std(t_s: np.ndarray, poles_s: np.ndarray, amps: np.ndarray, noise_var: float) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviations of sigma and omega from the Fisher information of the model
    ``sum a_m exp(s_m t)`` in complex white noise of variance ``noise_var``."""
    r = poles_s.size
    E = np.exp(np.outer(t_s, poles_s))
    tE = t_s[:, None] * E * amps[None, :]
    # parameters per mode: Re a, Im a, sigma (s = -sigma + j w), w
    D = np.concatenate([E, 1j * E, -tE, 1j * tE], axis=1)
    J = 2.0 / max(noise_var, 1e-300) * np.real(D.conj().T @ D)
    try:
        cov = np.linalg.pinv(J, hermitian=True)
    except np.linalg.LinAlgError:
        return np.full(r, np.inf), np.full(r, np.inf)
    var = np.clip(np.diag(cov), 0.0, None)
    return np.sqrt(var[2 * r:3 * r]), np.sqrt(var[3 * r:])


def _fit_band(g: np.ndarray, max_order: int, n_eff: float) -> tuple[np.ndarray, np.ndarray, float, int]:
    """ESPRIT with the model order chosen by BIC on one sub-band signal.

    Returns poles per sample, amplitudes at sample 0, residual variance and order."""
    n = g.size
    rows = n // 2
    U, _, _ = scipy.linalg.svd(_hankel(g, rows), full_matrices=False, lapack_driver="gesdd")
    energy = float(np.vdot(g, g).real)
    best = (2 * n_eff * math.log(max(energy / n, 1e-300)), np.zeros(0, complex), np.zeros(0, complex), energy / n, 0)
    worse_in_a_row = 0
    for order in range(1, min(max_order, rows - 2, n - rows - 1) + 1):
        z = esprit(g, order, rows=rows, _svd=U)
        z = z[(np.abs(z) < 1.0) & (np.abs(z) > 1e-3)]  # growing or vanishing: noise fitted as signal
        if z.size == 0:
            continue
        amps, model = _vandermonde_fit(g, z)
        rss = float(np.vdot(g - model, g - model).real)
        # -2 log L of complex Gaussian noise = 2 n log(RSS / n) + const; 4 real parameters
        # per mode; n_eff < n because the taper correlates neighbouring noise samples.
        bic = 2 * n_eff * math.log(max(rss / n, 1e-300)) + 4 * z.size * math.log(2 * n_eff)
        if bic < best[0]:
            best = (bic, z, amps, rss / n, z.size)
            worse_in_a_row = 0
        else:
            worse_in_a_row += 1
            if worse_in_a_row >= 6:  # BIC has turned; higher orders only fit noise
                break
    return best[1], best[2], best[3], best[4]


def _full_spectrum(H: np.ndarray) -> np.ndarray:
    """Two-sided DFT of the real circular impulse response from its one-sided half, so
    sub-bands can reach below 0 Hz (conjugate images) instead of being cut at DC."""
    n = 2 * (H.size - 1)
    full = np.empty(n, complex)
    full[:H.size] = H
    full[H.size:] = np.conj(H[1:-1][::-1])
    return full


class _Mode(NamedTuple):
    """One mode found in a sub-band (amplitude: real-mode amplitude per unit excitation)."""

    frequency_hz: float
    decay_rate_per_s: float
    amplitude: complex
    frequency_std_hz: float
    decay_rate_std_per_s: float
    snr_db: float


def _merge_levels(kept: list[_Mode], new: list[_Mode]) -> list[_Mode]:
    """Add modes from a wider sub-band level, dropping those that duplicate a mode already
    kept (the same mode seen at two adjacent widths: frequency within a quarter of the
    half-power bandwidth and decay rate within 30 %, or both within three standard
    deviations). A duplicate replaces the kept one only if it is more certain."""
    out = list(kept)
    for m in new:
        for i, k in enumerate(out):
            sigma = max(m.decay_rate_per_s, k.decay_rate_per_s)
            tol_f = max(0.25 * sigma / math.pi, 3.0 * math.hypot(m.frequency_std_hz, k.frequency_std_hz))
            tol_s = max(0.3 * sigma, 3.0 * math.hypot(m.decay_rate_std_per_s, k.decay_rate_std_per_s))
            if (abs(m.frequency_hz - k.frequency_hz) <= tol_f
                    and abs(m.decay_rate_per_s - k.decay_rate_per_s) <= tol_s):
                if m.decay_rate_std_per_s < k.decay_rate_std_per_s:
                    out[i] = m
                break
        else:
            out.append(m)
    return out


def estimate_modes(
    tf: TransferFunction,
    *,
    f_min_hz: float = 100.0,
    f_max_hz: float | None = None,
    band_hz: float = 800.0,
    max_order: int = 24,
    skip_samples: int = 6,
    max_samples: int = 600,
    samples_per_decay: float = 15.0,
    min_snr_db: float = 20.0,
) -> ModalEstimate:
    """Modal frequencies and decay rates from a transfer function, band by band.

    Args:
        tf: from :func:`transfer_function`.
        f_min_hz, f_max_hz: band to analyse (default up to the last valid bin).
        band_hz: narrowest sub-band. Modes are kept from the central half of a sub-band and
            consecutive sub-bands advance by half their width. Sub-bands are then doubled
            in width, level by level, and each mode is taken from the narrowest width at
            which it still lasts ``samples_per_decay`` samples (heavily damped modes need
            wide sub-bands, i.e. fine time steps; light ones profit from narrow ones).
        max_order: highest model order tried per sub-band.
        skip_samples: samples skipped at the start of each sub-band signal, where the
            responses of out-of-band modes and the excitation instant are concentrated.
        max_samples: longest sub-band signal fitted (bounds the cost of wide sub-bands).
        samples_per_decay: see ``band_hz``.
        min_snr_db: drop modes whose energy is below this over the residual noise.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # only a speed matter: threaded BLAS is slow on these small matrices
        import contextlib

        threadpool_limits = lambda **_: contextlib.nullcontext()  # noqa: E731
    with threadpool_limits(limits=1, user_api="blas"):
        return _estimate_modes(tf, f_min_hz, f_max_hz, band_hz, max_order, skip_samples, max_samples,
                               samples_per_decay, min_snr_db)


@dataclass(frozen=True)
class _Ladder:
    """What every sub-band fit of one transfer function shares."""

    tf: "TransferFunction"
    full: np.ndarray             # two-sided spectrum
    noise_full: np.ndarray | None
    df: float                    # bin width [Hz]
    k_min: int                   # narrowest sub-band [bins]
    k_edge: int | None           # the excitation's band edge [bins]
    f_bottom: float
    f_top: float
    max_order: int
    skip_samples: int
    max_samples: int
    samples_per_decay: float
    min_snr_db: float


def _fit_sub_band(ladder: _Ladder, k_lo_keep: int, k_hi_keep: int, K: int) -> tuple["BandFit", list[_Mode]]:
    """Fit one sub-band of K bins centred on the kept range [k_lo_keep, k_hi_keep)."""
    tf, full, noise_full, df = ladder.tf, ladder.full, ladder.noise_full, ladder.df
    k_edge, k_min, skip_samples, max_samples = ladder.k_edge, ladder.k_min, ladder.skip_samples, ladder.max_samples
    samples_per_decay, n_period = ladder.samples_per_decay, full.size
    f_bottom, f_top, max_order, min_snr_db = ladder.f_bottom, ladder.f_top, ladder.max_order, ladder.min_snr_db
    k_centre = (k_lo_keep + k_hi_keep) // 2
    k0 = k_centre - K // 2
    if k_edge is not None and k0 + K > k_edge:
        # slide the sub-band below the excitation's band edge (and above its mirror
        # image at -edge); modes near the edge then sit on the taper's flank, and are
        # dropped if it is too low
        k0 = max(k_edge - K, -k_edge)
        K = min(K, 2 * k_edge)
    w = _taper(K)
    bins = np.take(full, np.arange(k0, k0 + K), mode="wrap") * w
    g = np.fft.ifft(bins) * K  # the sub-band's time signal, heterodyned by f(k0)
    dt = tf.period_s / K
    n = min(K - 2 * skip_samples, max_samples)
    if K > k_min:
        # modes taken at this width live 1/2 .. 1 times samples_per_decay samples per
        # time constant: a dozen time constants of samples hold all there is to fit
        n = min(n, int(12 * samples_per_decay))
    idx = np.arange(skip_samples, skip_samples + n)
    n_eff = n * float(w.sum() ** 2 / (K * (w**2).sum()))
    z, amps, noise_var, order = _fit_band(g[idx], max_order, n_eff)
    expected = None
    if noise_full is not None:
        # white per-bin variance through taper and K-point inverse DFT: sum v w^2
        expected = float(np.sum(np.take(noise_full, np.arange(k0, k0 + K), mode="wrap") * w**2))
    energy = float(np.vdot(g[idx], g[idx]).real)
    band = BandFit(k0 * df, (k0 + K) * df, order, 1.0 - noise_var * n / energy if energy > 0 else 0.0,
                   noise_var, expected)
    if z.size == 0:
        return band, []
    s = np.log(z) / dt
    t_s = idx * dt
    amps0 = amps * np.exp(-s * t_s[0])  # amplitude at t = 0
    f_hz = k0 * df + np.mod(s.imag, 2 * np.pi / dt) / (2 * np.pi)
    sigma = -s.real
    gain = np.interp(f_hz, (k0 + np.arange(K)) * df, w)
    dof = n_eff / n
    sd_sigma, sd_w = _fisher_std(t_s, s, amps0, noise_var / dof)
    energy_m = np.abs(amps0) ** 2 * np.sum(np.exp(-2 * np.outer(t_s, sigma)), axis=0)
    snr_db = 10 * np.log10(np.maximum(energy_m, 1e-300) / max(noise_var, 1e-300))
    # Real-mode amplitude of the unwrapped impulse response per unit excitation: the
    # sub-band signal is P times the circular response, whose modes carry the
    # wrap-around factor 1 / (1 - exp(s T)); a real mode is two complex exponentials.
    with np.errstate(divide="ignore", invalid="ignore"):
        real_amps = 2.0 * amps0 / (n_period * gain) * (1.0 - np.exp(s * tf.period_s))
    keep = ((f_hz >= k_lo_keep * df) & (f_hz < k_hi_keep * df) & (f_hz >= f_bottom) & (f_hz < f_top)
            & (sigma > 0) & (snr_db >= min_snr_db) & (gain > 0.05))
    modes = [_Mode(f_hz[i], sigma[i], real_amps[i], sd_w[i] / (2 * np.pi), sd_sigma[i], snr_db[i])
             for i in np.flatnonzero(keep)]
    return band, modes


def _estimate_modes(tf, f_min_hz, f_max_hz, band_hz, max_order, skip_samples, max_samples,
                    samples_per_decay, min_snr_db) -> ModalEstimate:
    freqs = tf.frequencies_hz
    df = tf.bin_hz
    full = _full_spectrum(tf.response)
    n_period = full.size
    noise_full = None if tf.noise_var is None else np.concatenate([tf.noise_var, tf.noise_var[1:-1][::-1]])
    valid_idx = np.flatnonzero(tf.valid)
    if valid_idx.size == 0:
        raise ValueError("the excitation has no energy in any bin")
    f_top = freqs[valid_idx[-1]] if f_max_hz is None else min(float(f_max_hz), freqs[valid_idx[-1]])
    f_bottom = max(float(f_min_hz), freqs[valid_idx[0]])
    if not f_bottom < f_top:
        raise ValueError(f"empty analysis band [{f_bottom}, {f_top}] Hz")
    k_min = int(round(band_hz / df))
    if k_min < 64:
        raise ValueError(f"band_hz={band_hz} spans {k_min} bins of {df:g} Hz; need at least 64")
    k_max = n_period // 2

    ladder = _Ladder(tf, full, noise_full, df, k_min,
                     int(math.floor(tf.top_hz / df)) if math.isfinite(tf.top_hz) else None,
                     f_bottom, f_top, max_order, skip_samples, max_samples, samples_per_decay, min_snr_db)

    # Resolution ladder: sub-bands of k_min, 2 k_min, 4 k_min, ... bins. A mode with decay
    # rate sigma lives for period / K * samples_per_decay only if K >= samples_per_decay *
    # sigma * period, so each mode is taken from the narrowest sub-band width that samples
    # it well (narrow = long record = best frequency resolution for light damping; wide =
    # fine time steps for heavy damping).
    results: list[_Mode] = []
    bands: list[BandFit] = []
    K = k_min
    k_lower = -1.0
    k_first = int(math.floor(f_bottom / df))
    while True:
        level: list[_Mode] = []
        hop = K // 2
        k_lo = k_first
        while k_lo * df < f_top:
            band, modes = _fit_sub_band(ladder, k_lo, k_lo + hop, K)
            bands.append(band)
            for m in modes:
                k_needed = samples_per_decay * m.decay_rate_per_s * tf.period_s
                if (k_needed <= K or K >= k_max) and k_needed > k_lower:
                    level.append(m)
            k_lo += hop
        results = _merge_levels(results, level)
        if K >= k_max:
            break
        k_lower = K
        K = min(2 * K, k_max)
    if results:
        f, sig, a, sdf, sds, snr = (np.asarray(v) for v in zip(*sorted(results, key=lambda r: r.frequency_hz)))
    else:
        f = sig = sdf = sds = snr = np.zeros(0)
        a = np.zeros(0, complex)
    return ModalEstimate(f, sig, a.astype(complex), sdf, sds, snr, bands)


def estimate_modes_from_observation(observation, **kwargs: Any) -> ModalEstimate:
    """:func:`transfer_function` then :func:`estimate_modes` on a
    :class:`sensors.AcousticObservation`. Keyword arguments go to either function;
    ``f_max_hz`` defaults to 98 % of a sweep's end frequency, or 10 kHz for an impulse.
    With ``leak=``, a simulated recording's ``leak_target_lag`` metadata places the leak
    exactly; otherwise it is taken to start with the recording (the rig's layout)."""
    tf_keys = {"skip_periods", "regularization", "leak"}
    tf_kwargs = {k: kwargs.pop(k) for k in list(kwargs) if k in tf_keys}
    leak = tf_kwargs.get("leak")
    target = (observation.metadata or {}).get("leak_target_lag")
    if leak is not None and target is not None and "leak_delay_samples" not in kwargs:
        # the simulator shifted the leak so its excitation peak falls at target (sensors.signals.leak)
        from ..signals.leak import excitation_lag

        w = np.asarray(getattr(leak, "waveform", leak), dtype=float)
        P = observation.excitation.period_samples
        own = excitation_lag(w, observation.excitation.signal, max_lag=min(P - 1, w.size - P))
        tf_kwargs["leak_delay_samples"] = int(target) - own
    elif "leak_delay_samples" in kwargs:
        tf_kwargs["leak_delay_samples"] = kwargs.pop("leak_delay_samples")
    tf = transfer_function(observation.waveform, observation.excitation, start_s=observation.start_time_s, **tf_kwargs)
    if "f_max_hz" not in kwargs:
        f1 = observation.excitation.f1_hz
        # the last few per cent of a sweep carry little energy and no fade-out; an impulse
        # covers everything, but the paper's band ends at 10 kHz and higher modes are weak
        kwargs["f_max_hz"] = 0.98 * f1 if f1 is not None else min(10_000.0, 0.45 * observation.sample_rate_hz)
    return estimate_modes(tf, **kwargs)
