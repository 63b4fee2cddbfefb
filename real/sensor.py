"""``RealAcousticSensor``: the rig behind the ``sensors.AcousticSensor`` protocol, and leak
recording (the sim-to-real bridge: the simulator adds the rig's measured leak)."""

from __future__ import annotations

import datetime as _dt
import os
import warnings
from pathlib import Path
from typing import Any

from sensors import AcousticObservation, Excitation
from sensors.signals.leak import save_leak

from .errors import DeviceLostError, RigWarning, XrunError
from .records import RigRecording
from .rig import PyAudioRig


def _excitation(excitation: Excitation | str) -> Excitation:
    if isinstance(excitation, str):
        return Excitation.by_name(excitation)
    if not isinstance(excitation, Excitation):
        raise TypeError(f"excitation must be a sensors.Excitation or a name, got {type(excitation).__name__}")
    return excitation


class RealAcousticSensor:
    """The physical active acoustic sensor: ``sense`` plays and records through a
    :class:`PyAudioRig` and returns the same :class:`sensors.AcousticObservation` as the
    simulated sensor (float32 waveform of ``round(duration_s * sample_rate_hz)`` samples aligned to the
    excitation, ``start_time_s = 0``, the same 140 features), with ``metadata["source"] ==
    "real"`` and the rig's facts (devices, latency, xruns, synchronization, time, labels).

    Args:
        rig: the rig.
        trim_preroll: cut the recording to the simulated layout (see
            :meth:`RigRecording.to_observation`); ``False`` keeps the pre-roll and sets
            ``start_time_s`` to the latency.
        retries: re-record this many times when a recording has xruns, lost
            synchronization (rig ``xrun_policy="raise"``) or lost its device before the
            excitation came back (a sound server still starting); each retry is warned.
        save_dir: if set, every observation is saved there atomically as
            ``<time>_<excitation>.npz`` (samples stream to a partial file while recording).
        labels: metadata labels added to every observation (``sense`` can add more).
    """

    def __init__(self, rig: PyAudioRig, *, trim_preroll: bool = True, retries: int = 2,
                 save_dir: str | os.PathLike | None = None, labels: dict[str, Any] | None = None) -> None:
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        self.rig = rig
        self.trim_preroll = bool(trim_preroll)
        self.retries = int(retries)
        self.save_dir = Path(save_dir) if save_dir is not None else None
        self.labels = dict(labels or {})
        self.last_path: Path | None = None

    @property
    def sample_rate_hz(self) -> int:
        """The rig's sample rate."""
        return self.rig.sample_rate_hz

    def record(self, excitation: Excitation | str, duration_s: float, *,
               save_path: str | os.PathLike | None = None, labels: dict[str, Any] | None = None) -> RigRecording:
        """One :class:`RigRecording`, retried on xruns/lost synchronization."""
        excitation = _excitation(excitation)
        for attempt in range(self.retries + 1):
            try:
                return self.rig.record(excitation, duration_s, save_path=save_path, labels=labels)
            except (XrunError, DeviceLostError) as exc:
                # A stream that dies as it starts, before any excitation came back (a sound
                # server still coming up after a restart), is retried like an xrun; one lost
                # mid-recording is raised at once with its partial file.
                started = exc.recording is not None and exc.recording.latency_samples is not None
                if attempt == self.retries or (isinstance(exc, DeviceLostError) and started):
                    raise
                if exc.partial_path is not None:  # a retry follows: this one is superseded
                    Path(exc.partial_path).unlink(missing_ok=True)
                warnings.warn(f"{exc} (retry {attempt + 1} of {self.retries})", RigWarning, stacklevel=3)
        raise AssertionError("unreachable")

    def sense(self, excitation: Excitation | str, duration_s: float = 1.0, *,
              labels: dict[str, Any] | None = None) -> AcousticObservation:
        """Play ``excitation`` (looping) for ``duration_s`` seconds of aligned recording and
        return the observation (saved to ``save_dir`` if set)."""
        excitation = _excitation(excitation)
        all_labels = {**self.labels, **(labels or {})}
        path = None
        if self.save_dir is not None:
            stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S_%fZ")
            path = self.save_dir / f"{stamp}_{excitation.name}.npz"
        rec = self.record(excitation, duration_s, save_path=path, labels=all_labels)
        obs = rec.to_observation(trim=self.trim_preroll, labels=all_labels, extra_metadata={"kind": "recording"})
        if path is not None:
            self.last_path = obs.save(path)
            rec.discard_partial()
        return obs

    def record_leak(self, excitation: Excitation | str, path: str | os.PathLike, duration_s: float = 2.0, *,
                    labels: dict[str, Any] | None = None) -> Path:
        """Record the actuator-to-microphone leak with the gripper idle (nothing grasped) and
        save it atomically in the format the simulated sensor loads (``sensors.signals.leak``).

        The saved waveform starts at the first excitation period (the pre-roll is cut); the
        simulator re-aligns it by its excitation peak anyway.
        """
        excitation = _excitation(excitation)
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        meta_labels = {**self.labels, **(labels or {}), "gripper": "idle"}
        rec = self.record(excitation, duration_s, save_path=path, labels=meta_labels)
        obs = rec.to_observation(trim=True, labels=meta_labels)
        # save_leak writes atomically (temporary file, fsync, rename)
        save_leak(path, obs.waveform, obs.sample_rate_hz, excitation, {**obs.metadata, "kind": "leak"})
        rec.discard_partial()
        return path


def record_leaks(sensor: RealAcousticSensor, out_dir: str | os.PathLike,
                 excitations: list[Excitation | str] | None = None, duration_s: float = 2.0) -> dict[str, Path]:
    """Record the leak for each excitation (default: the paper's three) into
    ``out_dir/leak_<name>.npz``; returns excitation name -> path (the mapping
    ``aas_gym.SimAcousticSensor(leak=...)`` takes, after ``sensors.signals.leak.load_leak``)."""
    out = {}
    for ex in excitations or ["impulse", "linear", "exponential"]:
        ex = _excitation(ex)
        out[ex.name] = sensor.record_leak(ex, Path(out_dir) / f"leak_{ex.name}.npz", duration_s)
    return out
