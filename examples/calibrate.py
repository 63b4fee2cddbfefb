"""Calibrate a material from recordings, then simulate with it.

A "real" ABS bar whose stiffness and damping differ from the paper's table is recorded at two
grip forces and two grasp positions (here by the simulator, standing in for the rig; on the
rig use ``aas record`` and the same files). The calibration fits E, alpha, beta and gamma,
writes a material file, and the file is loaded back to simulate the object.

    python examples/calibrate.py

The same from the command line, on the files this script writes:

    aas calibrate outputs/calibration/*.npz --material abs --shape bar --dims 0.2 0.02 0.01 \
        --max-frequency-hz 12000 --out outputs/calibration/abs-calibrated.json
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sensors  # noqa: E402
from sensors import Contact, Excitation, simulate_recording  # noqa: E402
from sensors import with_material  # noqa: E402
from sensors.calibration import calibrate, load_material, save_material  # noqa: E402
from sensors.materials.solids import get_material  # noqa: E402

OUT = ROOT / "outputs" / "calibration"
LENGTH_M, WIDTH_M, HEIGHT_M = 0.2, 0.02, 0.01


def bar_model(material):
    """The bar's modal model (FEM)."""
    # modes a little above the analysed band (<= 10 kHz) are all the calibration needs
    return sensors.ModalModel.bar(LENGTH_M, WIDTH_M, HEIGHT_M, material, max_frequency_hz=12_000.0)


def grasp(x_m: float, force_n: float):
    """Antipodal grasp across the bar's height at x: actuator on top, microphone below."""
    h = HEIGHT_M / 2
    return Contact([x_m, 0.002, h], [0, 0, 1], force_n, 0.5), Contact([x_m, 0.002, -h], [0, 0, -1], force_n, 0.5)


def main() -> None:
    table = get_material("abs")
    model = bar_model(table)

    # 1. "Real" recordings: 5 s each (as the paper records), 30 dB SNR.
    truth = dataclasses.replace(table, youngs_modulus_pa=2.9e9, alpha=6.0, beta=2.4e-7, gamma=0.05)
    real = with_material(model, truth)
    exc = Excitation.linear_sweep()
    paths = []
    for k, (x, force) in enumerate([(0.03, 10.0), (0.03, 40.0), (0.055, 10.0), (0.055, 40.0)]):
        actuator, mic = grasp(x, force)
        clean = simulate_recording(real, exc, 5.0, actuator, mic)
        noise = 10 ** (-30 / 20) * float(np.sqrt(np.mean(clean.waveform.astype(float) ** 2)))
        obs = simulate_recording(real, exc, 5.0, actuator, mic, noise_std=noise, rng=k)
        paths.append(obs.save(OUT / f"abs_x{int(x * 1e3)}mm_{int(force)}N.npz"))
    print(f"wrote {len(paths)} recordings to {OUT}")

    # 2. Calibrate (contacts come from the recordings' metadata).
    recordings = [sensors.AcousticObservation.load(p) for p in paths]
    result = calibrate(model, recordings, table)
    m, sd = result.material, result.damping.std
    print(f"{'':6s}{'table':>10s}{'calibrated':>12s}{'+-':>10s}{'truth':>10s}")
    print(f"{'E':6s}{table.youngs_modulus_pa:10.3g}{m.youngs_modulus_pa:12.4g}"
          f"{result.report()['youngs_modulus_pa']['std']:10.2g}{truth.youngs_modulus_pa:10.3g}")
    for i, name in enumerate(("alpha", "beta", "gamma")):
        print(f"{name:6s}{getattr(table, name):10.3g}{getattr(m, name):12.4g}{sd[i]:10.2g}{getattr(truth, name):10.3g}")

    # 3. Write the material file, load it back, simulate with it.
    path = save_material(OUT / "abs-calibrated.json", m, calibration=result.report())
    loaded = load_material(path)
    actuator, mic = grasp(0.04, 40.0)
    sim = simulate_recording(with_material(model, loaded), exc, 1.0, actuator, mic)
    print(f"wrote {path}; simulated a new grasp with it: {sim.features().shape[0]} features")


if __name__ == "__main__":
    main()
