"""The rig's errors and warning: each names the device, and errors raised while recording
carry the samples recorded so far as ``.recording``."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path

    from .records import RigRecording


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


class StorageError(RigError, OSError):
    """Writing a recording to disk failed (disk full, file too large, no permission). The
    samples are not lost: ``recording`` holds all of them in memory, ``partial_path`` the
    file with what fitted (if any), and ``errno`` / ``strerror`` / ``filename`` say why (it is
    an ``OSError`` too, so ``except OSError`` handlers still see it)."""

    def __init__(self, message: str, *, cause: OSError | None = None, **kwargs) -> None:
        super().__init__(message, **kwargs)
        if cause is not None:
            self.errno, self.strerror, self.filename = cause.errno, cause.strerror, cause.filename

    def __str__(self) -> str:  # OSError's would print "[Errno n] ..." without the message
        return str(self.args[0]) if self.args else ""


class RigWarning(UserWarning):
    """Overflow/underrun or lost synchronization under ``xrun_policy="warn"``."""
