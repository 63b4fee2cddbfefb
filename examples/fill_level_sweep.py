"""How the modes of the everyday containers fall as they fill with water.

Run as is:  .venv/bin/python examples/fill_level_sweep.py
For the mug, glass, can and bottle: the elastic modes below 12 kHz at 0 %, 10 %, ..., 100 %
fill (water, standing upright), printed and drawn to docs/images/fill_level_sweep.png. Each
line follows one mode through the fills (matched by the shape of its wall motion). The first
run builds each container's dry modes and static correction (a few minutes in all, the mug
longest); later runs load them from the cache and take seconds.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import linear_sum_assignment

from sensors.objects import get_object
from sensors.fluid import container, filled

CONTAINERS = ("mug", "glass", "can", "bottle")
FILLS = np.round(np.linspace(0.0, 1.0, 11), 2)
MAX_HZ = 12000.0
FEATURE_BAND_HZ = (3000.0, 10000.0)  # the 140 spectral features


def track(previous, current):
    """Index into ``current``'s columns for each column of ``previous`` (best shape match)."""
    a = previous / np.linalg.norm(previous, axis=0)
    b = current / np.linalg.norm(current, axis=0)
    rows, cols = linear_sum_assignment(-np.abs(a.T @ b))
    return cols[np.argsort(rows)]


fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharex=True)
for ax, name in zip(axes.ravel(), CONTAINERS):
    obj = get_object(name).solid()
    c = container(obj)
    rng = np.random.default_rng(0)  # wall points where mode shapes are compared
    points = obj.surface.vertices[rng.choice(len(obj.surface.vertices), 400, replace=False)]
    n = int((c.dry.frequencies_hz <= MAX_HZ).sum())
    lines = np.full((len(FILLS), n), np.nan)
    shapes = None
    for i, fill in enumerate(FILLS):
        wet = filled(c, float(fill))
        u = wet.mode_shapes_at(points).reshape(-1, wet.n_modes)
        pick = np.arange(n) if shapes is None else track(shapes, u)
        lines[i] = wet.frequencies_hz[pick]
        shapes = u[:, pick]
        print(f"{name} {100 * fill:3.0f}% ({wet.liquid.mass_kg * 1000:5.1f} g water): "
              f"{np.round(np.sort(lines[i])).astype(int)} Hz")
    ax.axhspan(*(np.array(FEATURE_BAND_HZ) / 1000), color="0.93", zorder=0)
    ax.plot(100 * FILLS, lines / 1000, "o-", ms=3, lw=1.2)
    ax.set(title=f"{name} ({obj.material.name}, {c.volume_m3 * 1e6:.0f} ml)", ylim=(0, MAX_HZ / 1000))
    ax.grid(alpha=0.3)
for ax in axes[1]:
    ax.set_xlabel("fill level [% of the cavity volume, water]")
for ax in axes[:, 0]:
    ax.set_ylabel("mode frequency [kHz]")
fig.suptitle("Elastic modes below 12 kHz vs fill level (grey: the 3-10 kHz feature band)")
fig.tight_layout()
out = Path(__file__).resolve().parents[1] / "docs" / "images" / "fill_level_sweep.png"
fig.savefig(out, dpi=120)
print(f"saved {out}")
