"""The physical rig: PyAudio play/record with the same observation API as the simulation.

- :class:`PyAudioRig`, :func:`list_devices`: the actuator output and contact-microphone input;
  :class:`RigSettings`: its settings as one frozen value.
- :class:`RealAcousticSensor`: ``sense(excitation, duration_s) -> sensors.AcousticObservation``.
- :class:`RigStream`: the rig recording without a break while the excitation loops, read
  piece by piece (``read(n)``, ``latest_features()``), as ``sensors.AcousticStream`` simulates.
- :func:`record_leaks`: the rig's leak per excitation, in the file format the simulator loads.
- :class:`RealGraspEnv`, :class:`RobotInterface`, :class:`RobotState`: the AcousticGrasp task on
  a real robot, same spaces as the simulated env (``aas_gym.robot.MujocoRobot`` runs it on
  the simulated scene; this package never imports ``aas_gym``).
- :mod:`real.loopback`: a PulseAudio null-sink loopback to run all this without hardware.

PyAudio is imported lazily by the rig; ``import real`` works without it.
"""

# Exported lazily (PEP 562): `aas --help` imports real.cli to list its commands and should not
# pay for the sensor stack and PortAudio (~0.4 s, measured with -X importtime).
_LAZY = {
    "find_latency": "real.latency", "period_lags": "real.latency",
    "AudioDevice": "real.records", "list_devices": "real.devices",
    "DeviceLostError": "real.errors", "DeviceNotFoundError": "real.errors", "ExcitationNotFoundError": "real.errors",
    "NoAudioDeviceError": "real.errors", "RigError": "real.errors", "RigWarning": "real.errors",
    "StorageError": "real.errors", "UnsupportedSampleRateError": "real.errors", "XrunError": "real.errors",
    "PyAudioRig": "real.rig", "RigSettings": "real.settings",
    "RigRecording": "real.records", "recover_partial": "real.partial_files",
    "RigStream": "real.rig_stream",
    "RealAcousticSensor": "real.sensor", "record_leaks": "real.sensor",
    "RealGraspEnv": "real.env", "RobotInterface": "real.env", "RobotState": "real.env",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'real' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
