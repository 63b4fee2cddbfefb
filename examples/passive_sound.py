"""Passive sound: a held bar knocked onto the table and slid along it.

The hand grasps an aluminium bar resting on the table, lifts it 3 cm, brings it down at once
(the knock), presses it and slides it 3 cm along the table at 5 cm/s, while the linear sweep
loops.
The stream is recorded twice from the same physics: with passive sound
(``sensors.PassiveSound``: contact force changes and slides excite the bar) and without; the
figure shows the spectrogram of the recording, of the passive part alone (the difference),
and the table force with the steps where a table contact slides.

    python examples/passive_sound.py [--out PATH]   (default: docs/images/passive_sound.png)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np

from aas_gym.grasp import Hand, planar_grasp
from aas_gym.scenario import settle
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from aas_gym.sim_stream import SimAcousticStream
from sensors import PassiveSound

STEP = 2205                                   # samples per 0.05 s (25 physics steps)
#: (what, tcp offset from the grasp [m]: x, z, env steps, moved there gradually over the steps)
PLAN = (("hold", 0.0, 0.0, 6, False), ("lift", 0.0, 0.03, 12, False), ("knock", 0.0, -0.003, 10, False),
        ("slide", 0.03, -0.003, 12, True), ("hold", 0.03, -0.003, 8, False))
DEFAULT_OUT = Path(__file__).resolve().parent.parent / "docs" / "images" / "passive_sound.png"


def record(passive: PassiveSound | None):
    """The audio of the plan, the table force and whether a table contact slides, per step."""
    m = build_scene(["aluminium_bar"], contact_signature=True)
    d = mujoco.MjData(m)
    sensor = SimAcousticSensor(m, d, on_no_grasp="silence")
    hand = Hand(m)
    settle(m, d, 0.3)
    if not planar_grasp(m, d, sensor.bodies[0], 0.02, 40.0, hand=hand).success:
        raise RuntimeError("the bar could not be grasped")
    stream = SimAcousticStream(sensor, "linear", rng=0, passive=passive)
    home = hand.tcp(d).copy()
    audio, table, sliding, events = [], [], [], []
    target = home.copy()
    for name, dx, dz, steps, gradual in PLAN:
        events.append((len(audio) * STEP / stream.sample_rate_hz, name))
        start, goal = target, home + np.array([dx, 0.0, dz, 0.0])
        for i in range(steps):
            target = start + (goal - start) * ((i + 1) / steps if gradual else 1.0)
            hand.command(d, tcp=target)
            audio.append(stream.step_physics(25, STEP))
            c = sensor.contacts()[sensor.bodies[0]]
            env = c.select("environment")
            table.append(env.total_normal_force_n())
            sliding.append(bool(env.sensor_loads().sliding.any()))
    return np.concatenate(audio), np.array(table), np.array(sliding), events, stream.sample_rate_hz


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="figure file (PNG)")
    args = ap.parse_args(argv)
    on, table, sliding, events, fs = record(PassiveSound())
    off, *_ = record(None)
    out = _plot(on, on - off, table, sliding, events, fs, args.out)
    knock, slide = int(events[2][0] * fs), int(events[3][0] * fs)
    part = np.abs(on - off)
    print(f"passive part: peak {part.max():.3g} (drive peak {np.abs(off).max():.3g}); "
          f"knock peak {part[knock:slide].max():.3g}; slide peak {part[slide:].max():.3g}; "
          f"sliding steps {int(sliding.sum())}")
    print(f"wrote {out}")
    return out


def _plot(wave, passive, table, sliding, events, fs, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.signal import spectrogram

    from sensors._infra.atomic import atomic_savefig

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True, gridspec_kw={"height_ratios": [3, 3, 1]})
    panels = [(ax, spectrogram(w - np.mean(w), fs, nperseg=1024, noverlap=512), title) for ax, w, title in (
        (axes[0], wave, "recording with passive sound (linear sweep looping)"),
        (axes[1], passive, "passive part alone (with minus without passive sound)"))]
    # one colour scale for both panels, 100 dB down from the recording's loudest cells
    top = np.percentile(10 * np.log10(panels[0][1][2] + 1e-30), 99.5)
    for ax, (f, tt, S), title in panels:
        ax.pcolormesh(tt, f / 1e3, 10 * np.log10(S + 1e-30), shading="auto", cmap="magma", vmin=top - 100,
                      vmax=top)
        ax.set_ylabel("frequency [kHz]")
        ax.set_title(title, fontsize=10)
    t = (np.arange(len(table)) + 1) * STEP / fs
    bx = axes[2]
    bx.plot(t, table, label="table force [N]")
    bx.fill_between(t, 0, np.where(sliding, table.max(), 0), step="pre", alpha=0.2, color="C3",
                    label="a table contact slides")
    bx.set_xlabel("time [s]")
    bx.legend(loc="upper left", fontsize=8)
    for time_s, name in events:
        for a in axes:
            a.axvline(time_s, color="w" if a is not bx else "k", ls="--", lw=0.8)
        axes[0].text(time_s + 0.02, 20.5, name, color="w", fontsize=9, va="top")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    main()
