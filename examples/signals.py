"""The paper's three excitations, their spectra and the 140 features they give.

Run: python examples/signals.py   -> outputs/excitations.png
"""

from pathlib import Path

import sensors
from aas_gym.demo import render_signals

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"

for exc in (sensors.Excitation.impulse(), sensors.Excitation.linear_sweep(), sensors.Excitation.exponential_sweep()):
    features = sensors.spectral_features(exc.loop(1.0), exc.sample_rate_hz)
    print(f"{exc.name:12s} features {features.shape}, mean amplitude {features.mean():.3g}")
print("wrote", render_signals(OUTPUTS))
