"""Test-suite wiring shared by every file."""

import os

# Headless rendering unless the caller chose a backend (must precede any mujoco import).
os.environ.setdefault("MUJOCO_GL", "egl")

# gmsh (the everyday objects' reference mesher) fails to initialize if CoACD's library was
# loaded first in the process; loading gmsh first makes both work in one test session.
try:
    import gmsh  # noqa: F401
except ImportError:  # the dev extra is not installed: the reference tests will say so
    pass
