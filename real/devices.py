"""PortAudio devices: listing, lookup by index or name, sample-rate checks, and PortAudio's
own diagnostics kept out of the terminal."""

from __future__ import annotations

import contextlib
import os
import tempfile
from typing import Any, Iterator

import numpy as np

from . import bounded
from .errors import DeviceLostError, DeviceNotFoundError, NoAudioDeviceError, UnsupportedSampleRateError
from .records import AudioDevice

try:  # PyAudio is the optional extra [real]; the error says how to get it.
    import pyaudio
except ImportError:  # pragma: no cover - depends on the installation
    pyaudio = None


def _require_pyaudio():
    if pyaudio is None:
        raise NoAudioDeviceError("PyAudio is not installed: pip install 'aas-gym[real]' "
                                 "(building it needs Debian's portaudio19-dev)")
    return pyaudio


@contextlib.contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Collect what C libraries (ALSA, JACK) print on fd 2 instead of flooding the terminal;
    the lines are kept for error messages."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no fd 2 (embedded interpreter): nothing to capture
        yield lines
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(tmp.read().decode(errors="replace").splitlines())


_NOISE = ("ALSA lib", "Expression '", "jack", "Jack", "Cannot connect to server", "JackShm")


@contextlib.contextmanager
def quiet_stderr() -> Iterator[None]:
    """Like :func:`captured_stderr`, then writes back what is not PortAudio/ALSA noise."""
    with captured_stderr() as lines:
        yield
    keep = [ln for ln in lines if not any(n in ln for n in _NOISE)]
    if keep:
        os.write(2, ("\n".join(keep) + "\n").encode())


def alsa_hint(lines: list[str], n: int = 3) -> str:
    """The last ``n`` useful lines of captured diagnostics, as ``" [a | b]"`` for an error message."""
    useful = [ln for ln in lines if ln.strip() and "jack" not in ln.lower()]
    return (" [" + " | ".join(useful[-n:]) + "]") if useful else ""


#: Longest wait for a sound-server call that can block (initializing PortAudio, closing the
#: streams, terminating) before the rig gives up on it, seconds.
SERVER_TIMEOUT_S = 3.0


def new_portaudio(timeout_s: float = SERVER_TIMEOUT_S) -> Any:
    """A fresh PortAudio session (device lists are read at initialization, so a new
    session sees devices that appeared or vanished since the last one); the caller
    terminates it (:func:`terminate_portaudio`).

    Initializing waits at most ``timeout_s`` for a sound server that does not answer
    (:mod:`real.bounded`): :class:`DeviceLostError` instead of a hang. While a call given up
    on earlier is still blocked, a new session fails at once saying so (it would only queue
    behind it).
    """
    pa_mod = _require_pyaudio()
    still = bounded.wait_until_idle(timeout_s)
    if still is not None:
        raise DeviceLostError(f"the sound server has not answered for a while: PortAudio is still {still} from an "
                              "earlier recording (server stalled or stopped?); wait until it answers again, or "
                              "restart this process", device="default")
    with captured_stderr():
        done, pa = bounded.call_bounded(pa_mod.PyAudio, timeout_s, "initializing",
                                        on_late_result=lambda late: late.terminate())
    if not done:
        raise DeviceLostError(f"the sound server did not answer within {timeout_s:g} s: PortAudio could not "
                              "initialize (server stalled or stopped?)", device="default")
    return pa


def terminate_portaudio(pa, timeout_s: float = SERVER_TIMEOUT_S) -> None:
    """Terminate a session, waiting at most ``timeout_s``; behind a close that is still
    blocked, do not wait again: terminate after it."""
    with captured_stderr():
        bounded.call_bounded(pa.terminate, 0.0 if bounded.pending() else timeout_s, "terminating")


@contextlib.contextmanager
def portaudio_session(timeout_s: float = SERVER_TIMEOUT_S) -> Iterator[Any]:
    """:func:`new_portaudio` for a ``with`` block, terminated (bounded) at its end."""
    pa = new_portaudio(timeout_s)
    try:
        yield pa
    finally:
        terminate_portaudio(pa, timeout_s)


def _devices(pa) -> list[AudioDevice]:
    try:
        din = pa.get_default_input_device_info()["index"]
    except OSError:
        din = -1
    try:
        dout = pa.get_default_output_device_info()["index"]
    except OSError:
        dout = -1
    out = []
    for i in range(pa.get_device_count()):
        info = pa.get_device_info_by_index(i)
        out.append(AudioDevice(
            index=i, name=info["name"], host_api=pa.get_host_api_info_by_index(info["hostApi"])["name"],
            max_input_channels=int(info["maxInputChannels"]), max_output_channels=int(info["maxOutputChannels"]),
            default_sample_rate_hz=float(info["defaultSampleRate"]),
            is_default_input=i == din, is_default_output=i == dout))
    return out


def list_devices() -> list[AudioDevice]:
    """The audio devices PortAudio sees now (empty if there are none)."""
    with portaudio_session() as pa:
        return _devices(pa)


def _describe(devices: list[AudioDevice], kind: str) -> str:
    key = "max_input_channels" if kind == "input" else "max_output_channels"
    usable = [str(d) for d in devices if getattr(d, key) > 0]
    return ", ".join(usable) if usable else "none"


def resolve_device(pa, spec: int | str | None, kind: str, channels: int) -> AudioDevice:
    """The device for ``spec`` (``None`` = system default, an index, or a case-insensitive
    name or name substring; an exact name wins over substrings) with ``channels`` ``kind``
    (``"input"``/``"output"``) channels."""
    devices = _devices(pa)
    key = "max_input_channels" if kind == "input" else "max_output_channels"
    if not devices:
        raise NoAudioDeviceError(
            f"no audio device: PortAudio finds none for the {kind} "
            f"({'system default' if spec is None else repr(spec)}). Is a sound card connected, or a sound "
            "server running? (without hardware: python -m real.loopback start)",
            device="default" if spec is None else str(spec))
    if spec is None:
        chosen = [d for d in devices if (d.is_default_input if kind == "input" else d.is_default_output)]
        if not chosen:
            raise NoAudioDeviceError(f"no default {kind} device; {kind} devices: {_describe(devices, kind)}",
                                     device="default")
        dev = chosen[0]
    elif isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        if not 0 <= int(spec) < len(devices):
            raise DeviceNotFoundError(f"no {kind} device with index {spec}; {kind} devices: "
                                      f"{_describe(devices, kind)}", device=f"index {spec}")
        dev = devices[int(spec)]
    elif isinstance(spec, str):
        exact = [d for d in devices if d.name.lower() == spec.lower() and getattr(d, key) > 0]
        partial = [d for d in devices if spec.lower() in d.name.lower() and getattr(d, key) > 0]
        if exact:
            dev = exact[0]
        elif len(partial) == 1:
            dev = partial[0]
        elif partial:
            raise DeviceNotFoundError(f"{kind} device name {spec!r} is ambiguous: {', '.join(map(str, partial))}",
                                      device=spec)
        else:
            raise DeviceNotFoundError(f"no {kind} device named like {spec!r}; {kind} devices: "
                                      f"{_describe(devices, kind)}", device=spec)
    else:
        raise TypeError(f"{kind}_device must be None, an index or a name, got {type(spec).__name__}")
    if getattr(dev, key) < channels:
        raise DeviceNotFoundError(f"{kind} device {dev} has {getattr(dev, key)} {kind} channels, "
                                  f"{channels} needed", device=dev.name)
    return dev


def check_sample_rate(pa, device: AudioDevice, kind: str, sample_rate_hz: int, channels: int) -> None:
    """Raise :class:`UnsupportedSampleRateError` naming ``device`` if it refuses ``sample_rate_hz``."""
    kw = ({"input_device": device.index, "input_channels": channels, "input_format": pyaudio.paFloat32}
          if kind == "input" else
          {"output_device": device.index, "output_channels": channels, "output_format": pyaudio.paFloat32})
    try:
        with captured_stderr() as lines:
            pa.is_format_supported(float(sample_rate_hz), **kw)
    except ValueError as exc:
        raise UnsupportedSampleRateError(
            f"{kind} device {device} does not support a sample rate of {sample_rate_hz} Hz ({exc.args[0] if exc.args else exc}); "
            f"its default rate is {device.default_sample_rate_hz:g} Hz{alsa_hint(lines)}", device=device.name) from None
