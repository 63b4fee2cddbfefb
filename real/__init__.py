"""The physical rig: PyAudio play/record with the same observation API as the simulation.

- :class:`PyAudioRig`, :func:`list_devices`: the actuator output and contact-microphone input.
- :class:`RealAcousticSensor`: ``sense(excitation, duration_s) -> sensors.AcousticObservation``.
- :func:`record_leaks`: the rig's leak per excitation, in the file format the simulator loads.
- :class:`RealGraspEnv`, :class:`RobotInterface`, :class:`RobotState`: the AcousticGrasp task on
  a real robot, same spaces as the simulated env (``aas_gym.robot.MujocoRobot`` runs it on
  the simulated scene; this package never imports ``aas_gym``).
- :mod:`real.loopback`: a PulseAudio null-sink loopback to run all this without hardware.

PyAudio is imported lazily by the rig; ``import real`` works without it.
"""

from .latency import find_latency, period_lags
from .rig import (
    AudioDevice,
    DeviceLostError,
    DeviceNotFoundError,
    ExcitationNotFoundError,
    NoAudioDeviceError,
    PyAudioRig,
    RigError,
    RigRecording,
    RigWarning,
    UnsupportedSampleRateError,
    XrunError,
    list_devices,
    recover_partial,
)
from .sensor import RealAcousticSensor, record_leaks
from .env import RealGraspEnv, RobotInterface, RobotState
