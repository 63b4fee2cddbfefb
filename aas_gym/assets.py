"""Paths of the MJCF assets shipped at the repository root (``assets/``)."""

from __future__ import annotations

from pathlib import Path

#: ``assets/`` at the repository root (the package is installed editable from the repo).
ASSETS_DIR = Path(__file__).resolve().parent.parent / "assets"
#: The Franka hand with sensor housings on a floating Cartesian carriage.
HAND_XML = ASSETS_DIR / "franka_hand.xml"
#: Generated object MJCF files (one per default object), see ``aas_gym.scene.write_asset_files``.
OBJECTS_DIR = ASSETS_DIR / "objects"
#: Generated single- and multi-object scene MJCF files.
SCENES_DIR = ASSETS_DIR / "scenes"


def asset_path(name: str) -> Path:
    """Absolute path of ``assets/<name>``; raises ``FileNotFoundError`` with the folder listed."""
    path = ASSETS_DIR / name
    if not path.exists():
        known = sorted(str(p.relative_to(ASSETS_DIR)) for p in ASSETS_DIR.rglob("*.xml"))
        raise FileNotFoundError(f"no asset {name!r} in {ASSETS_DIR}; known MJCF files: {known}")
    return path
