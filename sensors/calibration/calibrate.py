"""The whole calibration: estimate modes, match them, fit E and the damping."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..modal.damping import contact_damping_matrix
from ..signals.leak import LeakRecording, load_leak
from ..materials.solids import Material, get_material
from .estimation import ModalEstimate, estimate_modes_from_observation
from ..signals.observation import AcousticObservation
from .damping_fit import DampingFit, fit_damping, refine_damping_exact
from .recordings import RecordingSetup, mode_clusters, observability
from .stiffness import StiffnessFit, fit_stiffness, log_decay_terms, match_modes, undamped_frequencies_hz
from .grasp_modes import recording_contact_model, recording_modes, scaled_frequencies_hz

#: The E fit under contact springs is a fixed point (the springs' share of each coupled mode's
#: stiffness does not scale with E): iterate until the frequency scale moves less than this
#: (relative), at most ``_SPRING_FIT_ITERATIONS`` times.
_SPRING_FIT_RTOL = 1e-5
_SPRING_FIT_ITERATIONS = 12


@dataclass
class CalibrationResult:
    """Everything :func:`calibrate` found.

    Attributes:
        material: the calibrated material.
        base_material: the material it started from.
        stiffness: the Young's modulus fit (``None`` if E was not fitted).
        damping: the alpha / beta / gamma fit.
        estimates: the modal estimate of each recording.
        contact_model: the contact model the fit inverted (``"spring_damper"`` or
            ``"damping"``, as the synthesis' ``contact_model``).
    """

    material: Material
    base_material: Material
    stiffness: StiffnessFit | None
    damping: DampingFit
    estimates: list[ModalEstimate]
    contact_model: str = "damping"

    def report(self) -> dict[str, Any]:
        """JSON-friendly summary with uncertainties (stored in the material file)."""
        d = self.damping
        std = d.std
        out: dict[str, Any] = {
            "base_material": self.base_material.to_dict(),
            "alpha": {"value": d.alpha, "std": std[0], "bootstrap_std": d.bootstrap_std[0]},
            "beta": {"value": d.beta, "std": std[1], "bootstrap_std": d.bootstrap_std[1]},
            "gamma": {"value": d.gamma, "std": std[2], "bootstrap_std": d.bootstrap_std[2], "fitted": d.gamma_fitted},
            "damping_modes_used": d.n_modes,
            "damping_modes_rejected": d.n_rejected,
            "damping_chi2_reduced": d.chi2_reduced,
            "modes_found_per_recording": [len(e) for e in self.estimates],
            "contact_model": self.contact_model,
        }
        if self.stiffness is not None:
            s = self.stiffness
            out["youngs_modulus_pa"] = {
                "value": self.material.youngs_modulus_pa,
                "std": self.base_material.youngs_modulus_pa * s.youngs_modulus_factor_std,
                "factor_to_base": s.youngs_modulus_factor,
            }
            out["modes_matched"] = s.n_matched
            out["frequency_rms_relative_misfit"] = s.rms_log_misfit
        return out


@dataclass(frozen=True)
class _VisibleModes:
    """What one recording can show of the modes it is made of: the clusters of modes
    observable between its fingertips (ids into ``clusters``, their frequencies at the base
    E, sizes and prior decay rates) and its contact damping per unit gamma."""

    cluster_ids: np.ndarray
    frequencies_hz: np.ndarray
    sizes: np.ndarray
    decay_priors: np.ndarray
    contact_damping: np.ndarray
    clusters: list


def _visible_modes(modes, setup: RecordingSetup, base: Material, f_base, min_observability: float) -> _VisibleModes:
    """``modes``: the modal basis of the recording (the model, or the model held by the
    recording's contact springs); ``f_base`` [Hz]: its frequencies at the base material's E."""
    clusters = mode_clusters(f_base)
    cluster_f = np.array([f_base[c].mean() for c in clusters])
    cluster_n = np.array([c.size for c in clusters])
    w_base = 2 * np.pi * f_base
    G = contact_damping_matrix(modes, setup.contacts)
    prior = 0.5 * (base.alpha + base.beta * w_base**2 + base.gamma * np.diag(G))
    obs = observability(modes, setup.actuator, setup.mic)
    obs_c = np.array([math.sqrt(np.sum(obs[c] ** 2)) for c in clusters])
    visible = obs_c >= min_observability * obs_c.max() if obs_c.max() > 0 else np.zeros(len(clusters), bool)
    ids = np.flatnonzero(visible)
    return _VisibleModes(ids, cluster_f[ids], cluster_n[ids], np.array([prior[clusters[i]].mean() for i in ids]), G,
                         clusters)


@dataclass(frozen=True)
class _MatchedMode:
    """One measured mode matched to a cluster of model modes: a row of the damping fit."""

    frequency_hz: float          # undamped frequency of the measured mode
    decay_rate_per_s: float
    decay_rate_std_per_s: float
    contact_term: float          # mean diagonal of G over the cluster (per unit gamma)
    recording: int
    modes: np.ndarray            # the model modes of the cluster


def _contact_term(G: np.ndarray, modes: np.ndarray) -> float:
    return float(np.trace(G[np.ix_(modes, modes)]) / modes.size)


def _as_leaks(leak) -> list:
    if leak is None:
        return []
    items = leak if isinstance(leak, (list, tuple)) else [leak]
    return [lk if isinstance(lk, LeakRecording) else load_leak(lk) for lk in items]


def calibrate(
    model,
    recordings: Sequence[RecordingSetup | AcousticObservation],
    base_material: Material | str | None = None,
    *,
    fit_youngs_modulus: bool = True,
    fit_gamma: bool | str = "auto",
    factor_range: tuple[float, float] = (1 / 3, 3.0),
    rel_tol: float = 0.01,
    min_observability: float = 1e-3,
    name: str | None = None,
    estimates: Sequence[ModalEstimate] | None = None,
    damping_model: str = "exact",
    rel_floor: float = 0.02,
    leak=None,
    contact_model: str | None = None,
    **estimate_kwargs: Any,
) -> CalibrationResult:
    """Fit E, alpha, beta and gamma of ``model``'s material to recordings of the object.

    Args:
        model: the object's modal model built with ``base_material`` (``sensors.ModalModel``
            or compatible: ``angular_frequencies_rad_s``, ``mode_shapes_at``, ``material``).
        recordings: :class:`RecordingSetup` (or observations with contacts in their metadata).
        base_material: starting material (default: the model's).
        fit_youngs_modulus: fit the E scale (else match at the base E).
        fit_gamma: True, False, or ``"auto"``: fit gamma when the recordings' contact damping
            differs between recordings (grip forces, contact sets) enough to separate it
            from alpha and beta; else hold it at the base value.
        factor_range: search range for E / E_base.
        rel_tol: relative frequency tolerance of the model (mode matching).
        min_observability: model modes (clusters) whose actuator-to-mic response is below this
            fraction of the strongest are not expected in the recording and not matched.
        name: name of the calibrated material (default ``"<base>-calibrated"``).
        estimates: modal estimates already made (skips estimation).
        damping_model: ``"diagonal"``: sigma = C_cc / 2 (first order, linear least squares);
            ``"exact"`` (default): then refine by nonlinear least squares on the eigenvalues
            of the full damped system of each recording, since contact damping couples
            modes and the diagonal is biased when modes are close or contact damping is
            strong (the damped system is 2r x 2r; r is a few hundred at most).
        rel_floor: relative model error of a decay rate (see :func:`fit_damping`).
        leak: the rig's idle leak recording(s) (``sensors.LeakRecording``, a path to one, or
            a sequence of them, one per excitation): removed from each recording made with
            the matching excitation before its modes are estimated.
        contact_model: the contact model of the simulation being calibrated, as the
            synthesis' ``contact_model``: ``"spring_damper"`` (the fingertip pads hold the
            object with the pad springs of the recording's fingertip, other contacts with
            their Hertz/Mindlin springs; the modes fitted are each recording's coupled modes,
            :mod:`sensors.calibration.grasp_modes`) or ``"damping"`` (the paper's model: the
            free modes, which scale with sqrt(E)).  ``None`` (default): the one the recordings'
            metadata names, else ``"spring_damper"``.
        **estimate_kwargs: passed to :func:`sensors.calibration.estimation.estimate_modes_from_observation`.
    """
    if damping_model not in ("exact", "diagonal"):
        raise ValueError(f"damping_model must be 'exact' or 'diagonal', got {damping_model!r}")
    base = get_material(base_material) if base_material is not None else model.material
    if not isinstance(base, Material):
        raise TypeError(f"base material must be a sensors.Material or a table name, got {type(base).__name__}")
    setups = [r if isinstance(r, RecordingSetup) else RecordingSetup.from_observation(r) for r in recordings]
    if not setups:
        raise ValueError("no recordings")
    contact_model = recording_contact_model(setups, contact_model)
    if estimates is None:
        leaks = _as_leaks(leak)
        estimates = []
        for s in setups:
            kw = dict(estimate_kwargs)
            if leaks:
                match = [lk for lk in leaks if lk.matches(s.observation.excitation)]
                if not match:
                    raise ValueError(f"no leak recording for the {s.observation.excitation.name} excitation")
                kw["leak"] = match[0]
            estimates.append(estimate_modes_from_observation(s.observation, **kw))
    estimates = list(estimates)
    if contact_model == "damping":
        w_model = np.asarray(model.angular_frequencies_rad_s, float)
        # the model may have been built with another E than the base material's
        model_E = float(model.material.youngs_modulus_pa)
        f_base = w_model / (2 * np.pi) * math.sqrt(base.youngs_modulus_pa / model_E)
        visible = [_visible_modes(model, s, base, f_base, min_observability) for s in setups]
        stiff = _fit_scale(estimates, visible, fit_youngs_modulus, factor_range, rel_tol)
        scale = stiff.scale if stiff is not None else 1.0
        # the free modes at the fitted E, one set for every recording
        w_fit = [w_model * math.sqrt(base.youngs_modulus_pa / model_E) * scale] * len(setups)
    else:
        visible, stiff, scale, w_fit = _fit_scale_with_springs(model, setups, base, estimates, fit_youngs_modulus,
                                                               factor_range, rel_tol, min_observability)
    if stiff is not None:
        matches = stiff.matches
    else:
        priors = [v.decay_priors for v in visible]
        matches = [match_modes(np.log(undamped_frequencies_hz(e)), np.log(v.frequencies_hz), v.sizes, 0.0, rel_tol,
                               *log_decay_terms(e, priors, k))
                   for k, (e, v) in enumerate(zip(estimates, visible))]

    undamped = [undamped_frequencies_hz(est) for est in estimates]  # once per recording
    rows = [_MatchedMode(float(undamped[r][i]), float(est.decay_rates_per_s[i]), float(est.decay_rate_std_per_s[i]),
                         _contact_term(v.contact_damping, v.clusters[v.cluster_ids[c]]), r,
                         v.clusters[v.cluster_ids[c]])
            for r, (est, m, v) in enumerate(zip(estimates, matches, visible)) for i, c in m]
    rows_f = np.array([row.frequency_hz for row in rows])
    rows_sig = np.array([row.decay_rate_per_s for row in rows])
    rows_sd = np.array([row.decay_rate_std_per_s for row in rows])
    rec_of_row = [row.recording for row in rows]
    members = [row.modes for row in rows]
    G_list = [v.contact_damping for v in visible]
    g = np.array([row.contact_term for row in rows])
    if fit_gamma == "auto":
        # gamma separates from alpha + beta w^2 only if g varies between recordings for the
        # same modes; require the per-recording mean contact term to differ by 10 %
        rec = np.asarray(rec_of_row)
        means = [g[rec == r].mean() for r in np.unique(rec)] if g.size else []
        fit_gamma = len(means) >= 2 and (max(means) - min(means)) > 0.1 * max(max(means), 1e-300)
    damping = fit_damping(rows_f, rows_sig, rows_sd, g,
                          gamma=None if fit_gamma else base.gamma, rel_floor=rel_floor)
    if damping_model == "exact":
        sd = np.sqrt(rows_sd ** 2 + (rel_floor * rows_sig) ** 2)
        damping = refine_damping_exact(damping, w_fit if contact_model != "damping" else w_fit[0],
                                       G_list, np.asarray(rec_of_row), members, rows_sig, sd,
                                       None if fit_gamma else base.gamma, rows_f)
    material = dataclasses.replace(
        base, name=name or f"{base.name}-calibrated", youngs_modulus_pa=base.youngs_modulus_pa * scale**2,
        alpha=damping.alpha, beta=damping.beta, gamma=damping.gamma)
    return CalibrationResult(material, base, stiff, damping, estimates, contact_model)


def _fit_scale(estimates, visible, fit_youngs_modulus: bool, factor_range, rel_tol) -> StiffnessFit | None:
    """The E scale from the matched frequencies of ``visible`` (at the base E); ``None`` when
    E is not fitted."""
    if not fit_youngs_modulus:
        return None
    return fit_stiffness(estimates, [v.frequencies_hz for v in visible], [v.sizes for v in visible],
                         factor_range=factor_range, rel_tol=rel_tol,
                         cluster_decay_priors=[v.decay_priors for v in visible])


def _fit_scale_with_springs(model, setups, base: Material, estimates, fit_youngs_modulus: bool, factor_range,
                            rel_tol, min_observability):
    """The E scale s under the recordings' contact springs: the fixed point of "build each
    recording's coupled modes at E = s^2 E_base, match them, fit s" (the springs' share of a
    coupled mode's stiffness does not scale with E, so no single scale of one set of modes
    does).  Secant steps on log s once two iterates exist.  Returns ``(visible, stiffness
    fit, scale, angular frequencies [rad/s] of each recording's modes at the fitted E)``."""
    log_s, history = 0.0, []
    for _ in range(_SPRING_FIT_ITERATIONS):
        s = math.exp(log_s)
        material = dataclasses.replace(base, youngs_modulus_pa=base.youngs_modulus_pa * s * s)
        modes = recording_modes(model, setups, material, "spring_damper")
        visible = [_visible_modes(m, st, base, scaled_frequencies_hz(m, s), min_observability)
                   for m, st in zip(modes, setups)]
        stiff = _fit_scale(estimates, visible, fit_youngs_modulus, factor_range, rel_tol)
        if stiff is None:
            break
        step = math.log(stiff.scale) - log_s              # h(log s): zero at the fixed point
        if abs(step) < _SPRING_FIT_RTOL:
            break
        history.append((log_s, step))
        if len(history) >= 2 and history[-1][1] != history[-2][1]:
            (x0, h0), (x1, h1) = history[-2], history[-1]
            secant = -h1 * (x1 - x0) / (h1 - h0)
            # a plain fixed-point step where the secant is not a contraction (matches changed)
            step = secant if 0.0 < secant / step < 10.0 else step
        log_s += step
    scale = stiff.scale if stiff is not None else 1.0
    return visible, stiff, scale, [np.asarray(m.angular_frequencies_rad_s, float) for m in modes]


def log_spectral_distance_db(recording: AcousticObservation, simulation: AcousticObservation,
                             band_hz: tuple[float, float] = (200.0, 9800.0)) -> float:
    """RMS difference [dB] of the amplitude spectra of two observations of the same excitation
    over ``band_hz``: how well a simulation (e.g. with a calibrated material) reproduces a
    recording; two noisy recordings of one object differ by the noise-limited floor."""
    f, a_rec = recording.spectrum()
    _, a_sim = simulation.spectrum()
    band = (f >= band_hz[0]) & (f <= band_hz[1])
    return float(np.sqrt(np.mean((20 * np.log10(a_sim[band] / a_rec[band])) ** 2)))
