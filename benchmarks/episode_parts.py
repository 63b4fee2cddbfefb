"""Exclusive CPU time per part of a probe env's episode (GraspPosition-v0, ObjectRecognition-v0),
after a warm-up, one thread: where a randomized episode's sensing goes (issue 27).

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/episode_parts.py aas_gym/GraspPosition-v0 \
        [--warmup-s 15] [--seconds 20] [--randomization-off] [--flag sensors.modal.basis:FAST_POINT_CHECKS=0 ...]

Random actions (seeded), resets included; thread CPU ms per episode per part (``PARTS``,
:class:`_exclusive.ExclusiveTimes`: a part called inside another is charged to itself only).
"""
import argparse
import importlib
import os
import sys
import time

import aas_gym  # noqa: F401  (registers the envs)
import gymnasium as gym

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _exclusive import SENSING_PARTS, ExclusiveTimes  # noqa: E402  (benchmarks/, the script's folder)

#: (module, class or None, function, label)
PARTS = (
    ("aas_gym.envs.base", "AasEnv", "_grasp", "physics: grasp (rest)"),
    ("aas_gym.envs.base", "AasEnv", "_place_objects", "physics: place (rest)"),
    ("aas_gym.contacts", "ContactStream", "read", "contacts: read"),
    ("aas_gym.contacts", "ContactStream", "fingertip_forces_n", "contacts: fingertip forces"),
    ("aas_gym.contacts", "ContactStream", "fingertip_rows", "contacts: fingertip rows"),  # the grasp's lazy test
    ("sensors.modal.contact", "Contact", "__init__", "Contact()"),
    ("sensors.modal.contact", "Contact", "to_dict", "Contact.to_dict"),
    ("sensors.synthesis.feature_recording", None, "_object_spectra", "features: object spectra (rest)"),
    ("sensors.synthesis.stream", "AcousticStream", "__init__", "AcousticStream()"),
    ("sensors.synthesis.stream", "AcousticStream", "grasp_systems", "stream.grasp_systems (rest)"),
    ("sensors.modal.damping", None, "check_groups_on_surface", "system: surface check"),
    ("sensors.mesh.locator", "TetLocator", "within_surface_distance", "within surface distance"),
    ("sensors.modal.basis", None, "check_points_m", "check_points_m"),
    ("sensors.modal.spring_modes", "SpringModes", "_solve", "springs: eigh"),
    ("sensors.modal.spring_modes", "SpringModes", "_ritz_rows", "springs: ritz rows"),
    ("sensors.modal.spring_modes", None, "contact_springs", "springs: contact springs"),
    ("sensors.modal.static_correction", "ContactFlexibility", "_basis", "attach: basis (rest)"),
    ("sensors.modal.static_correction", "ContactFlexibility", "_implicit_basis", "attach: implicit basis"),
    ("sensors.modal.static_correction", "ContactFlexibility", "_combination", "attach: combination"),
    ("sensors.modal.static_correction", "AttachmentBasis", "nodal", "attach: nodal"),
    ("sensors.modal.static_correction", "UnitLoadStore", "columns", "attach: store columns"),
    ("sensors.modal.static_correction", "UnitLoadStore", "products", "attach: store products"),
    ("sensors.synthesis.modal_system", None, "_relevant_modes", "system: relevant modes"),
    ("sensors.synthesis.lti", None, "symmetric_gains_part", "system: symmetric gains (rest)"),
    ("sensors.synthesis.lti", "EigenPart", "__init__", "EigenPart()"),
    ("sensors.synthesis.fingertip", "FingertipModel", "modes", "drive: fingertip modes (rest)"),
    ("sensors.synthesis.exciter_sums", "ExciterSums", "sums", "drive: exciter sums"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env_id")
    ap.add_argument("--warmup-s", type=float, default=15.0)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--randomization-off", action="store_true", help="randomization=False")
    ap.add_argument("--flag", nargs="*", default=[], help="module:NAME=0|1, set before the run")
    args = ap.parse_args()
    for f in args.flag:
        target, value = f.split("=")
        module, name = target.split(":")
        setattr(importlib.import_module(module), name, value == "1")
    env = gym.make(args.env_id, **({"randomization": False} if args.randomization_off else {}))
    env.reset(seed=0)
    env.action_space.seed(0)

    def run(seconds: float):
        t0, episodes = time.thread_time(), 0
        while time.thread_time() - t0 < seconds:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
                episodes += 1
        return episodes, time.thread_time() - t0

    run(args.warmup_s)
    times = ExclusiveTimes(PARTS + SENSING_PARTS, clock=time.thread_time, everywhere=True)
    with times:
        run(2.0)
        times.reset()
        e, total = run(args.seconds)
    spent = dict(times.seconds)
    spent["other (env, gym, rest)"] = total - sum(spent.values())
    print(f"{args.env_id}: exclusive thread-CPU ms per episode ({e} episodes, {total / e * 1e3:.2f} ms each "
          "under the timers)")
    for k, v in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {k:36s} {v / e * 1e3:7.3f}  calls/ep {times.calls.get(k, 0) / e:5.2f}")


if __name__ == "__main__":
    main()
