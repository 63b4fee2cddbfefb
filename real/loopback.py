"""A real audio loopback without sound hardware: PulseAudio with a null sink.

What is played to the null sink comes back, sample-exact, from its monitor source. This is
how the tests and the CI exercise the whole PyAudio path (PortAudio -> ALSA -> PulseAudio ->
ALSA -> PortAudio) for real on a machine without a sound card.

Needs Debian ``pulseaudio`` and ``libasound2-plugins`` (the ALSA ``pulse`` plugin that
PortAudio goes through), and ``portaudio19-dev`` to build PyAudio.

Start it from a shell (idempotent; prints the environment a client needs)::

    python -m real.loopback start      # or: stop, status

or from Python: :func:`start_loopback` (also sets ``PULSE_SERVER`` in ``os.environ`` so that
PyAudio instances created afterwards in this process find the server).

The server is private: its socket lives under a folder of its own (default
``/tmp/aas-gym-pulse-<uid>``, override with ``AAS_PULSE_DIR``), so it never touches a
desktop session's sound server. As root it runs in user mode with ``XDG_RUNTIME_DIR`` set
to that folder (PulseAudio warns that it is "not intended to be run as root"; harmless).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

DEFAULT_SINK = "aas_loop"
DEFAULT_FS = 44100


class LoopbackError(RuntimeError):
    """The PulseAudio loopback could not be started or reached."""


@dataclass(frozen=True)
class Loopback:
    """A running PulseAudio loopback.

    Attributes:
        runtime_dir: the server's private ``XDG_RUNTIME_DIR``.
        server: the ``PULSE_SERVER`` string clients use (``unix:<socket>``).
        sink: null sink name (what PyAudio's default output plays to).
        source: its monitor (PyAudio's default input).
        pid: server process id.
    """

    runtime_dir: Path
    server: str
    sink: str
    source: str
    pid: int

    def env(self) -> dict[str, str]:
        """Environment variables a client process needs to reach this server."""
        return {"PULSE_SERVER": self.server}


def default_runtime_dir() -> Path:
    """``$AAS_PULSE_DIR`` or ``/tmp/aas-gym-pulse-<uid>``."""
    return Path(os.environ.get("AAS_PULSE_DIR") or f"/tmp/aas-gym-pulse-{os.getuid()}")


def _require(tool: str) -> str:
    path = shutil.which(tool)
    if path is None:
        raise LoopbackError(
            f"{tool!r} not found: install Debian packages pulseaudio and libasound2-plugins "
            "(apt-get install -y pulseaudio libasound2-plugins)")
    return path


def _server_env(runtime_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["XDG_RUNTIME_DIR"] = str(runtime_dir)
    env["PULSE_SERVER"] = f"unix:{runtime_dir / 'pulse' / 'native'}"
    env.pop("PULSE_COOKIE", None)
    return env


def _pactl(runtime_dir: Path, *args: str, check: bool = True, timeout_s: float = 10.0) -> subprocess.CompletedProcess:
    proc = subprocess.run([_require("pactl"), *args], env=_server_env(runtime_dir), capture_output=True,
                          text=True, timeout=timeout_s)
    if check and proc.returncode != 0:
        raise LoopbackError(f"pactl {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()}")
    return proc


def server_pid(runtime_dir: Path) -> int | None:
    """The pid of the loopback's sound server in ``runtime_dir``, or None when none runs."""
    try:
        pid = int((runtime_dir / "pulse" / "pid").read_text().strip())
    except (OSError, ValueError):
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:
        pass
    # A zombie still answers kill(0); it is no server.
    try:
        if Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] == "Z":
            return None
    except OSError:
        pass
    return pid


def is_running(runtime_dir: str | os.PathLike | None = None) -> bool:
    """True if the loopback's PulseAudio server answers."""
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    if shutil.which("pactl") is None or not (runtime_dir / "pulse" / "native").exists():
        return False
    try:
        return _pactl(runtime_dir, "info", check=False, timeout_s=5.0).returncode == 0
    except subprocess.TimeoutExpired:
        return False


def sink_loaded(sink: str = DEFAULT_SINK, runtime_dir: str | os.PathLike | None = None) -> bool:
    """True if the null sink ``sink`` exists on the loopback server."""
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    out = _pactl(runtime_dir, "list", "short", "sinks").stdout
    return any(line.split("\t")[1:2] == [sink] for line in out.splitlines())


def load_sink(sink: str = DEFAULT_SINK, sample_rate_hz: int = DEFAULT_FS, channels: int = 2,
              runtime_dir: str | os.PathLike | None = None) -> None:
    """Load the null sink (float32, ``sample_rate_hz``, ``channels``) if absent and make it and its
    monitor the server's defaults."""
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    if not sink_loaded(sink, runtime_dir):
        # float32 so nothing is quantized to 16 bit on the way round; same rate as the rig
        # so the server never resamples.
        _pactl(runtime_dir, "load-module", "module-null-sink", f"sink_name={sink}",
               "format=float32le", f"rate={int(sample_rate_hz)}", f"channels={int(channels)}")
        _keep_clocked(sink, sample_rate_hz, channels, runtime_dir)
    _pactl(runtime_dir, "set-default-sink", sink)
    _pactl(runtime_dir, "set-default-source", f"{sink}.monitor")


#: The latency [ms] of the silent stream that keeps the null sink rendering in small blocks.
KEEPER_LATENCY_MS = 10


def _keep_clocked(sink: str, sample_rate_hz: int, channels: int, runtime_dir: Path) -> None:
    """Play silence into the null sink at a low latency, for as long as the sink lives. With
    nothing playing into it, a null sink renders in 2 s blocks, so a recording of its monitor
    started then waited up to 2 s for its first input (1.9 s per reset of the streamed real env,
    where a sound card delivers in milliseconds). Zeros mixed in change no sample (x + 0 = x).
    The stream belongs to a module, not a client (``pactl`` lists no client for it); it goes
    with the sink (``unload_sink``) and comes back with it."""
    silence = f"{sink}_silence"
    sources = _pactl(runtime_dir, "list", "short", "sources").stdout
    if not any(line.split("\t")[1:2] == [silence] for line in sources.splitlines()):
        _pactl(runtime_dir, "load-module", "module-null-source", f"source_name={silence}", "format=float32le",
               f"rate={int(sample_rate_hz)}", f"channels={int(channels)}")
    _pactl(runtime_dir, "load-module", "module-loopback", f"source={silence}", f"sink={sink}",
           f"latency_msec={KEEPER_LATENCY_MS}", "source_dont_move=true", "sink_dont_move=true")


def unload_sink(sink: str = DEFAULT_SINK, runtime_dir: str | os.PathLike | None = None) -> None:
    """Remove the null sink: every stream on it dies (a device unplugged mid-recording)."""
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    out = _pactl(runtime_dir, "list", "short", "modules").stdout
    for line in out.splitlines():
        fields = line.split("\t")
        if len(fields) >= 3 and fields[1] == "module-null-sink" and f"sink_name={sink}" in fields[2]:
            _pactl(runtime_dir, "unload-module", fields[0])


def start_loopback(sink: str = DEFAULT_SINK, sample_rate_hz: int = DEFAULT_FS, channels: int = 2,
                   runtime_dir: str | os.PathLike | None = None, *, set_environ: bool = True,
                   timeout_s: float = 10.0) -> Loopback:
    """Start (or reuse) the private PulseAudio server with a null sink whose monitor is the
    default source. Idempotent: a running server is reused and the sink (re)loaded.

    Args:
        sink: null sink name.
        sample_rate_hz: its sample rate in Hz (make it the rig's, so nothing is resampled).
        channels: its channel count.
        runtime_dir: the server's private folder (default :func:`default_runtime_dir`).
        set_environ: set ``PULSE_SERVER`` in ``os.environ`` so PyAudio in this process uses it.
        timeout_s: how long to wait for the server to answer.
    """
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    runtime_dir.mkdir(parents=True, exist_ok=True)
    os.chmod(runtime_dir, 0o700)  # PulseAudio refuses a runtime dir others can write
    if not is_running(runtime_dir):
        _clear_stale_server(runtime_dir)
        proc = subprocess.run(
            [_require("pulseaudio"), "-D", "--exit-idle-time=-1", "-n",
             "--load=module-native-protocol-unix", f"--log-target=file:{runtime_dir / 'pulse.log'}"],
            env=_server_env(runtime_dir), capture_output=True, text=True, timeout=timeout_s)
        deadline = time.monotonic() + timeout_s
        while not is_running(runtime_dir):
            if time.monotonic() > deadline:
                log = (runtime_dir / "pulse.log")
                tail = log.read_text()[-2000:] if log.exists() else ""
                raise LoopbackError(f"PulseAudio did not start in {timeout_s} s (exit {proc.returncode}): "
                                    f"{proc.stderr.strip()} {tail}")
            time.sleep(0.05)
    load_sink(sink, sample_rate_hz, channels, runtime_dir)
    pid = server_pid(runtime_dir)
    lb = Loopback(runtime_dir=runtime_dir, server=f"unix:{runtime_dir / 'pulse' / 'native'}",
                  sink=sink, source=f"{sink}.monitor", pid=pid or -1)
    if set_environ:
        os.environ.update(lb.env())
    return lb


def _clear_stale_server(runtime_dir: Path, timeout_s: float = 5.0) -> None:
    """Clean up after a server that died without cleaning up (SIGKILL): wait for a dying one
    to go, then remove its pid file and socket, which would make the next start fail with
    "Daemon already running"."""
    deadline = time.monotonic() + timeout_s
    while server_pid(runtime_dir) is not None and not is_running(runtime_dir) and time.monotonic() < deadline:
        time.sleep(0.05)  # still shutting down
    pid = server_pid(runtime_dir)
    if pid is not None and not is_running(runtime_dir):
        os.kill(pid, signal.SIGKILL)  # alive but not answering: it will never serve again
        while server_pid(runtime_dir) is not None and time.monotonic() < deadline + timeout_s:
            time.sleep(0.05)
    for stale in (runtime_dir / "pulse" / "pid", runtime_dir / "pulse" / "native"):
        with contextlib.suppress(FileNotFoundError):
            stale.unlink()


def stop_loopback(runtime_dir: str | os.PathLike | None = None, timeout_s: float = 5.0) -> bool:
    """Stop the loopback's server (only that one, by its pid file). Returns True if one ran."""
    runtime_dir = Path(runtime_dir) if runtime_dir else default_runtime_dir()
    pid = server_pid(runtime_dir)
    if pid is None:
        return False
    os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout_s
    while server_pid(runtime_dir) is not None and time.monotonic() < deadline:
        time.sleep(0.05)
    if server_pid(runtime_dir) is not None:
        os.kill(pid, signal.SIGKILL)
    return True


def main(argv: list[str] | None = None) -> int:
    """``python -m real.loopback start|stop|status``."""
    ap = argparse.ArgumentParser(prog="python -m real.loopback", description=__doc__.split("\n\n")[0])
    ap.add_argument("action", choices=["start", "stop", "status"])
    ap.add_argument("--sink", default=DEFAULT_SINK)
    ap.add_argument("--sample-rate-hz", type=int, default=DEFAULT_FS, help="null sink sample rate, Hz")
    ap.add_argument("--dir", default=None, help="private runtime folder (default %(default)s)")
    args = ap.parse_args(argv)
    if args.action == "start":
        lb = start_loopback(args.sink, args.sample_rate_hz, runtime_dir=args.dir, set_environ=False)
        print(f"export PULSE_SERVER={lb.server}  # pid {lb.pid}, sink {lb.sink}, source {lb.source}")
        return 0
    if args.action == "stop":
        print("stopped" if stop_loopback(args.dir) else "not running")
        return 0
    running = is_running(args.dir)
    print("running" if running else "not running")
    return 0 if running else 1


if __name__ == "__main__":
    raise SystemExit(main())
