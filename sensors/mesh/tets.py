"""Linear tetrahedral meshes: the :class:`TetMesh` type, and what every tet mesh must satisfy.

Signed volumes and orientation, the quality check (no inverted, flat or disconnected tets), the
size guard (refuse, before building, a mesh whose P2 model would not fit in memory) and the
boundary triangles. The meshers (:mod:`.prisms`, :mod:`.layered`, :mod:`.tetwild`,
:mod:`.surface`) all return a :class:`TetMesh`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np

__all__ = [
    "MeshError",
    "TetMesh",
    "P2_EDGES",
    "DEFAULT_MAX_DOF",
    "P2_DOF_PER_VERTEX",
    "check_positive",
    "tet_volumes",
    "orient_tets",
    "check_tet_quality",
    "check_size",
    "row_codes",
    "boundary_faces",
]

#: Local vertex pairs of the six edges of a tetrahedron, in VTK quadratic-tetra order
#: (mid-edge node 4 + i sits on edge P2_EDGES[i]).
P2_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])


class MeshError(ValueError):
    """The input geometry or the tetrahedral mesh is unusable; the message says why."""


@dataclasses.dataclass
class TetMesh:
    """A linear tetrahedral mesh (corner vertices only) plus what P2 needs to curve it.

    Attributes:
        vertices_m: (n, 3) vertex coordinates [m].
        tets: (m, 4) vertex indices, positively oriented.
        kind: "bar", "tube", "rod" or "mesh".
        dimensions_m: Shape parameters (e.g. length_m, width_m, ...), empty for "mesh".
        cylinder_radii_m: Radii of exact cylindrical surfaces about the x axis; mid-edge nodes
            of edges lying on them are projected onto them by
            :func:`~sensors.mesh.quadratic.quadratic_mesh`.
        mirror_axes: Axes (0 x, 1 y, 2 z) whose coordinate planes through the origin mirror the
            mesh onto itself, vertices and tets (a mesher that builds it so says so); the modal
            build splits its eigenproblem by them (:mod:`sensors.fem.mirror`).
    """

    vertices_m: np.ndarray
    tets: np.ndarray
    kind: str = "mesh"
    dimensions_m: dict = dataclasses.field(default_factory=dict)
    cylinder_radii_m: tuple = ()
    mirror_axes: tuple = ()

    @property
    def n_tets(self) -> int:
        return int(self.tets.shape[0])

    def volume_m3(self) -> float:
        return float(tet_volumes(self.vertices_m, self.tets).sum())

    def digest(self) -> str:
        """Content hash of the geometry (for cache keys)."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices_m, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(self.tets, dtype=np.int64).tobytes())
        h.update(repr((self.kind, sorted(self.dimensions_m.items()), tuple(self.cylinder_radii_m))).encode())
        if self.mirror_axes:  # the modes are solved another way (meshes without it keep their keys)
            h.update(repr(("mirror_axes", tuple(self.mirror_axes))).encode())
        return h.hexdigest()


def check_positive(**values: float) -> None:
    """Raise :class:`MeshError` naming the first argument that is not a finite positive number."""
    for name, value in values.items():
        if isinstance(value, (bool, np.bool_)) or not (
                isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value) and value > 0):
            raise MeshError(f"{name} must be a finite positive number, got {value!r}")


def tet_volumes(vertices: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes of tetrahedra (positive for right-handed vertex order) [m^3]."""
    p = vertices[tets[:, :4]]
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0


def orient_tets(vertices: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Swap two vertices of every negatively oriented tet (fTetWild returns them that way)."""
    tets = np.array(tets, dtype=np.int64, copy=True)
    neg = tet_volumes(vertices, tets) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2], tets[neg, 1].copy()
    return tets


def check_tet_quality(vertices: np.ndarray, tets: np.ndarray, min_quality: float = 1e-6) -> None:
    """Raise :class:`MeshError` for non-finite vertices, inverted, degenerate or disconnected tets.

    Quality is the volume relative to that of a regular tet with the same RMS edge length
    (1 for a regular tet, 0 for a flat one); below ``min_quality`` a tet is called degenerate.
    """
    vertices = np.asarray(vertices, dtype=float)
    tets = np.asarray(tets)
    if tets.ndim != 2 or tets.shape[1] < 4 or len(tets) == 0:
        raise MeshError(f"tetrahedral mesh has no tets (tets array shape {tets.shape})")
    if not np.all(np.isfinite(vertices)):
        raise MeshError(f"tetrahedral mesh has {int((~np.isfinite(vertices)).any(axis=1).sum())} non-finite vertices")
    if tets.min() < 0 or tets.max() >= len(vertices):
        raise MeshError("tetrahedral mesh references vertices that do not exist")
    vol = tet_volumes(vertices, tets)
    p = vertices[tets[:, :4]]
    edges = p[:, P2_EDGES[:, 1]] - p[:, P2_EDGES[:, 0]]
    l_rms = np.sqrt(np.mean(np.einsum("ijk,ijk->ij", edges, edges), axis=1))
    quality = vol / (l_rms**3 / (6.0 * math.sqrt(2.0)))
    n_inv = int((quality < -min_quality).sum())
    n_flat = int((np.abs(quality) <= min_quality).sum())
    if n_inv or n_flat:
        raise MeshError(
            f"tetrahedral mesh has {n_inv} inverted and {n_flat} zero-volume tets out of {len(tets)} "
            f"(worst quality {quality.min():.3g})"
        )
    import scipy.sparse.csgraph  # ~0.2 s to import: only a model build needs it

    n = len(vertices)
    t = tets[:, :4]
    rows = np.repeat(t[:, 0], 3)
    cols = t[:, 1:].ravel()
    graph = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    used = np.unique(t)
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    n_comp_used = len(np.unique(labels[used]))
    if n_comp_used != 1:
        raise MeshError(
            f"tetrahedral mesh has {n_comp_used} disconnected parts; a modal model needs one solid "
            "(each extra part adds six rigid-body modes)"
        )


def row_codes(rows: np.ndarray) -> np.ndarray | None:
    """One int64 code per row of non-negative ints (equal rows, equal codes), or None if the
    codes would overflow. np.unique on the codes is several times faster than on rows."""
    rows = np.asarray(rows, dtype=np.int64)
    n = int(rows.max()) + 1 if rows.size else 1
    if rows.ndim != 2 or n ** rows.shape[1] >= 2**63:
        return None
    codes = np.zeros(len(rows), dtype=np.int64)
    for column in rows.T:
        codes = codes * n + column
    return codes


def boundary_faces(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles of a tet mesh, oriented outward, and the tet each belongs to.

    Returns (faces (f, 3), owner_tet (f,)).
    """
    t = np.asarray(tets)[:, :4]
    # Faces opposite to vertex 0..3, ordered so the normal points away from that vertex for a
    # positively oriented tet.
    local = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    faces = t[:, local].reshape(-1, 3)
    owner = np.repeat(np.arange(len(t)), 4)
    key = np.sort(faces, axis=1)
    codes = row_codes(key)
    _, inverse, counts = (np.unique(codes, return_inverse=True, return_counts=True) if codes is not None
                          else np.unique(key, axis=0, return_inverse=True, return_counts=True))
    single = counts[inverse.ravel()] == 1
    return faces[single], owner[single]


#: Default limit on the degrees of freedom of a P2 model (3 per node): about 1 GB for K and M
#: and several times that for the eigensolver, tens of minutes on two cores. ``max_dof=``
#: raises it (or ``None`` removes it).
DEFAULT_MAX_DOF = 300_000
#: P2 degrees of freedom per vertex of a linear tet mesh (a vertex has about six edges, each
#: carrying a mid-edge node: 3 (1 + 6) ~ 20; measured 18-22 on the project's meshes).
P2_DOF_PER_VERTEX = 20


def check_size(n_vertices: int, max_dof: int | None, what: str) -> None:
    """Refuse, before building it, a mesh whose P2 model would exceed ``max_dof``."""
    dof = P2_DOF_PER_VERTEX * int(n_vertices)
    if max_dof is not None and dof > max_dof:
        gb = dof * 90 * 2 * 12 / 1e9      # ~90 nonzeros per row of K and of M, 12 bytes each
        raise MeshError(f"{what} would have about {dof:,} degrees of freedom (limit {max_dof:,}; K and M "
                        f"alone ~{gb:.1f} GB, the eigensolver several times that): coarsen it with "
                        "element_size_m= or a smaller resolution=, or raise the limit with max_dof=")
