"""Stage 3, meshes: surface checks, tetrahedral meshes (structured for prisms, tubes and layered
everyday shapes; fTetWild for any other watertight surface), quadratic nodes, point location."""

from .meshing import MeshError, TetMesh, bar_mesh, quadratic_mesh, rod_mesh, tube_mesh

__all__ = ["MeshError", "TetMesh", "bar_mesh", "quadratic_mesh", "rod_mesh", "tube_mesh"]
