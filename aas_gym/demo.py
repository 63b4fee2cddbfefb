"""``aas signals``: the paper's excitations and the features they give, as PNG."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def render_signals(out_dir: Path) -> Path:
    """Plot each paper excitation (one period), its spectrum and its 140 features."""
    # The sensor stack and matplotlib load here, not at import: `aas --help` imports this
    # module to list the command (sensors ~0.4 s, measured with -X importtime).
    from sensors import Excitation, amplitude_spectrum, feature_frequencies_hz, smooth_spectrum, spectral_features
    import matplotlib

    from sensors._infra.atomic import atomic_savefig

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    excitations = [Excitation.impulse(), Excitation.linear_sweep(), Excitation.exponential_sweep()]
    fig, axes = plt.subplots(len(excitations), 2, figsize=(11, 8), constrained_layout=True)
    freqs = feature_frequencies_hz()
    for row, exc in zip(axes, excitations):
        x = exc.loop(1.0)
        t_ms = np.arange(exc.period_samples) / exc.sample_rate_hz * 1e3
        row[0].plot(t_ms, exc.signal, lw=0.5)
        row[0].set(title=f"{exc.name}: one period", xlabel="time [ms]", ylabel="amplitude")
        f, a = amplitude_spectrum(x, exc.sample_rate_hz)
        band = (f >= 2500) & (f <= 10500)
        row[1].semilogy(f[band], a[band], lw=0.4, color="0.6", label="spectrum")
        row[1].semilogy(f[band], np.maximum(smooth_spectrum(a)[band], 1e-12), lw=1.0, label="Savitzky-Golay")
        row[1].semilogy(freqs, spectral_features(x, exc.sample_rate_hz), ".", ms=3, label="140 features")
        row[1].set(title=f"{exc.name}: amplitude spectrum", xlabel="frequency [Hz]", ylabel="amplitude [full scale]")
        lo, hi = float(np.min(a[band])), float(np.max(a[band]))
        if hi < 10 * lo:  # a flat spectrum (the click): show a decade around it, not one tick
            row[1].set_ylim(lo / 10, hi * 10)
        row[1].legend(fontsize=7)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "excitations.png"
    atomic_savefig(fig, path, dpi=110)
    plt.close(fig)
    return path


def _run(args: argparse.Namespace) -> int:
    path = render_signals(Path(args.out))
    print(f"wrote {path}")
    return 0


def add_subcommands(sub) -> None:
    p = sub.add_parser("signals", help="plot the paper's excitations and their spectral features")
    p.add_argument("--out", default="outputs", help="output folder (default: outputs)")
    p.set_defaults(func=_run)
