"""Where a streamed env step's time goes: CPU time per part of the stream, and the events behind it.

    python benchmarks/stream_profile.py [--scene contact_formation] [--steps 300] [--warm-s 15]
    python benchmarks/stream_profile.py --warm-s 0 --warm-steps 150   (the same steps in every process)
    python benchmarks/stream_profile.py --scene moving --object abs_bar [--steps 40] [--warm-steps 3]
    python benchmarks/stream_profile.py --ab sensors.modal.static_correction:KEEP_NODE_ROWS [--chunks 20] [--chunk-steps 10]

Scenes: ``contact_formation`` is ``aas_gym/ContactFormation-v0`` with its defaults (streamed,
passive sound on, ``MOVING_TOLERANCE``), random actions, resets included, timed after
``--warm-s`` CPU seconds; ``moving`` is ``benchmarks/streaming_env.py``'s moving scene of one
object (ContactFormation-v0's script on a steel-bar plinth, action 0), timed after
``--warm-steps`` env steps.

Each part is timed exclusively (a part called inside another is charged to itself only), by
wrapping the functions below for the run; ``other`` is the env step's time outside them (the
env's and the stream's Python, the contact list's bookkeeping). Parts: ``build:*`` the system
builds (``ModalSystem.build``: ``attachment`` the static-correction basis at the contact
points, ``spring modes`` / ``coupled bodies`` the rest of the modes with contact springs,
``eigen`` the complex modes, ``damping``, ``surface check``, ``build`` its own code); ``read``
the contact reads (``SimAcousticStream.read_state``: the MuJoCo contact list to a
``GraspState``); ``signature`` the per-physics-step check whether the contacts changed;
``lookup`` the system cache's tolerance match; ``passive:*`` passive sound (``project`` the
loads' mode shapes at their points, ``change`` a read's modal load, ``solve`` the load's
particular solutions); ``transfer`` the state hand-over between contact sets; ``synthesis`` the
samples (``DiscreteSystem.response`` / ``final_state`` / ``free_state``); ``features``;
``physics`` (``mj_step``). Counts per env step: signature changes by cause (a partner starts or
stops pressing, a net force, a force-weighted point beyond the tolerance), reads, system
lookups, builds and cache hits.

``--ab module:NAME``: a fast path against its reference in one process. Two envs of the scene
with the same seed and actions follow the same physics (the sound does not act on MuJoCo); the
flag is False while the first steps and True while the second does, chunk by chunk (their
order alternating, so that load from other processes hits both alike). Reported: each env's
mean ms per step over the chunks (the throughput: builds come in bursts, so a median chunk is
a quiet one; the medians are printed beside) and their ratio. The two envs share the modal
models' caches (unit-load store, spring modes), so a fast path that changes how they are used
also changes what the other env pays: for such a flag, compare the plain profile of two processes
over the same steps instead. Also reported: the largest difference of their
observed features (``acoustic``, dB) over all steps.

Times are CPU times of this process (``time.process_time``; the machine is shared). Prints a
table; writes nothing.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import importlib  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402

import aas_gym  # noqa: E402,F401  (registers the envs)
from _exclusive import ExclusiveTimes  # noqa: E402  (benchmarks/, the script's folder)

_clock = time.process_time

#: (module, class or None, function, part): what is timed.
PARTS = (
    ("sensors.synthesis.modal_system", "ModalSystem", "build", "build:build"),
    ("sensors.modal.static_correction", "ContactFlexibility", "attachment_basis", "build:attachment"),
    ("sensors.modal.spring_modes", "SpringModes", "__init__", "build:spring modes"),
    ("sensors.modal.coupled_bodies", "CoupledBodies", "__init__", "build:coupled bodies"),
    ("sensors.synthesis.modal_system", None, "_build_parts", "build:eigen"),
    ("sensors.synthesis.modal_system", None, "modal_damping_parts", "build:damping"),
    ("sensors.synthesis.modal_system", None, "check_groups_on_surface", "build:surface check"),
    ("aas_gym.sim_stream", "SimAcousticStream", "read_state", "read"),
    ("aas_gym.sim_stream", "SimAcousticStream", "grasp_state", "signature"),
    ("sensors.synthesis.caches", "SystemCache", "get_or_build", "lookup"),
    ("sensors.synthesis.stream", None, "project_reads", "passive:project"),
    ("sensors.synthesis.stream", "AcousticStream", "_modal_change", "passive:change"),
    ("sensors.synthesis.stream", "AcousticStream", "_load", "passive:change"),
    ("sensors.synthesis.passive", "LoadSolver", "__init__", "passive:solve"),
    ("sensors.synthesis.passive", "LoadSolver", "particular", "passive:solve"),
    ("sensors.synthesis.stream", None, "transfer_state", "transfer"),
    ("sensors.synthesis.stream", "_ObjectState", "state_in", "transfer"),
    ("sensors.synthesis.lti", "DiscreteSystem", "response", "synthesis"),
    ("sensors.synthesis.lti", "DiscreteSystem", "final_state", "synthesis"),
    ("sensors.synthesis.lti", "DiscreteSystem", "free_state", "synthesis"),
    ("sensors.synthesis.stream", None, "SteadyState", "synthesis"),
    ("sensors.synthesis.drive", "FingertipDrive", "forces", "synthesis"),
    ("sensors.synthesis.microphone", "Microphone", "record", "microphone"),
    ("sensors.synthesis.stream", None, "spectral_features", "features"),
    ("aas_gym.sim_stream", "mujoco", "mj_step", "physics"),
)


class StreamProfile(ExclusiveTimes):
    """Exclusive CPU time and calls per part while active (a context manager; every wrapped
    function is restored on exit), and the stream's events."""

    def __init__(self) -> None:
        super().__init__(PARTS, clock=_clock)
        self.events = collections.Counter()

    def __enter__(self) -> "StreamProfile":
        super().__enter__()
        self._count_events()
        return self

    def _count_events(self) -> None:
        from aas_gym.sim_stream import SimAcousticStream
        from sensors.synthesis.caches import SystemCache

        events = self.events
        changed, timed_lookup = SimAcousticStream.signature_changed, SystemCache.get_or_build   # lookup: timed

        def counted_changed(stream, present, v):
            out = changed(stream, present, v)
            if out:
                events["signature changes"] += 1
                events[f"  by {_cause(stream, present, v)}"] += 1
            return out

        def counted_lookup(cache, *args, **kwargs):
            misses = cache.misses
            out = timed_lookup(cache, *args, **kwargs)
            events["system lookups"] += 1
            events["  builds" if cache.misses > misses else "  cache hits"] += 1
            return out

        def counted_read(stream):
            events["contact reads"] += 1
            return timed_read(stream)

        timed_read = SimAcousticStream.read_state
        SimAcousticStream.signature_changed, SystemCache.get_or_build = counted_changed, counted_lookup
        SimAcousticStream.read_state = counted_read
        self._restore += [(SimAcousticStream, "signature_changed", changed), (SystemCache, "get_or_build", timed_lookup),
                          (SimAcousticStream, "read_state", timed_read)]

    def reset(self) -> None:
        super().reset()
        self.events.clear()


def _cause(stream, present, v) -> str:
    """Why ``SimAcousticStream.signature_changed`` said the contacts changed (the first reason)."""
    if present != stream._ref_present:
        return "presence (a partner starts or stops pressing, or a fingertip)"
    tol, n, ref = stream.tolerance, stream._n_partners, stream._ref_vec
    force = any(math.sqrt((x - a) ** 2 + (y - b) ** 2 + (z - c) ** 2)
                > tol.force_rtol * math.sqrt(a * a + b * b + c * c) + tol.force_atol_n
                for (x, y, z), (a, b, c) in zip(v[:n], ref[:n]))
    return "net force" if force else "force-weighted point"


def _contact_formation():
    return random_steps("aas_gym/ContactFormation-v0")


def random_steps(env_id: str, **kwargs):
    """``env_id`` (made with ``kwargs``) and a step function of seeded random actions (seed 0,
    resets included) returning the observation."""
    env = gym.make(env_id, disable_env_checker=True, **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)

    def step():
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            env.reset()
        return obs
    return env, step


def moving_scene(obj: str):
    """``streaming_env.py``'s moving scene of ``obj`` (ContactFormation-v0 streaming it on a steel-bar plinth):
    the env and a step function (action 0) returning the observation."""
    env = gym.make("aas_gym/ContactFormation-v0", objects=[obj], plinths=["steel_bar"], max_episode_steps=None,
                   acoustic={"cadence": "stream"}, disable_env_checker=True)
    env.reset(seed=0)
    return env, (lambda: env.step(0)[0])


def profile(step, steps: int, warm_s: float = 0.0, warm_steps: int = 0) -> tuple[float, StreamProfile]:
    """CPU seconds per env step of ``steps`` calls of ``step`` after the warm-up, and the profile."""
    t0 = _clock()
    done = 0
    while done < warm_steps or _clock() - t0 < warm_s:
        step()
        done += 1
    with StreamProfile() as prof:
        t = _clock()
        for _ in range(steps):
            step()
        total = _clock() - t
    return total / steps, prof


def report(per_step_s: float, prof: StreamProfile, steps: int) -> list[str]:
    """Markdown lines: ms per env step per part (with calls per step), then the events per step."""
    lines = [f"{1e3 * per_step_s:.2f} ms per env step ({1 / per_step_s:.1f} steps/s, {0.05 / per_step_s:.1f}x real time)",
             "", "| part | ms / step | share | calls / step |", "|---|---:|---:|---:|"]
    other = per_step_s * steps - sum(prof.seconds.values())
    rows = sorted(prof.seconds.items(), key=lambda kv: -kv[1]) + [("other (Python outside the parts)", other)]
    for part, s in rows:
        calls = f"{prof.calls[part] / steps:.2f}" if part in prof.calls else ""
        lines.append(f"| {part} | {1e3 * s / steps:.2f} | {s / (per_step_s * steps):.0%} | {calls} |")
    builds = sum(s for p, s in prof.seconds.items() if p.startswith("build:"))
    lines += ["", f"builds in all: {1e3 * builds / steps:.2f} ms / step", "", "| event | per env step |", "|---|---:|"]
    for key in ("signature changes", *sorted(k for k in prof.events if k.startswith("  by")), "contact reads",
                "system lookups", "  builds", "  cache hits"):
        lines.append(f"| {key.strip()} | {prof.events[key] / steps:.2f} |")
    return lines


def ab(make, flag: str, chunks: int, chunk_steps: int, warm_steps: int) -> dict:
    """Reference (flag False) against fast path (flag True), interleaved (see the docstring)."""
    import statistics

    import numpy as np

    module, name = flag.split(":")
    mod = importlib.import_module(module)
    saved = getattr(mod, name)
    envs = {False: make(), True: make()}
    costs = {False: [], True: []}
    feature_db = 0.0
    last = {}
    try:
        for k in range(-1, chunks):
            order = (False, True) if k % 2 == 0 else (True, False)
            for on in order:
                setattr(mod, name, on)
                _, step = envs[on]
                t = _clock()
                for _ in range(warm_steps if k < 0 else chunk_steps):
                    last.setdefault(on, []).append(step())
                if k >= 0:
                    costs[on].append((_clock() - t) / chunk_steps)
            for a, b in zip(last[False], last[True]):
                fa, fb = a["acoustic"].astype(float), b["acoustic"].astype(float)
                feature_db = max(feature_db, float(np.abs(fa - fb).max()))
            last.clear()
    finally:
        setattr(mod, name, saved)
        for env, _ in envs.values():
            env.close()
    # builds come in bursts (a set-down, a slide): the mean is the throughput, the median a quiet chunk
    ref, fast = statistics.fmean(costs[False]), statistics.fmean(costs[True])
    med = statistics.median(costs[False]), statistics.median(costs[True])
    return {"ref_ms": 1e3 * ref, "fast_ms": 1e3 * fast, "speedup": ref / fast, "feature_db": feature_db,
            "ref_median_ms": 1e3 * med[0], "fast_median_ms": 1e3 * med[1]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=("contact_formation", "moving"), default="contact_formation")
    ap.add_argument("--object", default="abs_bar", help="the moving scene's object")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--warm-s", type=float, default=15.0, help="contact_formation: CPU s of random actions first")
    ap.add_argument("--warm-steps", type=int, default=3, help="moving, or contact_formation with --warm-s 0: env steps first")
    ap.add_argument("--ab", default=None, help="module:NAME: the fast path (True) against its reference (False)")
    ap.add_argument("--chunks", type=int, default=20)
    ap.add_argument("--chunk-steps", type=int, default=10)
    args = ap.parse_args(argv)
    if args.ab:
        make = _contact_formation if args.scene == "contact_formation" else (lambda: moving_scene(args.object))
        r = ab(make, args.ab, args.chunks, args.chunk_steps, args.warm_steps)
        print(f"{args.scene}{'' if args.scene == 'contact_formation' else ' ' + args.object}, {args.ab}: "
              f"reference {r['ref_ms']:.2f} ms/step, fast {r['fast_ms']:.2f} ms/step, speed-up {r['speedup']:.2f}x "
              f"(means over {args.chunks} chunks of {args.chunk_steps} steps after {args.warm_steps}; medians "
              f"{r['ref_median_ms']:.2f} and {r['fast_median_ms']:.2f}); "
              f"features differ by at most {r['feature_db']:.3g} dB")
        return r
    if args.scene == "contact_formation":
        env, step = _contact_formation()
        # --warm-s 0: a fixed number of warm-up steps, the same steps in every process
        per_step, prof = profile(step, args.steps, warm_s=args.warm_s, warm_steps=0 if args.warm_s else args.warm_steps)
        title = (f"ContactFormation-v0 (defaults, random actions) after "
                 f"{f'{args.warm_s:g} CPU s' if args.warm_s else f'{args.warm_steps} steps'}")
    else:
        env, step = moving_scene(args.object)
        per_step, prof = profile(step, args.steps, warm_steps=args.warm_steps)
        title = f"moving {args.object} on a steel-bar plinth after {args.warm_steps} steps"
    env.close()
    print(f"## {title}, {args.steps} steps\n")
    print("\n".join(report(per_step, prof, args.steps)))


if __name__ == "__main__":
    main()
