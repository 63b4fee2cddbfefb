"""Stage 3, meshes: surface checks, tetrahedral meshes (structured for prisms, tubes and layered
everyday shapes; fTetWild for any other watertight surface), quadratic nodes, point location.

``tets`` (the mesh type, its checks and size guard), ``prisms`` (bar, tube, rod), ``quadratic``
(P2 nodes), ``intersections`` and ``tetwild`` (any watertight surface), ``surface`` (strict
checks of users' meshes), ``layered`` (everyday shapes), ``locator`` (point location).
"""

from .intersections import count_self_intersections
from .prisms import bar_mesh, extrude_to_tets, grid_triangles, rod_mesh, tube_mesh
from .quadratic import quadratic_mesh
from .tets import MeshError, TetMesh, boundary_faces, check_tet_quality, orient_tets
from .tetwild import tetrahedralize_surface, validate_surface

__all__ = ["count_self_intersections", "bar_mesh", "extrude_to_tets", "grid_triangles", "rod_mesh", "tube_mesh",
           "quadratic_mesh", "MeshError", "TetMesh", "boundary_faces", "check_tet_quality", "orient_tets",
           "tetrahedralize_surface", "validate_surface"]
