"""What a stream's ContactTolerance or fast path costs and changes in the sound, on one trajectory.

    python benchmarks/stream_tolerance.py [--scene contact_formation] [--steps 150] [--warm-steps 20]
        --tolerance position_m=1e-3 [--system-tolerance force_rtol=0.2] [--passive-off]
    python benchmarks/stream_tolerance.py --flag sensors.modal.static_correction:KEEP_NODE_ROWS

``--flag module:NAME``: A runs with that module flag False (the reference), B with it True (the
fast path); it is set before each stream's calls.

Two streaming microphones follow the SAME physics (the sound does not act on MuJoCo): A, the
env's own stream with its tolerance (ContactFormation-v0's ``MOVING_TOLERANCE``), and B, a
second ``SimAcousticStream`` on the same sensor whose tolerance has the fields given in
``--tolerance`` replaced (when to read the contacts and which systems match), or only its
system cache's (``--system-tolerance``: the contacts are read as often as A reads them, so
passive sound hears the same reads). Both noise-free. Per env step, A and B take turns going
first (caches shared through the sensor and the modal model charge the first), and each
stream's CPU time is its ``grasp_state`` calls plus its ``advance``.  Those times are only a
hint: a variant that uses the shared caches (the models' unit-load store, the spring-mode
cache) differently also changes what the other stream pays (an update of the springs on an
earlier build's basis, tried and dropped, read 1.3x here and 1.03x in two processes over the same steps).  Time in separate processes for speed; this tool
is for the sound.

Reported: contact reads and system builds of each, their CPU ms per step, and how far B's sound
is from A's: the rms of the difference of their samples relative to A's rms, and the 140
features (dB) of every loop period that both heard throughout (median, 95th percentile and
largest absolute difference). Scenes as ``benchmarks/stream_profile.py``'s.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import importlib  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import aas_gym  # noqa: E402,F401  (registers the envs)
from aas_gym.sim_stream import SimAcousticStream, span_bounds  # noqa: E402
from sensors import ContactTolerance  # noqa: E402

_clock = time.process_time


def replaced(tolerance: ContactTolerance, fields: str | None) -> ContactTolerance:
    """``tolerance`` with ``"name=value,..."`` replaced (None: itself)."""
    if not fields:
        return tolerance
    return dataclasses.replace(tolerance, **{k.strip(): float(v) for k, v in
                                             (kv.split("=") for kv in fields.split(","))})


class TwinStream:
    """Stands in for the env's stream A: each physics step feeds A and B, and returns A's samples."""

    def __init__(self, a: SimAcousticStream, b: SimAcousticStream, log: "TwinLog", flag=None) -> None:
        self.a, self.b, self.log, self.flag = a, b, log, flag

    def _set(self, key: str) -> None:
        if self.flag is not None:
            setattr(self.flag[0], self.flag[1], key == "B")

    def __getattr__(self, name):
        return getattr(self.a, name)

    def step_physics(self, n_steps: int, n_samples: int) -> np.ndarray:
        m, d = self.a.model, self.a.data
        bounds = span_bounds(n_samples, n_steps)
        spans = {"A": [], "B": []}
        order = (("A", self.a), ("B", self.b)) if self.log.steps % 2 == 0 else (("B", self.b), ("A", self.a))
        for k in range(int(n_steps)):
            mujoco.mj_step(m, d)
            n = int(bounds[k + 1] - bounds[k])
            for key, s in order:
                self._set(key)
                t = _clock()
                spans[key].append((n, s.grasp_state()))
                self.log.cpu_s[key] += _clock() - t
        out = {}
        for key, s in order:
            self._set(key)
            t = _clock()
            out[key] = s.stream.advance(spans[key])
            self.log.cpu_s[key] += _clock() - t
        self._set("A")
        self.log.record(self.a, self.b, out["A"], out["B"])
        return out["A"]


@dataclasses.dataclass
class TwinLog:
    cpu_s: dict = dataclasses.field(default_factory=lambda: {"A": 0.0, "B": 0.0})
    audio: dict = dataclasses.field(default_factory=lambda: {"A": [], "B": []})
    features: list = dataclasses.field(default_factory=list)   # (A, B) of periods both heard throughout
    streams: list = dataclasses.field(default_factory=list)
    steps: int = 0

    def record(self, a: SimAcousticStream, b: SimAcousticStream, ya: np.ndarray, yb: np.ndarray) -> None:
        self.steps += 1
        self.audio["A"].append(ya)
        self.audio["B"].append(yb)
        sa, sb = a.stream, b.stream
        period = sa.latest_features_period
        if period >= 0 and period != getattr(self, "_period", -1):
            self._period = period
            if sa.latest_features_heard == 1.0 and sb.latest_features_heard == 1.0:
                self.features.append((sa.latest_features(), sb.latest_features()))

    def totals(self) -> dict:
        return {"reads": {k: sum(getattr(p[i], "contact_reads") for p in self.streams) for i, k in enumerate("AB")},
                "builds": {k: sum(p[i].stream.systems.misses for p in self.streams) for i, k in enumerate("AB")}}

    def differences(self) -> dict:
        ya = np.concatenate(self.audio["A"]).astype(float)
        yb = np.concatenate(self.audio["B"]).astype(float)
        out = {"bitwise_equal": bool(np.array_equal(ya, yb)),
               "rms_rel": float(np.sqrt(np.mean((ya - yb) ** 2) / max(np.mean(ya ** 2), 1e-300))),
               "periods": len(self.features)}
        if self.features:
            db = np.array([np.abs(20 * np.log10(np.maximum(fa, 1e-30)) - 20 * np.log10(np.maximum(fb, 1e-30)))
                           for fa, fb in self.features])
            out.update(db_median=float(np.median(db)), db_p95=float(np.quantile(db, 0.95)), db_max=float(db.max()))
        return out


def run(scene: str = "contact_formation", steps: int = 150, warm_steps: int = 20, tolerance: str | None = None,
        system_tolerance: str | None = None, passive: bool = True, obj: str = "abs_bar",
        flag: str | None = None) -> TwinLog:
    """A and B over ``steps`` env steps (CPU times counted after ``warm_steps``)."""
    acoustic = {"noise_std": 0.0, "passive_sound": passive}
    if scene == "contact_formation":
        env = gym.make("aas_gym/ContactFormation-v0", disable_env_checker=True, acoustic=acoustic)
    else:
        env = gym.make("aas_gym/ContactFormation-v0", objects=[obj], plinths=["steel_bar"], max_episode_steps=None,
                       acoustic=dict(acoustic, cadence="stream"), disable_env_checker=True)
    u = env.unwrapped
    log = TwinLog()
    if flag:
        module, name = flag.split(":")
        flag = (importlib.import_module(module), name)
        setattr(flag[0], name, False)

    def twin():
        a = u._stream
        b = SimAcousticStream(u.sensor, a.stream.excitation, variation=u._variation, rng=0,
                              tolerance=replaced(a.tolerance, tolerance), passive=u.acoustic.passive)
        if system_tolerance:
            b.stream.systems.tolerance = replaced(a.tolerance, system_tolerance)
        log.streams.append((a, b))
        u._stream = TwinStream(a, b, log, flag)

    env.reset(seed=0)
    env.action_space.seed(0)
    twin()
    for i in range(steps):
        if i == warm_steps:
            log.cpu_s = {"A": 0.0, "B": 0.0}
        action = env.action_space.sample() if scene == "contact_formation" else 0
        if any(env.step(action)[2:4]):
            env.reset()
            twin()
    env.close()
    if flag:
        setattr(flag[0], flag[1], True)
    log.timed_steps = steps - warm_steps
    return log


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=("contact_formation", "moving"), default="contact_formation")
    ap.add_argument("--object", default="abs_bar")
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--warm-steps", type=int, default=20)
    ap.add_argument("--tolerance", default=None, help="B's tolerance fields, e.g. position_m=1e-3")
    ap.add_argument("--system-tolerance", default=None, help="B's system cache tolerance fields only")
    ap.add_argument("--passive-off", action="store_true")
    ap.add_argument("--flag", default=None, help="module:NAME, False on A and True on B")
    args = ap.parse_args(argv)
    log = run(args.scene, args.steps, args.warm_steps, args.tolerance, args.system_tolerance,
              not args.passive_off, args.object, args.flag)
    tot, diff = log.totals(), log.differences()
    n = log.timed_steps
    print(f"{args.scene} {args.steps} steps, B: tolerance {args.tolerance or '='}, system tolerance "
          f"{args.system_tolerance or '='}, flag {args.flag or '-'} (A off, B on), passive sound {'off' if args.passive_off else 'on'}")
    print(f"  reads A {tot['reads']['A']} B {tot['reads']['B']}; builds A {tot['builds']['A']} B {tot['builds']['B']}; "
          f"CPU A {1e3 * log.cpu_s['A'] / n:.2f} B {1e3 * log.cpu_s['B'] / n:.2f} ms/step (after {args.warm_steps})")
    line = f"  sound: rms(A - B) / rms(A) {diff['rms_rel']:.3g}, bitwise equal {diff['bitwise_equal']}"
    if diff["periods"]:
        line += (f"; features of {diff['periods']} periods heard throughout: |dB| median {diff['db_median']:.3g}, "
                 f"p95 {diff['db_p95']:.3g}, max {diff['db_max']:.3g}")
    print(line)
    return log


if __name__ == "__main__":
    main()
