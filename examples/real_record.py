"""Record the contact microphone while the actuator plays each excitation, on the real rig.

Uses the system's default input and output devices (change ``INPUT`` / ``OUTPUT`` to a
device name or index from ``aas audio-devices``). Without a sound card, start the loopback
first and the example records what it plays:

    python -m real.loopback start          # prints: export PULSE_SERVER=...
    export PULSE_SERVER=unix:/tmp/aas-gym-pulse-0/pulse/native
    python examples/real_record.py
"""

import sys
from pathlib import Path

import sensors
from real import NoAudioDeviceError, PyAudioRig, RealAcousticSensor, RigError, list_devices

INPUT = None    # contact microphone: None = system default, or a name / index
OUTPUT = None   # actuator amplifier
GAIN = 0.5      # output level (full scale 1); leave headroom for the microphone
SECONDS = 1.0   # the paper uses the first second of each recording
OUT_DIR = Path(__file__).resolve().parents[1] / "recordings"  # the repository's (git-ignored), whatever the cwd


def main() -> int:
    try:
        devices = list_devices()
    except NoAudioDeviceError as exc:  # PyAudio itself missing
        print(exc)
        return 1
    if not devices:
        print("No audio device found: connect the rig's sound card, or run without hardware through\n"
              "a PulseAudio loopback:  python -m real.loopback start  (then export the PULSE_SERVER it prints).")
        return 1
    try:
        rig = PyAudioRig(INPUT, OUTPUT, output_gain=GAIN, xrun_policy="warn")
    except RigError as exc:
        print(f"Cannot use the audio devices: {exc}")
        return 1
    print(f"Rig: {rig}")
    sensor = RealAcousticSensor(rig, save_dir=OUT_DIR, labels={"example": "real_record"})
    for name in ("impulse", "linear", "exponential"):
        try:
            obs = sensor.sense(name, SECONDS)
        except RigError as exc:
            print(f"{name}: {exc}")
            return 1
        m = obs.metadata
        f = obs.features()
        print(f"{name:12s} -> {sensor.last_path}  first period at {m['latency_s'] * 1e3:.1f} ms, "
              f"drift {m['sync']['drift_samples']} samples, peak {m['peak_amplitude']:.3f}, "
              f"features {f.shape[0]} (max {f.max():.3g} at {sensors.feature_frequencies_hz()[f.argmax()]:.0f} Hz)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
