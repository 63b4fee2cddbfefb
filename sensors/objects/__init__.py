"""Stage 7, objects: the catalog of everyday objects (structured meshes, containers)."""

from .everyday import EverydayObject, everyday_object

__all__ = ["EverydayObject", "everyday_object"]
