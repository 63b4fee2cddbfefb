"""The report of a generated dataset: protocols, figures, and what the numbers say."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from aas_gym.experiments.generate import load_dataset
from aas_gym.experiments.protocols import RecognitionResult
from aas_gym.experiments.report import run_protocols, write_report
from sensors._infra.atomic import atomic_write_text


def dataset_spectra(df, excitation: str = "linear") -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """The spectra figure's curves, from the dataset itself: mean feature vectors (3-10 kHz)
    that differ in one factor each: material (single-object scenes, bars), shape (bar and
    tube of one material), grasp position (the position sweep) and contact (the same object
    alone and with others lying across it)."""
    from sensors import feature_frequencies_hz

    f = feature_frequencies_hz()
    d = df[df.excitation == excitation]
    if d.empty:
        d = df[df.excitation == df.excitation.iloc[0]]
    curves = []

    def mean(rows):
        return np.mean(np.stack(rows.features), axis=0)

    single = d[d.scene == "single"]
    for obj in sorted(o for o in single.object.unique() if o.endswith("_bar")):
        curves.append(("material (bars, single-object scenes)", obj.split("_")[0], f, mean(single[single.object == obj])))
    both = sorted(m for m in single.material.unique() if {"bar", "tube"} <= set(single[single.material == m]["shape"]))
    if both:
        for obj in (f"{both[0]}_bar", f"{both[0]}_tube"):
            curves.append((f"shape ({both[0]})", obj.split("_")[1], f, mean(single[single.object == obj])))
    sweep = d[d.scene == "position"]
    if not sweep.empty:
        obj = sorted(sweep.object.unique())[0]
        rows = sweep[sweep.object == obj]
        positions = np.sort(rows.position_m.unique())
        for p in positions[[0, len(positions) // 2, -1]] if len(positions) > 2 else positions:
            curves.append((f"grasp position ({obj})", f"{p * 1e3:.0f} mm", f, mean(rows[rows.position_m == p])))
    multi = d[d.scene == "multi"]
    common = sorted(set(single.object) & set(multi.object))
    if common:
        obj = common[0]
        curves.append((f"contact ({obj})", "alone", f, mean(single[single.object == obj])))
        curves.append((f"contact ({obj})", "others lying across", f, mean(multi[multi.object == obj])))
    return curves


def _notes(df, rec: list[RecognitionResult], pos) -> str:
    """Observations computed from the results (nothing here is typed in by hand)."""
    lines = []
    single = {(r.excitation, r.classifier): r for r in rec if r.protocol == "single"}
    transfer = {(r.excitation, r.classifier): r for r in rec if r.protocol == "transfer"}
    if single:
        best = max(single.values(), key=lambda r: r.accuracy)
        lines.append(f"- Single-object recognition peaks at {best.accuracy:.1f}% ({best.classifier}, {best.excitation}).")
        # Bar vs tube of one material: how often are they confused?
        for r in single.values():
            pairs = [(i, j) for i, a in enumerate(r.labels) for j, b in enumerate(r.labels)
                     if a.split("_")[0] == b.split("_")[0] and a != b
                     and {a.rpartition("_")[2], b.rpartition("_")[2]} == {"bar", "tube"}]
            if pairs and r is best:
                confused = sum(r.confusion[i, j] for i, j in pairs)
                total = sum(r.confusion[i].sum() for i in {i for i, _ in pairs})
                lines.append(f"- Bar and tube of the same material (same length and outer size) are confused in "
                             f"{confused} of {total} predictions ({best.classifier}, {best.excitation}): their mode "
                             f"frequencies differ (a tube has a larger radius of gyration, so higher bending modes, and "
                             f"its thin wall adds low cross-section modes).")
    if single and transfer:
        drops = [single[k].accuracy - transfer[k].accuracy for k in transfer if k in single]
        mean_drop = float(np.mean(drops))
        if mean_drop > 0:
            lines.append(f"- Multi-object scenes are harder: trained on single-object scenes, the classifiers lose "
                         f"{mean_drop:.1f} points on average on multi-object scenes (from {min(drops):+.1f} to "
                         f"{max(drops):+.1f}). Objects lying across the target touch it at new places: with contact "
                         f"springs (the default) they vibrate with it, coupled through the contact "
                         f"(sensors.modal.TouchingObjects), which adds and shifts resonances; with the paper's "
                         f"damping-only model they only damp some resonances.")
        else:
            lines.append(f"- Multi-object scenes are NOT harder here: transfer accuracy is {-mean_drop:.1f} points "
                         f"above the single-object cross-validation on average (training on all single-object "
                         f"data also uses a quarter more data than a CV fold).")
        if "other_contact_force_n" in df and mean_drop <= 0:
            f_single = df[df.scene == "single"].other_contact_force_n.mean()
            f_multi = df[df.scene == "multi"].other_contact_force_n.mean()
            lines.append(f"- Why contacts matter little in simulation: the table and the objects lying across the "
                         f"target press on it with {f_single:.1f} N (single) and {f_multi:.1f} N (multi) in total on "
                         f"average, against 2 x {df.grip_force_n.mean():.0f} N of grip. In the paper's contact model "
                         f"(Zheng & James) damping grows with contact force, so these contacts add little damping; "
                         f"the default contact springs couple the touching objects to the target, the paper's "
                         f"damping-only model does not.")
    geometry = [r for r in rec if r.protocol == "geometry"]
    if geometry:
        best = max(geometry, key=lambda r: r.accuracy)
        chance = 100.0 / len(best.labels)
        lines.append(f"- Material on a shape never trained on: at best {best.accuracy:.1f}% ({best.classifier}, "
                     f"{best.excitation}; chance {chance:.0f}%). The 140-d features are mode frequencies and "
                     f"amplitudes, which shape sets as much as material: a classifier that has seen one shape of a "
                     f"material has not learnt the material's damping or sound speed apart from that shape.")
    if pos:
        best = min(pos, key=lambda r: r.rmse_mm)
        worst = max(pos, key=lambda r: r.rmse_mm)
        lines.append(f"- Grasp positions 5 mm apart are resolved to {best.rmse_mm:.2f} mm RMSE at best "
                     f"({best.object_name}, {best.excitation}) and {worst.rmse_mm:.2f} mm at worst "
                     f"({worst.object_name}, {worst.excitation}). Moving the fingertips along the bar moves the "
                     f"drive and pick-up points across the mode shapes, so each mode's amplitude changes smoothly "
                     f"with position; heavily damped materials keep fewer resolvable modes.")
    lines.append("- Differences from the paper: the simulation has no unmodelled variability (object-to-object "
                 "tolerances, fingertip wear, room noise, cable motion), so single-object accuracies are higher "
                 "than on the real rig. The impulse, a single click, carries about 1/10000 of a sweep's energy, "
                 "so at the same microphone noise its features sit near the noise floor.")
    return "\n".join(lines)


def report_dataset(dataset_dir: Path, out_dir: Path, seed: int = 0, workers: int | None = None) -> Path:
    """Protocols, figures and notes of the dataset in ``dataset_dir`` -> ``out_dir/report.md``
    (every file written atomically; the fits run on ``workers`` processes)."""
    df = load_dataset(dataset_dir)
    rec, pos = run_protocols(df, seed=seed, workers=workers)
    spectra = dataset_spectra(df)
    path = write_report(rec, pos, out_dir, spectra=spectra, notes=_notes(df, rec, pos))
    summary = {
        "recognition": [{"excitation": r.excitation, "protocol": r.protocol, "classifier": r.classifier,
                         "accuracy_percent": r.accuracy} for r in rec],
        "grasp_position": [{"object": r.object_name, "excitation": r.excitation, "rmse_mm": r.rmse_mm} for r in pos],
    }
    atomic_write_text(out_dir / "results.json", json.dumps(summary, indent=2))
    return path
