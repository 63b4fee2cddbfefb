"""Sense your own object: a mesh file into the envs, next to the shipped everyday objects.

Builds a small part from trimesh primitives (a 30 mm square post with a 40 mm round cap),
saves it as an STL file the way a CAD export would be, names it to ``gym.make`` as
``"<file>:<material>"``, grasps it and records it; then grasps the shipped mug, can and
L-bracket too and draws each grasp with the spectrum it gave to ``--out``.

    python examples/any_object.py [--out outputs/any_object.png]
    python examples/any_object.py --out docs/images/any_object.png   # the README's figure
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402

import aas_gym  # noqa: E402, F401  (registers the envs)
from sensors import feature_frequencies_hz  # noqa: E402

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"


def make_part(folder: Path) -> Path:
    """A user's part as an STL file in metres."""
    body = trimesh.creation.box((0.03, 0.03, 0.12))
    cap = trimesh.creation.cylinder(0.02, 0.05)
    cap.apply_translation((0.0, 0.0, 0.07))
    path = folder / "post.stl"
    trimesh.boolean.union([body, cap], engine="manifold").export(path)
    return path


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=OUTPUTS / "any_object.png", help="figure file (default: outputs/ of the repository)")
    args = ap.parse_args(argv)
    part = make_part(Path(tempfile.mkdtemp(prefix="aas-part-")))
    objects = [f"{part}:aluminium", "mug", "can", "l_bracket"]
    fig, axes = plt.subplots(2, len(objects), figsize=(4 * len(objects), 7), constrained_layout=True)
    freqs_khz = feature_frequencies_hz() / 1e3
    for col, name in enumerate(objects):
        env = gym.make("aas_gym/GraspPosition-v0", objects=[name], n_positions=3, spacing_m=0.01,
                       render_mode="rgb_array", camera_name="closeup")
        obs, info = env.reset(seed=col)
        print(f"{info['label']}: grasped at {info['grasp_position_m'] * 1e3:.1f} mm along its grasp path, "
              f"pads {info.get('grip_force_n', 0):.0f} N, grasped={info['grasp_success']}")
        axes[0, col].imshow(env.render())
        axes[0, col].set_title(info["label"])
        axes[0, col].axis("off")
        spectrum = np.asarray(obs["acoustic"], float)
        axes[1, col].plot(freqs_khz, 20 * np.log10(np.maximum(spectrum, 1e-12) / spectrum.max()), lw=0.8)
        axes[1, col].set(xlabel="frequency [kHz]", ylabel="amplitude [dB re max]", ylim=(-60, 3))
        env.close()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    main()
