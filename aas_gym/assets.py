"""Paths of the MJCF assets shipped at the repository root (``assets/``)."""

from __future__ import annotations

from pathlib import Path

#: ``assets/`` at the repository root (the package is installed editable from the repo).
ASSETS_DIR = Path(__file__).resolve().parent.parent / "assets"
#: The Franka hand with sensor housings on a floating Cartesian carriage.
HAND_XML = ASSETS_DIR / "franka_hand.xml"
#: Generated object MJCF files (a bar and a tube of every material), see ``aas_gym.scene.write_asset_files``.
OBJECTS_DIR = ASSETS_DIR / "objects"
#: Generated single- and multi-object scene MJCF files.
SCENES_DIR = ASSETS_DIR / "scenes"

