"""Cost of the streaming microphone per env step, against the same env with sensing off.

    python benchmarks/streaming_env.py [--chunks 9] [--steps 20] [--no-write]
    python benchmarks/streaming_env.py --scenes moving --set sensors.modal.coupled_basis:SNAP_TO_NODES=1 --no-write

For objects of about 12, 46 and 100 modes below Nyquist (aluminium bar, ABS bar, PLA tube),
three envs are built with the same seed: ``acoustic={"cadence": "stream"}`` (passive sound on,
the streaming default), the same with ``"passive_sound": False`` and ``acoustic={"enabled":
False}``. Two scenes per object:

- ``held``: ``aas_gym/AcousticGrasp-v0``, the object grasped (scripted ``planar_grasp``) and
  held still; each step streams 0.05 s (2205 samples through 25 physics steps); timed after
  a 5 s hold, when drive and object are in their periodic steady state and the stream repeats
  a precomputed period;
- ``moving``: ``aas_gym/ContactFormation-v0``'s script (lift, carry, set down, press, slide)
  with a steel-bar plinth: contacts change all the time.

Each chunk of ``--steps`` env steps is timed on both envs in turn (interleaved, so load from
other processes hits both alike); reported are the medians over chunks: milliseconds per
step, the ratio streamed / off, and the real-time factor of the streamed env (0.05 s of
simulated time per step / its cost). Times are CPU times of this process (the machine is
shared). Goal (issue 12): streaming keeps at least 50x real time for objects of up to 50
modes. Sensing off against bare MuJoCo is ``benchmarks/env.py``'s physics table.

``--scenes``: only these scenes; ``--set module:NAME=0|1``: a module flag for the whole run (a
fast path against its reference: the same steps in two processes, one with ``=0``, run side by
side so that load from other processes hits both alike).

Writes ``docs/benchmarks/streaming_env.md`` (not with ``--scenes`` or ``--set``).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import aas_gym  # noqa: E402,F401  (registers the envs)
from aas_gym.grasp import planar_grasp  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OBJECTS = ("aluminium_bar", "abs_bar", "pla_tube")
_clock = time.process_time
HOLD = np.array([0, 0, 0, 0, -1, 0], np.float32)


def _held_env(obj: str, acoustic: dict):
    env = gym.make("aas_gym/AcousticGrasp-v0", objects=[obj], randomization=False, max_episode_steps=None,
                   acoustic=acoustic, disable_env_checker=True)
    env.reset(seed=0)
    u = env.unwrapped
    sc = u._scene
    assert planar_grasp(sc.model, sc.data, sc.bodies[0], 0.02, 40.0, hand=sc.hand).success
    sc.ctrl[sc.tcp_ctrl] = sc.hand.tcp(sc.data)
    if u._stream is not None:
        u._stream = u._new_stream()        # the grasp just closed
    return env, (lambda: env.step(HOLD))


def _moving_env(obj: str, acoustic: dict):
    env = gym.make("aas_gym/ContactFormation-v0", objects=[obj], plinths=["steel_bar"], max_episode_steps=None,
                   acoustic=acoustic, disable_env_checker=True)
    env.reset(seed=0)
    return env, (lambda: env.step(0))


def measure(make, obj: str, chunks: int, steps: int, warm: int) -> dict:
    on, step_on = make(obj, {"cadence": "stream"})
    quiet, step_quiet = make(obj, {"cadence": "stream", "passive_sound": False})
    off, step_off = make(obj, {"enabled": False})
    for _ in range(warm):           # systems, drive, imports; a held grasp reaches its steady state
        step_on(), step_quiet(), step_off()
    costs_on, costs_quiet, costs_off = [], [], []
    for _ in range(chunks):
        for step, costs in ((step_on, costs_on), (step_quiet, costs_quiet), (step_off, costs_off)):
            t0 = _clock()
            for _ in range(steps):
                step()
            costs.append((_clock() - t0) / steps)
    u = on.unwrapped
    stream = u._stream
    modes = int((stream.sensor.modal_model(stream.sensor.bodies[0]).frequencies_hz < 22050).sum())
    on_s, off_s = statistics.median(costs_on), statistics.median(costs_off)
    quiet_s = statistics.median(costs_quiet)
    out = {"object": obj, "modes": modes, "on_ms": on_s * 1e3, "off_ms": off_s * 1e3, "ratio": on_s / off_s,
           "quiet_ms": quiet_s * 1e3, "passive_ratio": on_s / quiet_s,
           "rtf": u.dt / on_s, "builds": stream.stream.systems.misses, "reads": stream.contact_reads,
           "steps": chunks * steps + warm, "warm": warm}
    on.close(), quiet.close(), off.close()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chunks", type=int, default=9)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--scenes", nargs="+", choices=("held", "moving"), default=("held", "moving"))
    ap.add_argument("--set", action="append", default=[], metavar="MODULE:NAME=0|1")
    args = ap.parse_args(argv)
    for item in args.set:
        target, value = item.split("=")
        module, name = target.split(":")
        setattr(importlib.import_module(module), name, bool(int(value)))
        print(f"{module}.{name} = {bool(int(value))}")
    rows = []
    for scene, make, warm in (("held", _held_env, 100), ("moving", _moving_env, 3)):
        if scene not in args.scenes:
            continue
        for obj in OBJECTS:
            r = measure(make, obj, args.chunks, args.steps, warm)
            r["scene"] = scene
            rows.append(r)
            print(f"{scene:6s} {obj:14s} {r['modes']:4d} modes  streamed {r['on_ms']:7.2f} ms  "
                  f"(passive off {r['quiet_ms']:7.2f} ms)  off {r['off_ms']:6.2f} ms"
                  f"  ratio {r['ratio']:6.1f}  {r['rtf']:6.1f}x real time  builds {r['builds']}, reads {r['reads']}"
                  f" in {r['steps']} steps", flush=True)
    lines = ["# Streaming microphone: cost per env step", "",
             f"`python benchmarks/streaming_env.py --chunks {args.chunks} --steps {args.steps}` on "
             f"{platform.node() or 'this machine'} ({os.cpu_count()} CPUs, shared), Python {platform.python_version()}, "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. See the script's docstring for the scenes.",
             "Medians over interleaved chunks after the warm-up steps, CPU time of the process; real-time factor "
             "= 0.05 s / streamed cost. Steps: warm-up + timed.", "",
             "| scene | object | modes < Nyquist | streamed [ms/step] | streamed, passive sound off [ms/step] | "
             "passive on / off | sensing off [ms/step] | streamed / off | real-time factor | goal | system builds | "
             "contact reads | steps |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|"]
    for r in rows:
        goal = ">= 50x" if r["modes"] <= 50 else ""
        lines.append(f"| {r['scene']} | {r['object']} | {r['modes']} | {r['on_ms']:.2f} | {r['quiet_ms']:.2f} | "
                     f"{r['passive_ratio']:.2f} | {r['off_ms']:.2f} | "
                     f"{r['ratio']:.1f} | {r['rtf']:.2g}x | {goal} | {r['builds']} | {r['reads']} | {r['steps']} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write and not args.set and len(args.scenes) == 2:
        out = ROOT / "docs" / "benchmarks" / "streaming_env.md"
        out.write_text(text)
        print(f"wrote {out}")
    return rows


if __name__ == "__main__":
    main()
