"""Test-suite wiring shared by every file."""

import os

import pytest

# Headless rendering unless the caller chose a backend (must precede any mujoco import).
os.environ.setdefault("MUJOCO_GL", "egl")


def pytest_collection_modifyitems(config, items):
    """Under ``pytest-xdist --dist loadgroup``, keep each file on one worker (its module
    fixtures are built once) unless a test names a group itself: the audio tests of several
    files share one ``real_audio`` group because they restart the same sound server."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(name=item.nodeid.split("::")[0]))
