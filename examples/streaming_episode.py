"""Sensing while the robot moves: a spectrogram of one streamed episode.

The hand of ``aas_gym/AcousticGrasp-v0`` (``acoustic={"cadence": "stream"}``) reaches an
aluminium bar, grasps it, lifts it, sets it back down and presses it on the table, then lets
go. The microphone records without a break while the sweep loops; every env step returns its
2205 samples under ``audio``. The figure shows the spectrogram of the whole episode with the
events marked, and below it the grip and table forces from MuJoCo's contacts.

    python examples/streaming_episode.py [--out docs/images/streaming_episode.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

import aas_gym  # noqa: F401  (registers the envs)

#: Where this example writes, whatever the current folder: the repository's outputs/ (git-ignored).
OUTPUTS = Path(__file__).resolve().parents[1] / "outputs"


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=OUTPUTS / "streaming_episode.png", help="figure file (PNG)")
    args = ap.parse_args(argv)

    env = gym.make("aas_gym/AcousticGrasp-v0", randomization=False, max_episode_steps=None,
                   acoustic={"cadence": "stream", "feature_scale": "db", "noise_std": 2e-7})
    obs, _ = env.reset(seed=0)
    sim = env.unwrapped
    audio, grip, table, events = [], [], [], []

    def step(dx=0.0, dy=0.0, dz=0.0, close=False):
        nonlocal obs
        action = np.array([dx, dy, dz, 0.0, -1.0 if close else 1.0, 0.0], np.float32)
        obs, _, _, _, info = env.step(np.clip(action, -1, 1))
        c = sim.sensor.contacts()[sim.sensor.bodies[0]]
        audio.append(obs["audio"])
        grip.append(c.total_normal_force_n("actuator"))
        table.append(c.total_normal_force_n("environment"))
        return info

    def go_to(z_m, close, steps=40, xy=True):
        for _ in range(steps):
            err = obs["object"][:3] - obs["tcp"][:3]
            step(*(np.clip(err[:2] / 0.01, -1, 1) if xy else (0.0, 0.0)),
                 np.clip((z_m - obs["tcp"][2]) / 0.01, -1, 1), close)

    t = lambda: len(audio) * sim.dt  # noqa: E731  (stream time [s])
    go_to(obs["object"][2] + 0.06, close=False, steps=25)          # above the bar
    go_to(obs["object"][2], close=False, steps=20)                  # down around it
    events.append((t(), "grasp"))
    for _ in range(20):
        step(close=True)
    rest_z = obs["tcp"][2]
    events.append((t(), "lift"))
    go_to(rest_z + 0.03, close=True, steps=25, xy=False)
    events.append((t(), "set down"))
    go_to(rest_z, close=True, steps=20, xy=False)
    events.append((t(), "press"))
    go_to(rest_z - 0.002, close=True, steps=20, xy=False)
    events.append((t(), "release"))
    for _ in range(20):
        step(close=False)
    env.close()

    out = _plot(np.concatenate(audio), sim.excitation.sample_rate_hz, sim.dt, np.array(grip), np.array(table),
                events, Path(args.out))
    print(f"{len(audio)} steps = {t():.2f} s streamed; wrote {out}")
    return out


def _plot(wave, fs, dt, grip, table, events, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import spectrogram

    from sensors._infra.atomic import atomic_savefig

    f, tt, S = spectrogram(wave, fs, nperseg=1024, noverlap=512)
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    ax.pcolormesh(tt, f / 1e3, 10 * np.log10(S + 1e-30), shading="auto", cmap="magma", vmin=-220, vmax=-120)
    ax.set_ylabel("frequency [kHz]")
    ax.set_title("Streamed microphone of one episode (linear sweep looping, aluminium bar)")
    steps_t = (np.arange(len(grip)) + 1) * dt
    bx.plot(steps_t, grip, label="grip force (actuator tip)")
    bx.plot(steps_t, table, label="table force")
    bx.set_ylabel("force [N]")
    bx.set_xlabel("time [s]")
    bx.legend(loc="upper right", fontsize=8)
    for time_s, name in events:
        for a in (ax, bx):
            a.axvline(time_s, color="w" if a is ax else "k", ls="--", lw=0.8)
        ax.text(time_s + 0.02, 20.5, name, color="w", fontsize=9, va="top")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    main()
