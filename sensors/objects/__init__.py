"""Stage 7, objects: the catalog of every object the project names (paper prisms, everyday
objects, users' meshes), its shape, material and modal model (:mod:`.catalog`)."""

from .catalog import ObjectSpec, get_object, known_material_names
from .everyday import EVERYDAY_OBJECTS, EverydayObject

__all__ = ["ObjectSpec", "get_object", "known_material_names", "EVERYDAY_OBJECTS", "EverydayObject"]
