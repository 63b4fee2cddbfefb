"""Simulate the contact microphone on a grasped bar and plot the spectrum of the recording.

Bars of the paper's four materials (200 x 20 x 20 mm, FEM modal models) are held by the two
fingertips at 40 N, 40 mm from the centre, resting on a table (five light contacts under
them).  The actuator plays the paper's linear sweep; the plot shows the raw and the
Savitzky-Golay smoothed spectra in the feature band (3-10 kHz): mode frequencies follow
sqrt(E / rho), peak widths the material's damping plus the fingers' contact damping.

Run: python examples/synthesis.py   -> outputs/synthesis_spectrum.png
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import sensors  # noqa: E402

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

h = 0.01  # half thickness: the fingers touch the +y and -y faces
actuator = sensors.Contact([0.04, h, 0.0], [0, 1, 0], force_n=40.0, friction=0.8)
mic = sensors.Contact([0.04, -h, 0.0], [0, -1, 0], force_n=40.0, friction=0.8)
table = [sensors.Contact([x, 0.0, -h], [0, 0, -1], force_n=0.5, friction=0.5) for x in np.linspace(-0.09, 0.09, 5)]
excitation = sensors.Excitation.linear_sweep()

fig, ax = plt.subplots(figsize=(10, 5))
for material in ("aluminium", "steel", "wood", "abs"):
    model = sensors.ModalModel.bar(0.2, 0.02, 0.02, material)
    obs = sensors.simulate_recording(model, excitation, 1.0, actuator, mic, other_contacts=table,
                                     noise_std=1e-4, rng=0)
    f, a = obs.spectrum()
    band = (f >= 3000) & (f <= 10000)
    line, = ax.semilogy(f[band], a[band], lw=0.4, alpha=0.35)
    ax.semilogy(f[band], np.maximum(sensors.smooth_spectrum(a)[band], 1e-9), color=line.get_color(), lw=1.6,
                label=f"{material}: {len(model.frequencies_hz)} modes < 22 kHz, peak |x| {np.abs(obs.waveform).max():.3f}")
    print(f"{material:10s} {model.describe()}; features {obs.features().shape}, peak {np.abs(obs.waveform).max():.3g}")
ax.set_xlabel("frequency [Hz]")
ax.set_ylabel("amplitude (full scale 1)")
ax.set_title("Simulated recordings: 200 x 20 x 20 mm bars, linear sweep, 40 N grasp, on a table")
ax.legend(fontsize=8)
fig.tight_layout()
out = OUTPUTS
out.mkdir(exist_ok=True)
fig.savefig(out / "synthesis_spectrum.png", dpi=120)
print("wrote", out / "synthesis_spectrum.png")
