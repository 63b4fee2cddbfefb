"""Run the paper's protocols on a dataset and write the Markdown report with its figures."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed
from tqdm.auto import tqdm

from sensors._infra.atomic import atomic_savefig, atomic_write_text

from aas_gym.experiments.protocols import (
    CLASSIFIERS,
    PAPER_BEST_POSITION_RMSE_MM,
    PAPER_RECOGNITION,
    PositionResult,
    RecognitionResult,
    grasp_position,
    held_out_geometry,
    recognition,
)
from aas_gym.object_names import DEFAULT_OBJECT_NAMES


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def protocol_jobs(df, seed: int = 0) -> list:
    """The independent fits the dataset ``df`` supports, in report order: recognition per
    excitation (5-fold CV within single-object scenes, and single -> multi transfer), grasp
    position per object and excitation. Each job returns a list of results."""
    jobs = []
    for exc in sorted(df["excitation"].unique(), key=["impulse", "linear", "exponential"].index):
        single = df[(df.scene == "single") & (df.excitation == exc)]
        multi = df[(df.scene == "multi") & (df.excitation == exc)]
        if len(single) and single["object"].nunique() > 1:
            X, y = np.stack(single.features), single["object"].to_numpy()
            jobs.append(delayed(recognition)(X, y, excitation=exc, seed=seed))
            if len(multi):
                jobs.append(delayed(recognition)(X, y, excitation=exc, seed=seed, test_features=np.stack(multi.features),
                                                 test_labels=multi["object"].to_numpy()))
            shapes_of = single.groupby("material")["object"].nunique()
            if (shapes_of > 1).any():  # some material comes in several shapes: held-out geometry
                jobs.append(delayed(held_out_geometry)(X, single["material"].to_numpy(), single["object"].to_numpy(),
                                                       excitation=exc, seed=seed))
        sweep = df[(df.scene == "position") & (df.excitation == exc)]
        for obj in sorted(sweep["object"].unique()):
            rows = sweep[sweep["object"] == obj]
            if len(rows) >= 6:
                jobs.append(delayed(_position_job)(np.stack(rows.features), rows["position_m"].to_numpy(),
                                                   object_name=obj, excitation=exc, seed=seed))
    return jobs


def run_protocols(df, seed: int = 0, *, workers: int | None = None,
                  progress: bool = True) -> tuple[list[RecognitionResult], list[PositionResult]]:
    """All recognition and grasp-position results that the dataset ``df`` supports.

    The fits are independent: they run on ``workers`` processes (default: every core) with a
    progress bar; the results are those of a serial run, in the same order."""
    jobs = protocol_jobs(df, seed)
    workers = max(1, min(len(jobs), workers or os.cpu_count() or 1))
    runner = Parallel(n_jobs=workers, return_as="generator") if workers > 1 else (lambda js: (f(*a, **k) for f, a, k in js))
    rec: list[RecognitionResult] = []
    pos: list[PositionResult] = []
    for results in tqdm(runner(jobs), total=len(jobs), desc="protocols", unit="fit", disable=not progress):
        for r in results:
            (rec if isinstance(r, RecognitionResult) else pos).append(r)
    return rec, pos


def _position_job(*args, **kwargs) -> list[PositionResult]:
    """One grasp-position fit as a job: every job returns a list of results."""
    return [grasp_position(*args, **kwargs)]


#: Protocol keys and their names in tables and figures.
PROTOCOL_NAMES = {"single": "single -> single (5-fold)", "transfer": "single -> multiple",
                  "geometry": "material, held-out shape"}


def on_paper_objects(results: list[RecognitionResult]) -> bool:
    """Whether the objects recognized are among the paper's seven, so that the paper's
    accuracies are a comparison (another object set, such as the everyday objects, is not)."""
    labels = {label for r in results if r.protocol != "geometry" for label in r.labels}
    return bool(labels) and labels <= set(DEFAULT_OBJECT_NAMES)


def recognition_table(results: list[RecognitionResult], paper: bool | None = None) -> str:
    """Table II layout: simulated accuracy per excitation and protocol, next to the paper's
    when ``paper`` (default: when the objects are the paper's, :func:`on_paper_objects`)."""
    paper = on_paper_objects(results) if paper is None else paper
    header = " sim / paper" if paper else " sim"
    lines = ["| excitation | protocol | " + " | ".join(f"{c}{header}" for c in CLASSIFIERS) + " |",
             "|---|---|" + "---|" * len(CLASSIFIERS)]
    by_key = {(r.excitation, r.protocol, r.classifier): r.accuracy for r in results}
    for exc in ("impulse", "linear", "exponential"):
        for protocol, label in PROTOCOL_NAMES.items():
            if (exc, protocol, "KNN") not in by_key:
                continue
            ours = [f"{by_key[(exc, protocol, c)]:.1f}" for c in CLASSIFIERS]
            if paper:
                theirs = PAPER_RECOGNITION[exc].get(protocol, [float("nan")] * len(CLASSIFIERS))
                ours = [f"{a} / " + ("-" if p != p else f"{p:.1f}") for a, p in zip(ours, theirs)]
            lines.append(f"| {exc} | {label} | " + " | ".join(ours) + " |")
    return "\n".join(lines)


def position_table(results: list[PositionResult]) -> str:
    excs = [e for e in ("impulse", "linear", "exponential") if any(r.excitation == e for r in results)]
    objs = sorted({r.object_name for r in results})
    by_key = {(r.object_name, r.excitation): r.rmse_mm for r in results}
    lines = ["| object | " + " | ".join(f"{e} RMSE [mm]" for e in excs) + " |", "|---|" + "---|" * len(excs)]
    for obj in objs:
        lines.append(f"| {obj} | " + " | ".join(f"{by_key[(obj, e)]:.2f}" if (obj, e) in by_key else "-" for e in excs) + " |")
    return "\n".join(lines)


def plot_confusions(results: list[RecognitionResult], path: Path) -> Path:
    plt = _plt()
    picked = [r for r in results if r.classifier == "MLP"]
    rows = [p for p in PROTOCOL_NAMES if any(r.protocol == p for r in picked)]
    fig, axes = plt.subplots(len(rows), 3, figsize=(15, 4.75 * len(rows)), constrained_layout=True, squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for r in picked:
        row = rows.index(r.protocol)
        col = ["impulse", "linear", "exponential"].index(r.excitation)
        ax = axes[row, col]
        ax.axis("on")
        cm = r.confusion / np.maximum(r.confusion.sum(axis=1, keepdims=True), 1)
        ax.imshow(cm, vmin=0, vmax=1, cmap="Blues")
        ax.set_xticks(range(len(r.labels)), r.labels, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(r.labels)), r.labels, fontsize=7)
        for i in range(cm.shape[0]):
            for j in range(cm.shape[1]):
                if r.confusion[i, j]:
                    ax.text(j, i, r.confusion[i, j], ha="center", va="center", fontsize=7,
                            color="white" if cm[i, j] > 0.5 else "black")
        name = PROTOCOL_NAMES[r.protocol].replace(" (5-fold)", "")
        ax.set_title(f"MLP, {r.excitation}, {name}: {r.accuracy:.1f}%", fontsize=9)
        ax.set(xlabel="predicted", ylabel="true")
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)
    return path


def plot_positions(results: list[PositionResult], path: Path) -> Path:
    plt = _plt()
    objs = sorted({r.object_name for r in results})
    fig, axes = plt.subplots(1, len(objs), figsize=(3.2 * len(objs), 3.4), constrained_layout=True, squeeze=False)
    for ax, obj in zip(axes[0], objs):
        for r in results:
            if r.object_name == obj:
                ax.plot(r.true_mm, r.predicted_mm, ".", ms=4, label=f"{r.excitation} ({r.rmse_mm:.2f} mm)")
        lim = max(r.true_mm.max() for r in results) + 5
        ax.plot([0, lim], [0, lim], "k--", lw=0.6)
        ax.set(title=obj, xlabel="true position [mm]", ylabel="predicted [mm]", xlim=(-3, lim), ylim=(-3, lim))
        ax.legend(fontsize=6)
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)
    return path


def plot_spectra(curves: list[tuple[str, str, np.ndarray, np.ndarray]], path: Path,
                 band_hz: tuple[float, float] = (3000.0, 10000.0)) -> Path:
    """The spectra figure: one panel per factor, over the whole feature band; full-resolution
    spectra are drawn raw and Savitzky-Golay smoothed (the paper's figure), feature vectors
    (50 Hz steps) as they are.

    ``curves``: (panel title, curve label, frequencies_hz, amplitude [full scale]) tuples.
    """
    from sensors import smooth_spectrum

    plt = _plt()
    panels = list(dict.fromkeys(c[0] for c in curves))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6), constrained_layout=True, squeeze=False)
    for ax, panel in zip(axes[0], panels):
        for k, (_, label, f, a) in enumerate(c for c in curves if c[0] == panel):
            band = (f >= band_hz[0]) & (f <= band_hz[1])
            color = f"C{k}"
            if f.size > 1 and f[1] - f[0] >= 10.0:  # feature vectors: few points, drawn as they are
                ax.semilogy(f[band], a[band], lw=1.0, color=color, label=label)
                continue
            ax.semilogy(f[band], a[band], lw=0.3, color=color, alpha=0.35)
            # Smooth the log-amplitude: smoothing the amplitude itself overshoots below zero at sharp peaks.
            smooth = 10 ** smooth_spectrum(np.log10(np.maximum(a, 1e-30)), 101)
            ax.semilogy(f[band], smooth[band], lw=1.2, color=color, label=label)
        ax.set(title=panel, xlabel="frequency [Hz]", ylabel="amplitude [full scale]", xlim=band_hz)
        ax.legend(fontsize=7)
    atomic_savefig(fig, path, dpi=100)
    plt.close(fig)
    return path


def write_report(rec: list[RecognitionResult], pos: list[PositionResult], out_dir: Path, *,
                 spectra: list | None = None, notes: str = "") -> Path:
    """Write ``report.md`` with its figures into ``out_dir`` from the results of
    :func:`run_protocols`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paper = on_paper_objects(rec)
    parts = ["# aas-gym: the paper's experiments in simulation" if paper or not rec
             else "# aas-gym: the paper's protocols on other objects, in simulation", ""]
    if rec:
        parts += [f"## Object recognition (accuracy %, simulated{' / paper' if paper else ''})", "",
                  recognition_table(rec, paper), ""]
        if not paper:
            parts += ["The objects are not the paper's, so its accuracies are not shown beside these.", ""]
        parts += ["![confusion matrices](confusion.png)", ""]
        plot_confusions(rec, out_dir / "confusion.png")
    if pos:
        best = min(pos, key=lambda r: r.rmse_mm)
        parts += ["## Grasp position (KNN k = 3, 3-fold CV)", "", position_table(pos), "",
                  f"Best: {best.object_name}, {best.excitation} sweep, {best.rmse_mm:.2f} mm "
                  f"(paper's best: wood bar, linear sweep, {PAPER_BEST_POSITION_RMSE_MM} mm).", "",
                  "![predicted vs true position](positions.png)", ""]
        plot_positions(pos, out_dir / "positions.png")
    if spectra:
        plot_spectra(spectra, out_dir / "spectra.png")
        parts += ["## Spectra across material, shape, grasp position and contact", "",
                  "![spectra](spectra.png)", ""]
    if notes:
        parts += ["## What the results say", "", notes.strip(), ""]
    path = out_dir / "report.md"
    atomic_write_text(path, "\n".join(parts))
    return path
