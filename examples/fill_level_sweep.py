"""How the modes of the everyday containers fall as they fill with water.

Run as is:  .venv/bin/python examples/fill_level_sweep.py
For the mug, glass, can and bottle: the elastic modes below 12 kHz at 0 %, 10 %, ..., 100 %
fill (water, standing upright), printed and drawn to docs/images/fill_level_sweep.png, for the
compressible liquid (the default: coloured lines and dots) and the incompressible one (thin
grey lines). Each line follows one wall mode through the fills (matched by the shape of its
wall motion); dots are the compressible model's further modes (the liquid's own, coupled to
the wall), and the dashed line is the liquid's quarter-wave column mode with rigid walls (its
lowest acoustic mode). The first run builds each container's dry modes and static correction
(a few minutes in all, the mug longest); later runs load them from the cache and take seconds.
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


def sweep(c, points, n, compressible):
    """(fills, n) tracked wall-mode frequencies [Hz], the untracked extra modes (fill, Hz) and
    the liquid's lowest acoustic mode [Hz] per fill."""
    lines = np.full((len(FILLS), n), np.nan)
    extra, column = [], np.full(len(FILLS), np.nan)
    shapes = None
    for i, fill in enumerate(FILLS):
        wet = filled(c, float(fill), compressible=compressible)
        keep = wet.frequencies_hz <= MAX_HZ * 1.2
        u = wet.mode_shapes_at(points).reshape(-1, wet.n_modes)[:, keep]
        pick = np.arange(n) if shapes is None else track(shapes, u)
        lines[i] = wet.frequencies_hz[pick]
        shapes = u[:, pick]
        extra += [(100 * fill, f) for f in np.delete(wet.frequencies_hz[keep], pick) if f <= MAX_HZ]
        if wet.n_liquid_modes:
            column[i] = wet.liquid_modes_hz[0]
        print(f"{name} {100 * fill:3.0f}% ({wet.liquid.mass_kg * 1000:5.1f} g water, {wet.liquid_model}): "
              f"{np.round(np.sort(wet.frequencies_hz[wet.frequencies_hz <= MAX_HZ])).astype(int)} Hz")
    return lines, np.array(extra).reshape(-1, 2), column


fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharex=True)
for ax, name in zip(axes.ravel(), CONTAINERS):
    obj = get_object(name).solid()
    c = container(obj)
    rng = np.random.default_rng(0)  # wall points where mode shapes are compared
    points = obj.surface.vertices[rng.choice(len(obj.surface.vertices), 400, replace=False)]
    n = int((c.dry.frequencies_hz <= MAX_HZ).sum())
    incompressible, _, _ = sweep(c, points, n, False)
    lines, extra, column = sweep(c, points, n, True)
    ax.axhspan(*(np.array(FEATURE_BAND_HZ) / 1000), color="0.93", zorder=0)
    ax.plot(100 * FILLS, incompressible / 1000, "-", color="0.6", lw=0.7, zorder=1)
    ax.plot(100 * FILLS, lines / 1000, "o-", ms=3, lw=1.2, zorder=2)
    if len(extra):
        ax.plot(extra[:, 0], extra[:, 1] / 1000, "k.", ms=5, zorder=3)
    ax.plot(100 * FILLS, column / 1000, "k--", lw=0.8, zorder=3)
    ax.set(title=f"{name} ({obj.material.name}, {c.volume_m3 * 1e6:.0f} ml)", ylim=(0, MAX_HZ / 1000))
    ax.grid(alpha=0.3)
for ax in axes[1]:
    ax.set_xlabel("fill level [% of the cavity volume, water]")
for ax in axes[:, 0]:
    ax.set_ylabel("mode frequency [kHz]")
fig.suptitle("Modes below 12 kHz vs fill level: compressible water (colour; dots: further coupled modes;\n"
             "dashed: the liquid column's c/4h), incompressible (thin grey); shaded: the 3-10 kHz feature band")
fig.tight_layout()
out = Path(__file__).resolve().parents[1] / "docs" / "images" / "fill_level_sweep.png"
fig.savefig(out, dpi=120)
print(f"saved {out}")
