"""Rig commands for the ``aas`` command line (hooked in by ``aas_gym.cli``).

- ``aas audio-devices``: list PortAudio devices.
- ``aas record --excitation linear --seconds 5 -o take.npz``: play and record, save atomically.
- ``aas record-leak -o leaks/``: the gripper-idle leak for each excitation (simulator format).
- ``aas audio-loopback start|stop|status``: the PulseAudio null-sink loopback (no hardware).

``python -m real.cli ...`` runs the same commands without the ``aas`` entry point.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
from pathlib import Path


def _device(value: str | None):
    """A device argument: an integer is an index, anything else a name (substring)."""
    if value is None:
        return None
    return int(value) if value.lstrip("-").isdigit() else value


def _rig_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--input", default=None, help="input device: index or name substring (default: system default)")
    p.add_argument("--output", default=None, help="output device: index or name substring (default: system default)")
    p.add_argument("--sample-rate-hz", type=int, default=44100, help="sample rate, Hz (default %(default)s)")
    p.add_argument("--mic-channel", type=int, default=0, help="input channel of the contact microphone")
    p.add_argument("--actuator-channel", type=int, default=0, help="output channel of the actuator")
    p.add_argument("--gain", type=float, default=1.0, help="output gain in (0, 1] (default %(default)s)")
    p.add_argument("--stream-mode", choices=["separate", "duplex"], default="separate")
    p.add_argument("--xruns", choices=["raise", "warn", "ignore"], default="raise",
                   help="what overflows/underruns and lost sync do (default %(default)s)")
    p.add_argument("--retries", type=int, default=2, help="re-record on xruns this many times")


def _make_sensor(args, save_dir=None):
    from .rig import PyAudioRig
    from .sensor import RealAcousticSensor

    rig = PyAudioRig(_device(args.input), _device(args.output), args.sample_rate_hz, actuator_channel=args.actuator_channel,
                     mic_channel=args.mic_channel, output_gain=args.gain, stream_mode=args.stream_mode,
                     xrun_policy=args.xruns)
    return RealAcousticSensor(rig, retries=args.retries, save_dir=save_dir)


def _excitation(args):
    from sensors import Excitation

    return Excitation.by_name(args.excitation, sample_rate_hz=args.sample_rate_hz)


def cmd_devices(args) -> int:
    """``aas audio-devices``."""
    from .rig import RigError, list_devices

    try:
        devices = list_devices()
    except RigError as exc:
        print(f"aas: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps([d.to_dict() for d in devices], indent=2))
        return 0
    if not devices:
        print("no audio devices (without hardware: aas audio-loopback start)")
        return 1
    for d in devices:
        default = ("  [default in]" if d.is_default_input else "") + ("  [default out]" if d.is_default_output else "")
        print(f"{d.index:3d}  {d.name:<32s} {d.host_api:<6s} in {d.max_input_channels:2d}  "
              f"out {d.max_output_channels:2d}  {d.default_sample_rate_hz:g} Hz{default}")
    return 0


def _labels(pairs: list[str]) -> dict[str, str]:
    out = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep:
            raise SystemExit(f"aas: --label wants KEY=VALUE, got {pair!r}")
        out[key] = value
    return out


def cmd_record(args) -> int:
    """``aas record``: one recording, saved atomically (partial file if interrupted)."""
    from .rig import RigError

    out = Path(args.output_file or f"recording_{_dt.datetime.now(_dt.timezone.utc):%Y%m%dT%H%M%SZ}_{args.excitation}.npz")
    if out.suffix != ".npz":
        out = out.with_suffix(".npz")
    try:
        sensor = _make_sensor(args)
        rec = sensor.record(_excitation(args), args.seconds, save_path=out, labels=_labels(args.label))
    except RigError as exc:
        print(f"aas record: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"aas record: interrupted; what was recorded is in {out.with_suffix('')}.partial.npz", file=sys.stderr)
        return 130
    path = rec.save(out, trim=not args.keep_preroll, labels=_labels(args.label), extra_metadata={"kind": "recording"})
    print(f"{path}: {rec.duration_s:.2f} s at {rec.sample_rate_hz} Hz, first period at {rec.latency_s * 1e3:.1f} ms into the recording, "
          f"input {rec.input_device.name!r}, output {rec.output_device.name!r}, "
          f"xruns {sum(v for k, v in rec.flag_counts().items() if k != 'priming_output')}, "
          f"drift {rec.drift_samples} samples")
    return 0


def cmd_record_leak(args) -> int:
    """``aas record-leak``: the leak for each excitation, gripper idle."""
    from .rig import RigError
    from .sensor import record_leaks

    try:
        sensor = _make_sensor(args)
        from sensors import Excitation

        paths = record_leaks(sensor, args.output_dir, [Excitation.by_name(n, sample_rate_hz=args.sample_rate_hz) for n in args.excitations],
                             args.seconds)
    except RigError as exc:
        print(f"aas record-leak: {exc}", file=sys.stderr)
        return 1
    for name, path in paths.items():
        print(f"{name}: {path}")
    return 0


def cmd_loopback(args) -> int:
    """``aas audio-loopback``."""
    from . import loopback

    argv = [args.action, "--sink", args.sink]
    return loopback.main(argv)


def add_subcommands(subparsers) -> None:
    """Register the rig commands on an ``argparse`` sub-parser collection."""
    p = subparsers.add_parser("audio-devices", help="list audio devices (PortAudio)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_devices)

    p = subparsers.add_parser("record", help="play an excitation and record the contact microphone")
    _rig_arguments(p)
    p.add_argument("--excitation", "-e", default="linear", help="impulse, linear or exponential (default %(default)s)")
    p.add_argument("--seconds", "-s", type=float, default=1.0, help="aligned recording length (default %(default)s)")
    p.add_argument("--output-file", "-o", default=None, help="output .npz (default recording_<time>_<excitation>.npz)")
    p.add_argument("--label", action="append", metavar="KEY=VALUE", help="metadata label (repeatable)")
    p.add_argument("--keep-preroll", action="store_true",
                   help="keep the samples before the first period (start_time_s = latency)")
    p.set_defaults(func=cmd_record)

    p = subparsers.add_parser("record-leak", help="record the actuator-to-microphone leak, gripper idle")
    _rig_arguments(p)
    p.add_argument("--output-dir", "-o", default="leaks", help="folder for leak_<excitation>.npz (default %(default)s)")
    p.add_argument("--excitations", nargs="+", default=["impulse", "linear", "exponential"])
    p.add_argument("--seconds", "-s", type=float, default=2.0, help="recording length (default %(default)s)")
    p.set_defaults(func=cmd_record_leak)

    p = subparsers.add_parser("audio-loopback", help="PulseAudio null-sink loopback for tests without hardware")
    p.add_argument("action", choices=["start", "stop", "status"])
    p.add_argument("--sink", default="aas_loop")
    p.set_defaults(func=cmd_loopback)


def main(argv: list[str] | None = None) -> int:
    """``python -m real.cli``."""
    parser = argparse.ArgumentParser(prog="python -m real.cli", description=__doc__.split("\n\n")[0])
    add_subcommands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
