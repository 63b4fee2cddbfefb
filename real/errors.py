"""The rig's errors and warning: each names the device, and errors raised while recording
carry the samples recorded so far as ``.recording``."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path

    from .rig_recording import RigRecording


class RigError(RuntimeError):
    """An audio-rig failure. ``device`` names the device involved; ``recording`` holds what
    was recorded before the failure (a :class:`RigRecording` with ``complete=False``) and
    ``partial_path`` the file it was saved to, if any."""

    def __init__(self, message: str, *, device: str | None = None, recording: RigRecording | None = None,
                 partial_path: Path | None = None) -> None:
        super().__init__(message)
        self.device = device
        self.recording = recording
        self.partial_path = partial_path


class NoAudioDeviceError(RigError):
    """PortAudio finds no device (or no default device of the needed kind)."""


class DeviceNotFoundError(RigError):
    """No device matches the requested name or index."""


class UnsupportedSampleRateError(RigError):
    """The device refuses the sample rate."""


class DeviceLostError(RigError):
    """The device stopped delivering audio during a recording (unplugged, server gone)."""


class ExcitationNotFoundError(RigError):
    """The excitation does not come back in the microphone recording."""


class XrunError(RigError):
    """Overflow/underrun flags or lost sample synchronization (``xrun_policy="raise"``)."""


class RigWarning(UserWarning):
    """Overflow/underrun or lost synchronization under ``xrun_policy="warn"``."""
