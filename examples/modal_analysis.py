"""Modal analysis of the paper's default objects: a 200 x 25 x 25 mm bar and a 200 mm tube.

Run as is:  .venv/bin/python examples/modal_analysis.py
Prints the elastic modes below 10 kHz next to Euler-Bernoulli beam theory and saves
outputs/modal_analysis.png (first bending mode along the bar; FE vs theory frequencies).
The first run builds the models (a few seconds each); later runs load them from the cache.
"""

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensors import MATERIALS, ModalModel

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

ROOTS = [4.730041, 7.853205, 10.995608, 14.137165, 17.278760]  # free-free beta_n L


def euler_bernoulli_hz(length_m, material, area_m2, inertia_m4):
    c = math.sqrt(material.youngs_modulus_pa * inertia_m4 / (material.density_kg_m3 * area_m2))
    return [r**2 / (2 * math.pi * length_m**2) * c for r in ROOTS]


material = MATERIALS["aluminium"]
bar = ModalModel.bar(0.2, 0.025, 0.025, material)
tube = ModalModel.tube(0.2, 0.0125, 0.0095, material)

theory = {
    "bar": euler_bernoulli_hz(0.2, material, 0.025**2, 0.025**4 / 12),
    "tube": euler_bernoulli_hz(0.2, material, math.pi * (0.0125**2 - 0.0095**2), math.pi * (0.0125**4 - 0.0095**4) / 4),
}
for name, model in (("bar", bar), ("tube", tube)):
    print(model)
    f = model.frequencies_hz[model.frequencies_hz < 10000]
    print(f"  FE modes below 10 kHz [Hz]: {np.round(f).astype(int)}")
    print(f"  Euler-Bernoulli bending [Hz] (thin-beam theory; 3D modes of a stubby bar are lower): "
          f"{np.round([x for x in theory[name] if x < 10000]).astype(int)}")
    print(f"  decay rates [1/s]: {np.round(model.decay_rates_per_s[: len(f)], 1)}")

# First bending mode along the top edge of the bar, 5 mm apart (interpolated, not snapped).
x = np.linspace(-0.1, 0.1, 41)
points = np.c_[x, np.zeros_like(x), np.full_like(x, 0.0125)]
shape = bar.mode_shapes_at(points)[:, :, 0]  # (n, 3) of mode 0
component = int(np.argmax(np.abs(shape).max(axis=0)))

out = OUTPUTS
out.mkdir(exist_ok=True)
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.5))
ax1.plot(1000 * x, shape[:, component], "o-")
ax1.set(xlabel="x [mm]", ylabel=f"u_{'xyz'[component]} [m/sqrt(kg)]",
        title=f"bar mode 1 ({bar.frequencies_hz[0]:.0f} Hz) on the top edge")
for name, model, marker in (("bar", bar, "o"), ("tube", tube, "s")):
    f = model.frequencies_hz[model.frequencies_hz < 10000]
    ax2.plot(np.arange(1, len(f) + 1), f, marker, label=f"{name} FE (P2)")
    ax2.plot(2 * np.arange(1, 4) - 0.5, [t for t in theory[name][:3]], "k" + marker, mfc="none",
             label=f"{name} Euler-Bernoulli bending")
ax2.set(xlabel="mode number", ylabel="frequency [Hz]", title="aluminium bar and tube")
ax2.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out / "modal_analysis.png", dpi=120)
print(f"saved {out / 'modal_analysis.png'}")
