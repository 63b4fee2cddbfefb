"""Calibrate a material (stiffness and damping) from recordings of a grasped object.

What is fitted, and from what:

- **Young's modulus**: with geometry, density and Poisson's ratio fixed, the stiffness matrix
  is proportional to E and the mass matrix does not depend on it, so every modal frequency
  scales with sqrt(E) and the mass-normalised mode shapes do not change. The scale
  ``s = sqrt(E / E_base)`` is found by matching measured frequencies to the model's
  observable modes with a robust score (missing and extra modes cost nothing but a lost
  vote), then refined by a weighted mean of log frequency ratios over the matched pairs.
- **Rayleigh alpha, beta and contact gamma** in one weighted linear least squares: a
  measured mode matched to model mode (or cluster of near-repeated modes) ``c`` in a
  recording with contacts P obeys, to first order in the damping,
  ``sigma = (alpha + beta w^2 + gamma G_cc) / 2`` with ``G = sum_p c_p U_p^T (mu I +
  (1 - mu) n n^T) U_p`` the contact damping per unit gamma of that recording's contacts
  (:func:`sensors.modal.damping.contact_damping_matrix`). gamma is identifiable when the
  recordings differ in grip force or contact set; otherwise it is held at the base value.
  Weights come from each decay rate's standard deviation plus a relative floor for model
  error; uncertainties from the covariance (scaled by the reduced chi-square when the
  scatter exceeds the error bars) and from a bootstrap over modes.

- **Contact springs** (``contact_model``, as the synthesis'): with ``"spring_damper"`` (the
  default, and what recordings without metadata get) each recording's modes are the object's
  coupled modes under its contact springs (the fingertip pads' springs, Hertz/Mindlin for the
  others; :mod:`sensors.calibration.grasp_modes`). They do not scale with sqrt(E) alone, so
  E is the fixed point of "couple at E, match, fit the scale", and the damping rows use the
  coupled modes' frequencies and contact damping. ``"damping"`` is the paper's model (free
  modes); a simulated recording's metadata says which model made it.

The calibrated :class:`sensors.Material` is written as JSON by :func:`save_material` and read
back by :func:`load_material`.
"""

from __future__ import annotations

from .calibrate import CalibrationResult, calibrate, log_spectral_distance_db
from .grasp_modes import recording_contact_model, recording_contacts, recording_modes
from .damping_fit import DampingFit, exact_decay_rates, fit_damping, refine_damping_exact
from .material_files import MATERIAL_FILE_FORMAT, load_material, save_material
from .recordings import RecordingSetup, mode_clusters, observability
from .stiffness import StiffnessFit, fit_stiffness, log_decay_terms, match_modes, undamped_frequencies_hz

__all__ = [
    "MATERIAL_FILE_FORMAT",
    "save_material",
    "load_material",
    "RecordingSetup",
    "StiffnessFit",
    "DampingFit",
    "CalibrationResult",
    "mode_clusters",
    "observability",
    "undamped_frequencies_hz",
    "fit_stiffness",
    "fit_damping",
    "match_modes",
    "log_decay_terms",
    "exact_decay_rates",
    "refine_damping_exact",
    "calibrate",
    "recording_contact_model",
    "recording_contacts",
    "recording_modes",
    "log_spectral_distance_db",
]
