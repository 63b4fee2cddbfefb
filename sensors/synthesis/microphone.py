"""The contact microphone and the recorder behind it: object motion -> recorded samples.

Microphone level
----------------
A piezo contact microphone's output follows the surface motion under it; the rig records it
through a sound card at full scale 1.  ``MIC_GAIN_PER_M`` maps object displacement [m] at the
mic contact (the paper's choice of quantity) to recorded units: 2e5 per metre, i.e. full scale
at 5 um.  It is ONE constant for every object and grasp, so relative levels between objects
(material and damping information) survive.  Measured with the default fingertip model (1 N
exciter, 40 N grip) on the FEM bars (200 x 20 x 20 mm) and tubes (20/16 mm) of the paper's
materials, grasped antipodally 40 mm from the centre, 1 s recordings peak at about
0.003-0.05 (aluminium, steel, wood) under the sweeps, with 3-10 kHz spectral peaks of 1e-5 to
1e-4, well above a 1e-4 noise floor (1e-6 per bin); the soft ABS objects deflect far more
below their first mode and peak at 0.8-2.5 (a real rig would turn its preamp down).  The
grasp position matters as much as the material: moved along the bar (0-80 mm from the
centre) the metal bars peak at 0.001-0.04 under the linear sweep (lowest at 60 mm, e.g.
0.002 for aluminium) and the ABS bar at 0.2-4.  The one-sample impulse carries ~4e4 times
less energy than a sweep (~200x lower RMS).
Velocity and acceleration outputs use the same gain referred to 5 kHz (the middle of the
feature band): divided by 2 pi 5 kHz and (2 pi 5 kHz)^2.
Recorded values are not clipped (the waveform stays float32; a clipping rig would have to
lower its gain).

Noise and leak
--------------
White sensor noise (recorded units) is drawn sample by sample in recording order.  The leak
through the gripper (``sensors.LeakRecording``, recorded once per excitation with nothing
grasped) is looped as ``sensors.signals.aligned_leak_cycle`` aligns it for a recording that starts at
loop phase 0, its excitation peak at ``leak_lag_samples``.
"""

from __future__ import annotations

import os

import numpy as np

from ..signals.excitation import Excitation
from ..signals.leak import LeakRecording, aligned_leak_cycle, leak_file_identity, load_leak

__all__ = ["MIC_GAIN_PER_M", "Microphone", "mic_gain"]

MIC_GAIN_PER_M = 2e5
_REF_W = 2 * np.pi * 5000.0


def mic_gain(output: str = "displacement") -> float:
    """Recorded units per metre, per m/s or per m/s^2 (see module docstring)."""
    return {"displacement": MIC_GAIN_PER_M, "velocity": MIC_GAIN_PER_M / _REF_W,
            "acceleration": MIC_GAIN_PER_M / _REF_W**2}[output]


class Microphone:
    """Gain, white noise and leak: the object's motion at the mic -> float32 recorded samples.

    Parameters
    ----------
    excitation : the looped excitation (the leak was recorded under it).
    output : what the motion is: ``"displacement"`` [m], ``"velocity"`` or ``"acceleration"``.
    noise_std, rng : white sensor noise (recorded units) from this ``numpy.random.Generator``
        (or seed).
    leak : ``LeakRecording`` or its .npz path (``leak_file`` then says which file), or ``None``.
    leak_lag_samples : where the leak's excitation peak falls in each loop period.
    """

    def __init__(self, excitation: Excitation, output: str = "displacement", noise_std: float = 0.0, rng=None,
                 leak: LeakRecording | str | os.PathLike | None = None, leak_lag_samples: int = 0) -> None:
        if not np.isfinite(noise_std) or noise_std < 0:
            raise ValueError(f"noise_std must be >= 0, got {noise_std!r}")
        self.gain = mic_gain(output)
        self.noise_std = float(noise_std)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.leak_lag_samples = int(leak_lag_samples)
        self.leak_file: dict | None = None
        self._leak: np.ndarray | None = None      # one aligned leak cycle (whole periods)
        if leak is not None:
            if not isinstance(leak, LeakRecording):
                self.leak_file = leak_file_identity(leak)
                leak = load_leak(leak)
            self._leak = aligned_leak_cycle(leak, excitation, self.leak_lag_samples)

    def record(self, motion: np.ndarray, start: int = 0) -> np.ndarray:
        """The recorded samples (float32) of ``motion`` at samples ``start`` .. of the
        recording: gain, then noise, then leak, added in float64."""
        n = len(motion)
        wave = self.gain * motion
        if self.noise_std > 0:
            wave = wave + self.noise_std * self.rng.standard_normal(n)
        if self._leak is not None:
            wave = wave + self._leak[(start + np.arange(n)) % len(self._leak)]
        return wave.astype(np.float32)
