"""What a contact does to the sound: one grasp of the aluminium bar, free, on the table, on another bar.

The same grasp (both fingertips 30 mm from the bar's centre, 40 N) held in the air, with the
bar's end pressed on the table (5 N) near its end or nearer the grasp, and with the same end
resting on a steel bar that lies crosswise on the table (the two bars vibrate together,
``sensors.modal.TouchingObjects``; a wooden bar, heavily damped, sounds almost like the table).  Features (dB) of the linear chirp, no noise.

    python examples/contact_spectra.py        # writes docs/images/contact_spectra.png

Also imported by ``examples/contact_position.py`` (:func:`grasp_features`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensors import Contact, Excitation, feature_frequencies_hz
from sensors.modal import TouchingObjects, TouchingPartner
from sensors.objects.catalog import get_object
from sensors.synthesis import simulate_features

OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "contact_spectra.png"
GRASP_X_M = 0.03          # fingertips along the bar [m]
GRIP_N = 40.0
TABLE_FORCE_N = 5.0


def bar_and_grasp(name: str = "aluminium_bar"):
    """The object's spec and modal model and its two fingertip contacts (on the +-y faces)."""
    spec = get_object(name)
    w = spec.width_m / 2
    act = Contact([GRASP_X_M, w, 0.0], [0.0, 1.0, 0.0], GRIP_N, 0.5)
    mic = Contact([GRASP_X_M, -w, 0.0], [0.0, -1.0, 0.0], GRIP_N, 0.5)
    return spec, spec.modal_model(), act, mic


def table_contact(spec, x_m: float, force_n: float = TABLE_FORCE_N) -> Contact:
    """The bar's bottom face on the (wooden) table at ``x_m`` along it."""
    return Contact([x_m, 0.0, -spec.height_m / 2], [0.0, 0.0, -1.0], force_n, 0.5)


def plinth_group(spec, model, x_m: float, plinth: str = "wood_bar", force_n: float = TABLE_FORCE_N):
    """The bar resting at ``x_m`` on ``plinth`` (crosswise, below it), the plinth on the table
    at both its ends: a ``TouchingObjects``."""
    pspec = get_object(plinth)
    pmodel = pspec.modal_model()
    # plinth frame: its axis along the bar's y, its top face touching the bar's bottom at x_m
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = np.array([x_m, 0.0, -spec.height_m / 2 - pspec.height_m / 2])
    link = Contact([x_m, 0.0, -spec.height_m / 2], [0.0, 0.0, -1.0], force_n, 0.5, counter_material=pspec.material)
    feet = [Contact([s * 0.45 * pspec.length_m, 0.0, -pspec.height_m / 2], [0.0, 0.0, -1.0],
                    force_n / 2 + 9.81 * pmodel.mass_kg / 2, 0.5) for s in (-1, 1)]
    return TouchingObjects(model, [TouchingPartner(pmodel, R, t, (link,), tuple(feet))])


def grasp_features(model, act, mic, others=(), excitation=None, noise_std=0.0, rng=None) -> np.ndarray:
    """The 140 features [dB] of one 1 s recording."""
    ex = Excitation.by_name("linear") if excitation is None else excitation
    obs = simulate_features(model, ex, 1.0, act, mic, list(others), noise_std=noise_std, rng=rng)
    return 20 * np.log10(np.maximum(obs.features(), 1e-12))


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec, model, act, mic = bar_and_grasp()
    end = -0.45 * spec.length_m
    cases = {
        "free (held in the air)": (model, ()),
        f"on the table at {end * 1e3:.0f} mm": (model, (table_contact(spec, end),)),
        "on the table at -30 mm": (model, (table_contact(spec, -0.03),)),
        f"on a steel bar at {end * 1e3:.0f} mm": (plinth_group(spec, model, end, "steel_bar"), ()),
    }
    f = feature_frequencies_hz()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    free = None
    for label, (m, others) in cases.items():
        db = grasp_features(m, act, mic, others)
        free = db if free is None else free
        top.plot(f, db, lw=1.2, label=label)
        bottom.plot(f, db - free, lw=1.2, label=label)
        print(f"{label:32s} mean |change| {np.mean(np.abs(db - free)):.2f} dB, max {np.max(np.abs(db - free)):.2f} dB")
    top.set(ylabel="feature [dB]", title=f"{spec.name or 'aluminium_bar'}: one grasp at {GRASP_X_M * 1e3:.0f} mm, "
            f"{GRIP_N:.0f} N, linear chirp")
    top.legend(fontsize=8)
    bottom.set(xlabel="frequency [Hz]", ylabel="change against free [dB]")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=120)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
