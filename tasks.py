#!/usr/bin/env python3
"""One-command set-up and run for aas-gym, on a machine with only Python 3.10+ and pip.

    python3 tasks.py main [ARGS...]   set up, then run the main job (``aas run`` on the default scene)
    python3 tasks.py test [ARGS...]   set up, then run the test suite (what CI runs)
    python3 tasks.py test --fast      the edit-test loop: everything but the tests marked slow
    python3 tasks.py setup            set up only

Set-up is idempotent and cheap when nothing changed: it creates or reuses ``.venv``,
installs the Debian packages the project needs when run as root (PortAudio headers for
PyAudio, OSMesa/EGL for headless rendering, PulseAudio for the audio loopback tests), and
installs the project with pinned versions from ``constraints.txt`` (on x86-64 that includes
MKL, whose PARDISO is the modal build's sparse solver; it needs no Debian package).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
STAMP = VENV / ".aas-gym-installed"
EXTRAS = "dev,real,ray,rl"

# Debian package -> why the project needs it.
DEBIAN_PACKAGES = {
    "portaudio19-dev": "PortAudio headers, to build PyAudio (package `real`)",
    "libosmesa6": "OSMesa, headless MuJoCo rendering without a GPU",
    "libegl1": "EGL, headless MuJoCo rendering",
    "libgl1": "OpenGL runtime for MuJoCo rendering",
    "pulseaudio": "sound server with a null sink: the real audio loopback in tests",
    "pulseaudio-utils": "pactl, to configure the loopback",
    "libasound2-plugins": "ALSA -> PulseAudio bridge, so PortAudio sees the loopback",
}


def say(msg: str) -> None:
    print(f"[tasks] {msg}", flush=True)


def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, check=True, **kw)


def missing_debian_packages() -> list[str]:
    if shutil.which("dpkg-query") is None:
        return []
    missing = []
    for pkg in DEBIAN_PACKAGES:
        res = subprocess.run(["dpkg-query", "-W", "-f=${Status}", pkg], capture_output=True, text=True)
        if "install ok installed" not in res.stdout:
            missing.append(pkg)
    return missing


def ensure_system_packages() -> None:
    missing = missing_debian_packages()
    if not missing:
        return
    if os.geteuid() != 0 or shutil.which("apt-get") is None:
        say("WARNING: these Debian packages are missing and this is not a root Debian shell, so they "
            "are not installed automatically:")
        for pkg in missing:
            say(f"  {pkg}: {DEBIAN_PACKAGES[pkg]}")
        say("install them with: sudo apt-get install -y " + " ".join(missing))
        return
    say("installing Debian packages: " + " ".join(missing))
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    try:
        run(["apt-get", "update", "-q"], env=env, stdout=subprocess.DEVNULL)
        run(["apt-get", "install", "-y", "-q", "--no-install-recommends", *missing], env=env,
            stdout=subprocess.DEVNULL)
    except subprocess.CalledProcessError:
        say("ERROR: apt-get could not install: " + " ".join(missing))
        for pkg in missing:
            say(f"  {pkg}: {DEBIAN_PACKAGES[pkg]}")
        raise SystemExit(1)


def venv_python() -> Path:
    return VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def ensure_venv() -> Path:
    py = venv_python()
    if py.exists():
        return py
    say(f"creating virtual environment {VENV}")
    try:
        run([sys.executable, "-m", "venv", str(VENV)])
    except subprocess.CalledProcessError:
        shutil.rmtree(VENV, ignore_errors=True)
        if os.geteuid() == 0 and shutil.which("apt-get"):
            ver = f"python{sys.version_info.major}.{sys.version_info.minor}-venv"
            say(f"venv failed; installing Debian package {ver}")
            run(["apt-get", "install", "-y", "-q", ver])
            run([sys.executable, "-m", "venv", str(VENV)])
        else:
            say("ERROR: `python3 -m venv` failed; install your distribution's venv package "
                "(Debian: python3-venv) and try again")
            raise SystemExit(1)
    return py


def install_fingerprint() -> str:
    h = hashlib.sha256()
    for name in ("pyproject.toml", "constraints.txt"):
        p = ROOT / name
        if p.exists():
            h.update(p.read_bytes())
    h.update(sys.version.encode())
    return h.hexdigest()


def ensure_installed(py: Path) -> None:
    fingerprint = install_fingerprint()
    if STAMP.exists() and STAMP.read_text() == fingerprint:
        return
    say("installing aas-gym and its pinned dependencies into .venv (first run takes a few minutes)")
    pip = [str(py), "-m", "pip", "install", "--disable-pip-version-check"]
    for cmd in ([*pip, "--upgrade", "pip", "setuptools", "wheel"],
                [*pip, "-c", str(ROOT / "constraints.txt"), "-e", f"{ROOT}[{EXTRAS}]"]):
        # pip's log is long; show it only when something fails.
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            print(res.stdout[-6000:], res.stderr[-6000:], sep="\n", file=sys.stderr)
            say("ERROR: pip could not install the project (log above). If PyAudio failed to build, "
                "install the PortAudio headers (Debian: portaudio19-dev) and run again.")
            raise SystemExit(1)
    STAMP.write_text(fingerprint)
    say("installed")
    report_solver(py)


def report_solver(py: Path) -> None:
    """One line on the modal build's sparse solver: MKL PARDISO (installed with the project on
    x86-64 Linux and Windows) or SciPy's SuperLU (the same modes, several times slower on big models)."""
    res = subprocess.run([str(py), "-c", "from sensors.fem import available_solvers; print(available_solvers()[0])"],
                         capture_output=True, text=True, cwd=ROOT)
    solver = res.stdout.strip() or "unknown"
    say(f"sparse solver of the modal build: {solver}")


def runtime_env() -> dict[str, str]:
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("MUJOCO_GL", "egl")  # headless rendering
        env.setdefault("PYOPENGL_PLATFORM", env["MUJOCO_GL"])
    env.setdefault("AAS_GYM_CACHE", str(ROOT / ".cache" / "aas_gym"))
    return env


def setup() -> Path:
    if sys.version_info < (3, 10):
        raise SystemExit(f"aas-gym needs Python 3.10 or newer; this is {sys.version.split()[0]}")
    ensure_system_packages()
    py = ensure_venv()
    ensure_installed(py)
    return py


def main(argv: list[str]) -> int:
    if not argv or argv[0] in {"-h", "--help"} or argv[0] not in {"main", "test", "setup"}:
        print(__doc__)
        return 0 if argv and argv[0] in {"-h", "--help"} else 2
    task, rest = argv[0], argv[1:]
    py = setup()
    env = runtime_env()
    if task == "setup":
        say("set-up complete")
        return 0
    if task == "main":
        return subprocess.call([str(py), "-m", "aas_gym.cli", "run", *rest], cwd=ROOT, env=env)
    # Tests: two workers for the two cores; each file stays on one worker (module fixtures are
    # built once, and all audio tests, which share one sound server, are in one file). Files go
    # out in collection order, which tests/conftest.py starts with the longest (not xdist's
    # default, most tests first, which left the few-test cold builds for last).
    if "--fast" in rest:
        rest = [a for a in rest if a != "--fast"] + ["-m", "not slow"]
    return subprocess.call([str(py), "-m", "pytest", "-n", "2", "--dist", "loadfile", "--no-loadscope-reorder", *rest],
                           cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
