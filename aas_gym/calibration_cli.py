"""``aas calibrate``: fit a material (E, alpha, beta, gamma) to recordings of a grasped object.

    aas calibrate rec1.npz rec2.npz --material abs --shape bar --dims 0.2 0.02 0.01 --out abs.json

Recordings are ``sensors.AcousticObservation`` files (the rig's or the simulator's). Their
contacts come from the recording metadata when present (the simulator writes them); for rig
recordings give the grasp: ``--grasp-x`` (position along the main axis) and ``--grip-force``
(one value, or one per recording), an antipodal grasp along ``--grasp-axis`` (default z,
the height: actuator on the + face, microphone on the - face). The written file loads back
with ``sensors.calibration.load_material``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

SHAPE_DIMS = {
    "bar": ("length_m", "width_m", "height_m"),
    "tube": ("length_m", "outer_radius_m", "inner_radius_m"),
    "rod": ("length_m", "radius_m"),
}


def _base_material(spec: str):
    from sensors.calibration import load_material
    from sensors.materials.solids import get_material

    if Path(spec).suffix == ".json" or Path(spec).is_file():
        return load_material(spec)
    return get_material(spec)


def build_model(args, material):
    """The model ``aas calibrate`` fits: the one saved at ``--model``, else ``--shape`` with
    ``--dims`` in ``material``."""
    import sensors

    if args.model:
        return sensors.ModalModel.load(args.model)
    dims = args.dims
    names = SHAPE_DIMS[args.shape]
    if dims is None or len(dims) != len(names):
        raise SystemExit(f"aas calibrate: --shape {args.shape} needs --dims {' '.join(n.upper() for n in names)}")
    options = {}
    if args.max_frequency_hz is not None:
        options["max_frequency_hz"] = args.max_frequency_hz
    if args.element_size_m is not None:
        options["element_size_m"] = args.element_size_m
    return getattr(sensors.ModalModel, args.shape)(*dims, material, **options)


def _grasp_contacts(args, force_n: float):
    from sensors import Contact

    axis = 1 if args.grasp_axis == "y" else 2
    if args.shape == "bar":
        half = args.dims[axis] / 2
    elif args.shape in ("tube", "rod"):
        half = args.dims[1]
    else:
        raise SystemExit("aas calibrate: --grasp-x needs --shape and --dims")
    point, normal = np.zeros(3), np.zeros(3)
    point[0], point[axis], normal[axis] = args.grasp_x, half, 1.0
    return (Contact(point, normal, force_n, args.friction), Contact(point * [1, -1, -1], -normal, force_n, args.friction))


def _setups(args):
    from sensors import AcousticObservation
    from sensors.calibration import RecordingSetup

    forces = args.grip_force or []
    if forces and len(forces) not in (1, len(args.recordings)):
        raise SystemExit(f"aas calibrate: give one --grip-force or one per recording ({len(args.recordings)})")
    setups = []
    for k, path in enumerate(args.recordings):
        obs = AcousticObservation.load(path)
        has_meta = bool((obs.metadata or {}).get("contacts", {}).get("actuator"))
        if args.grasp_x is not None and forces:
            actuator, mic = _grasp_contacts(args, forces[k if len(forces) > 1 else 0])
            setups.append(RecordingSetup(obs, actuator, mic))
        elif has_meta:
            setups.append(RecordingSetup.from_observation(obs))
        else:
            raise SystemExit(f"aas calibrate: {path} has no contacts in its metadata; give --grasp-x and --grip-force")
    return setups


def _fmt(value: float, std: float) -> str:
    rel = f" ({100 * std / abs(value):.1f} %)" if value else ""
    return f"{value:.4g} +- {std:.2g}{rel}"


def run_calibrate(args: argparse.Namespace) -> int:
    """Entry point of ``aas calibrate``."""
    from sensors.calibration import calibrate, save_material

    base = _base_material(args.material)
    model = build_model(args, base)
    setups = _setups(args)
    fit_gamma = {"auto": "auto", "yes": True, "no": False}[args.fit_gamma]
    kwargs = {}
    if args.f_min is not None:
        kwargs["f_min_hz"] = args.f_min
    if args.f_max is not None:
        kwargs["f_max_hz"] = args.f_max
    try:
        result = calibrate(model, setups, base, fit_youngs_modulus=not args.fixed_e, fit_gamma=fit_gamma,
                           factor_range=(args.e_range[0], args.e_range[1]), name=args.name,
                           leak=args.leak or None, contact_model=args.contact_model, **kwargs)
    except ValueError as exc:  # too few modes found or matched: say so, no traceback
        print(f"aas calibrate: {exc}", file=sys.stderr)
        return 1
    report = result.report()
    report["recordings"] = [str(p) for p in args.recordings]
    path = save_material(args.out, result.material, calibration=report)
    m, d = result.material, result.damping
    std = d.std
    print(f"calibrated {base.name} from {len(setups)} recording(s); modes found: {report['modes_found_per_recording']}")
    if result.stiffness is not None:
        s = result.stiffness
        print(f"  E      {_fmt(m.youngs_modulus_pa, report['youngs_modulus_pa']['std'])} Pa "
              f"(x{s.youngs_modulus_factor:.4f} of {base.youngs_modulus_pa:.4g}; {s.n_matched} modes matched, "
              f"rms misfit {100 * s.rms_log_misfit:.2f} %)")
    print(f"  alpha  {_fmt(m.alpha, std[0])} 1/s   (table {base.alpha:g})")
    print(f"  beta   {_fmt(m.beta, std[1])} s     (table {base.beta:g})")
    print(f"  gamma  {_fmt(m.gamma, std[2])} s/m   (table {base.gamma:g}{'' if d.gamma_fitted else '; held, not fitted'})")
    print(f"  contact model: {result.contact_model}")
    print(f"  damping fit: {d.n_modes} modes, {d.n_rejected} rejected, reduced chi2 {d.chi2_reduced:.2f}")
    bands = [b for e in result.estimates for b in e.bands]
    bad = [b for b in bands if not b.fit_ok]
    if bad:
        # leak, fingertip and nonlinearity leave non-modal residue; many such bands mean
        # the modal estimates (and so the fit) deserve a look
        print(f"  note: {len(bad)} of {len(bands)} sub-band fits left more residual than the noise explains "
              f"(e.g. {bad[0].f_lo_hz:.0f}-{bad[0].f_hi_hz:.0f} Hz)")
    print(f"wrote {path}")
    if args.json:
        print(json.dumps(report, indent=2, default=lambda o: o.tolist() if isinstance(o, np.ndarray) else float(o)))
    return 0


def add_subcommands(sub) -> None:
    """Register ``aas calibrate``."""
    p = sub.add_parser("calibrate", help="fit a material (E, alpha, beta, gamma) to recordings; write a material file",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recordings", nargs="+", help="AcousticObservation .npz files")
    p.add_argument("--material", required=True, help="base material: table name (abs, steel, ...) or material .json")
    p.add_argument("--shape", choices=sorted(SHAPE_DIMS), help="object shape (with --dims)")
    p.add_argument("--dims", type=float, nargs="+", metavar="M",
                   help="bar: L W H; tube: L R_OUT R_IN; rod: L R (metres)")
    p.add_argument("--model", help="a saved sensors.ModalModel instead of --shape/--dims")
    p.add_argument("--max-frequency-hz", type=float,
                   help="FEM band limit (default: ModalModel's); modes a little above the analysed band suffice")
    p.add_argument("--element-size-m", type=float, help="FEM element size (default: ModalModel's)")
    p.add_argument("--out", required=True, help="material file to write (.json)")
    p.add_argument("--name", help="name of the calibrated material (default <base>-calibrated)")
    p.add_argument("--grasp-x", type=float, help="grasp position along the main axis [m] (recordings without contacts)")
    p.add_argument("--grip-force", type=float, nargs="+", metavar="N", help="grip force(s) [N], one or one per recording")
    p.add_argument("--grasp-axis", choices=("y", "z"), default="z",
                   help="the grasp presses along this axis: actuator on +axis, microphone on -axis (default z)")
    p.add_argument("--friction", type=float, default=0.5, help="friction coefficient of the grasp contacts (default 0.5)")
    p.add_argument("--leak", nargs="+", metavar="NPZ",
                   help="idle leak recording(s) of the rig (sensors.signals.leak format), one per excitation: removed first")
    p.add_argument("--fit-gamma", choices=("auto", "yes", "no"), default="auto",
                   help="fit gamma (auto: when grip forces / contact sets differ between recordings)")
    p.add_argument("--contact-model", choices=("spring_damper", "damping"),
                   help="contact model of the simulation being calibrated (default: the recordings' metadata, "
                        "else spring_damper: the fingertip pads are springs)")
    p.add_argument("--fixed-e", action="store_true", help="keep the base Young's modulus")
    p.add_argument("--e-range", type=float, nargs=2, default=(1 / 3, 3.0), metavar=("LO", "HI"),
                   help="search range of E / E_base (default 0.333 3)")
    p.add_argument("--f-min", type=float, help="lowest frequency analysed [Hz] (default 100)")
    p.add_argument("--f-max", type=float, help="highest frequency analysed [Hz] (default: the excitation's band)")
    p.add_argument("--json", action="store_true", help="also print the full report as JSON")
    p.set_defaults(func=run_calibrate)


if __name__ == "__main__":  # pragma: no cover
    parser = argparse.ArgumentParser(prog="aas")
    add_subcommands(parser.add_subparsers(dest="command"))
    a = parser.parse_args()
    sys.exit(a.func(a))
