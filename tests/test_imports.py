"""Imports stay cheap: what `import sensors`, `import aas_gym`, `import real` and `aas --help`
load (modules, not seconds: times are measured in benchmarks, never asserted)."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("sklearn", "scipy.signal", "scipy.optimize", "matplotlib", "pyaudio", "torch", "ray")


def _loaded(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"],
                         capture_output=True, text=True, check=True)
    return set(out.stdout.split())


@pytest.mark.parametrize("module", ["sensors", "aas_gym", "real"])
def test_import_loads_no_heavy_module(module):
    loaded = _loaded(f"import {module}")
    assert not [m for m in HEAVY if m in loaded]


def test_aas_help_loads_neither_the_sensor_stack_nor_mujoco():
    loaded = _loaded("import contextlib, io\nfrom aas_gym.cli import build_parser\n"
                     "with contextlib.redirect_stdout(io.StringIO()):\n    build_parser().format_help()")
    assert "sensors.synthesis" not in loaded and "pyaudio" not in loaded
    assert not [m for m in HEAVY if m in loaded]


def test_lazy_exports_resolve():
    import real
    import sensors

    assert sensors.SpectralFeatures.__module__ == "sensors.transformers"
    assert callable(sensors.calibrate) and real.PyAudioRig.__module__ == "real.rig"
    with pytest.raises(AttributeError):
        sensors.no_such_name  # noqa: B018
