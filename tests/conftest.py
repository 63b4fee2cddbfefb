"""Test-suite wiring shared by every file."""

import os

# Headless rendering unless the caller chose a backend (must precede any mujoco import).
os.environ.setdefault("MUJOCO_GL", "egl")
