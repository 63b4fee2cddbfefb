"""Grasp an object with the simulated Franka hand, play an excitation, look at the spectrum.

    python examples/grasp_and_sense.py --object wood_bar --excitation linear --position 0.03
    python examples/grasp_and_sense.py --robot panda     # the Franka Panda arm holds the same hand

Saves ``outputs/grasp_scene.png`` (the grasp, rendered headless) and
``outputs/grasp_spectrum.png`` (raw and smoothed spectrum, and the 140 features).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import aas_gym  # noqa: F401  (sets MUJOCO_GL=egl when there is no display)
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import mujoco

from aas_gym.grasp import planar_grasp
from aas_gym.robots import ROBOT_NAMES, robot_controller
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation, feature_frequencies_hz, smooth_spectrum

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="aluminium_bar", help="<material>_<shape>, e.g. wood_bar, pla_tube")
    parser.add_argument("--excitation", default="linear", help="impulse, linear or exponential")
    parser.add_argument("--position", type=float, default=0.03, help="grasp point along the object axis [m]")
    parser.add_argument("--grip-force", type=float, default=40.0, help="grip force [N]")
    parser.add_argument("--robot", default="floating_hand", choices=ROBOT_NAMES, help="who grasps")
    parser.add_argument("--out", type=Path, default=OUTPUTS)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    # 1. A scene with the hand, a table and the object; grasp it across its axis.
    model = build_scene([args.object], robot=args.robot)
    data = mujoco.MjData(model)
    grasp = planar_grasp(model, data, args.object, args.position, args.grip_force, hand=robot_controller(model))
    print(f"grasp: success={grasp.success} fingertip forces {grasp.actuator_force_n:.1f} / "
          f"{grasp.mic_force_n:.1f} N, opening {grasp.opening_m * 1e3:.1f} mm")

    # 2. The simulated sensor reads the contacts and synthesizes the microphone signal.
    sensor = SimAcousticSensor(model, data)
    excitation = Excitation.by_name(args.excitation)
    observation = sensor.sense(excitation, duration_s=1.0)
    features = observation.features()

    # 3. Pictures.
    with mujoco.Renderer(model, 480, 640) as renderer:
        renderer.update_scene(data, camera="panda_view" if args.robot == "panda" else "closeup")
        plt.imsave(args.out / ("panda_grasp.png" if args.robot == "panda" else "grasp_scene.png"), renderer.render())
    freqs, amplitude = observation.spectrum()
    band = (freqs >= 3000) & (freqs <= 8000)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), constrained_layout=True)
    top.plot(freqs[band], amplitude[band], lw=0.6, color="0.6", label="raw")
    top.plot(freqs[band], smooth_spectrum(amplitude)[band], lw=1.5, label="Savitzky-Golay")
    top.set(xlabel="frequency [Hz]", ylabel="amplitude", yscale="log",
            title=f"{args.object}, {excitation.name}, grasp at {args.position * 1e3:.0f} mm")
    top.legend()
    bottom.stem(feature_frequencies_hz(), features, markerfmt=" ", basefmt=" ")
    bottom.set(xlabel="frequency [Hz]", ylabel="feature", yscale="log", title="140-d feature vector")
    fig.savefig(args.out / "grasp_spectrum.png", dpi=120)
    scene_png = "panda_grasp.png" if args.robot == "panda" else "grasp_scene.png"
    print(f"wrote {args.out / scene_png} and {args.out / 'grasp_spectrum.png'}")


if __name__ == "__main__":
    main()
