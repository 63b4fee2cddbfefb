"""Independent modal reference for the everyday objects: gmsh geometry and mesh, scikit-fem P2.

Nothing here comes from the project's meshers or FEM: the solid is rebuilt from its sizes
with gmsh's OpenCASCADE kernel (cylinders, boxes, a revolved profile), meshed by
gmsh with curved 10-node tets on the exact geometry, and K and M are assembled with
scikit-fem's own linear-elasticity and mass forms. Only the spoon (a mapped plate with no
CAD primitive) is rebuilt from a fine surface of the same shape and volume-meshed by gmsh.
"""

from __future__ import annotations

import math

import gmsh
import numpy as np
import scipy.sparse.linalg

from sensors.materials.solids import Material


def _occ_solid(obj, gmsh):
    """Build the object's solid in gmsh's OCC kernel; returns the volume tags."""
    occ = gmsh.model.occ
    d = obj.dimensions_m
    name = obj.name
    if name in ("can", "glass"):
        outer = occ.addCylinder(0, 0, 0, d["height_m"], 0, 0, d["outer_radius_m"])
        inner = occ.addCylinder(d["floor_m"], 0, 0, d["height_m"], 0, 0, d["inner_radius_m"])
        out, _ = occ.cut([(3, outer)], [(3, inner)])
    elif name == "bottle":
        prof = obj.inner_profile_m  # (x, r) of the inside, floor to rim
        wall = d["wall_m"]
        x_in, r_in = prof[1:, 0], prof[1:, 1]
        pts = [(0.0, 0.0), (0.0, r_in[0] + wall)]
        pts += [(x, r + wall) for x, r in zip(x_in, r_in)]
        pts += [(x, r) for x, r in zip(x_in[::-1], r_in[::-1])]
        pts += [(d["floor_m"], 0.0)]
        tags = [occ.addPoint(x, r, 0) for x, r in pts]
        lines = [occ.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
        face = occ.addPlaneSurface([occ.addCurveLoop(lines)])
        out = occ.revolve([(2, face)], 0, 0, 0, 1, 0, 0, 2 * math.pi)
        out = [e for e in out if e[0] == 3]
    elif name == "mug":
        h, ro, ri = d["height_m"], d["outer_radius_m"], d["inner_radius_m"]
        w, t, top, bottom = d["handle_width_m"], d["handle_thickness_m"], d["handle_top_m"], d["handle_bottom_m"]
        y_c = ro + d["handle_stub_m"]
        x_c, r_out = 0.5 * (top + bottom), 0.5 * (top - bottom)
        body = occ.addCylinder(0, 0, 0, h, 0, 0, ro)
        # D handle: two boxes from the axis out to y_c (the part inside the cup is wall or
        # hollow), joined by a half annulus (a z cylinder pair cut to y >= y_c).
        stubs = [occ.addBox(x0, 0, -w / 2, t, y_c, w) for x0 in (top - t, bottom)]
        ring = occ.addCylinder(x_c, y_c, -w / 2, 0, 0, w, r_out)
        hole = occ.addCylinder(x_c, y_c, -w / 2, 0, 0, w, r_out - t)
        ring, _ = occ.cut([(3, ring)], [(3, hole)])
        half = occ.addBox(x_c - 2 * r_out, y_c, -w, 4 * r_out, 2 * r_out, 2 * w)
        bend, _ = occ.intersect(ring, [(3, half)])
        fused, _ = occ.fuse([(3, body)], [(3, b) for b in stubs] + bend)
        hollow = occ.addCylinder(d["floor_m"], 0, 0, h + 0.01, 0, 0, ri)
        out, _ = occ.cut(fused, [(3, hollow)])
    elif name == "box":
        h, w, L, t = d["height_m"], d["width_m"], d["length_m"], d["wall_m"]
        outer = occ.addBox(0, -w / 2, -L / 2, h, w, L)
        inner = occ.addBox(t, -w / 2 + t, -L / 2 + t, h, w - 2 * t, L - 2 * t)
        out, _ = occ.cut([(3, outer)], [(3, inner)])
    elif name == "l_bracket":
        f, t, w = d["flange_m"], d["thickness_m"], d["width_m"]
        a = occ.addBox(-w / 2, 0, 0, w, f, t)
        b = occ.addBox(-w / 2, 0, 0, w, t, f)
        out, _ = occ.fuse([(3, a)], [(3, b)])
    else:
        return None
    occ.synchronize()
    return out


def gmsh_p2_mesh(obj, mesh_size_m: float, high_order_optimize: int = 1):
    """Curved 10-node tets of the object from gmsh: (corner nodes (n, 3), tets (m, 4), mid-node
    coordinates keyed by sorted corner pair). ``high_order_optimize`` is gmsh's
    Mesh.HighOrderOptimize (0 none, 1 optimization, 2 elastic + optimization, 4 fast curving); gmsh aborts the
    process when it fails, so callers that try several settings run it in a child process."""
    gmsh.initialize([], readConfigFiles=False, interruptible=False)  # not sys.argv: gmsh parses it
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(obj.name)
        exact = _occ_solid(obj, gmsh) is not None
        if not exact:  # spoon: volume-mesh a fine surface of the same shape
            import tempfile

            fine = obj.tet_mesh(resolution=3.0)
            from sensors.mesh.tets import boundary_faces
            import trimesh

            faces, _ = boundary_faces(fine.tets)
            with tempfile.TemporaryDirectory() as tmp:
                path = f"{tmp}/surface.stl"
                trimesh.Trimesh(fine.vertices_m, faces).export(path)
                gmsh.merge(path)
            gmsh.model.mesh.classifySurfaces(math.radians(40), True, False, math.pi)
            gmsh.model.mesh.createGeometry()
            surfaces = [s[1] for s in gmsh.model.getEntities(2)]
            gmsh.model.geo.addVolume([gmsh.model.geo.addSurfaceLoop(surfaces)])
            gmsh.model.geo.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size_m)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.25 * mesh_size_m)
        # Curvature sizing on a remeshed faceted surface (the spoon) sees every facet edge as
        # curvature: millions of elements, out of memory. There the size is the mesh size alone.
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 24 if exact else 0)
        gmsh.option.setNumber("Mesh.ElementOrder", 2)
        gmsh.option.setNumber("Mesh.HighOrderOptimize", high_order_optimize)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        xyz = np.zeros((int(tags.max()) + 1, 3))
        xyz[tags] = coords.reshape(-1, 3)
        _, node_tags = gmsh.model.mesh.getElementsByType(11)  # 10-node tetrahedra
    finally:
        gmsh.finalize()
    t10 = node_tags.reshape(-1, 10).astype(np.int64)
    corners = t10[:, :4]
    used, inverse = np.unique(corners, return_inverse=True)
    nodes = xyz[used]
    tets = inverse.reshape(-1, 4)
    # Which corner pair each higher-order node sits on (gmsh's order differs from VTK's):
    # find it geometrically on the first elements, then use it for all.
    pairs = [(i, j) for i in range(4) for j in range(i + 1, 4)]
    sample = xyz[t10[:50]]
    order = []
    for k in range(4, 10):
        dist = [np.linalg.norm(sample[:, k] - 0.5 * (sample[:, i] + sample[:, j]), axis=1).mean() for i, j in pairs]
        order.append(pairs[int(np.argmin(dist))])
    mids = {}
    for k, (i, j) in zip(range(4, 10), order):
        a, b = tets[:, i], tets[:, j]
        key = np.minimum(a, b) * len(nodes) + np.maximum(a, b)
        mids.update(zip(key.tolist(), xyz[t10[:, k]]))
    return nodes, tets, mids


def reference_frequencies_hz(obj, n_modes: int, mesh_size_m: float, material: Material | None = None,
                             high_order_optimize: int = 1):
    """The lowest ``n_modes`` elastic frequencies [Hz] from gmsh + scikit-fem P2, and the dof count."""
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, MeshTet2, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    material = material or obj.material
    nodes, tets, mids = gmsh_p2_mesh(obj, mesh_size_m, high_order_optimize)
    vol = np.einsum("ij,ij->i", nodes[tets[:, 1]] - nodes[tets[:, 0]],
                    np.cross(nodes[tets[:, 2]] - nodes[tets[:, 0]], nodes[tets[:, 3]] - nodes[tets[:, 0]]))
    neg = vol < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2], tets[neg, 1].copy()
    mesh = MeshTet2.from_mesh(MeshTet(nodes.T.copy(), tets.T.copy()))
    doflocs = mesh.doflocs.copy()
    nv = len(nodes)
    e = mesh.edges.astype(np.int64)
    key = np.minimum(e[0], e[1]) * nv + np.maximum(e[0], e[1])
    doflocs[:, nv:] = np.array([mids[k] for k in key.tolist()]).T
    mesh = MeshTet2(doflocs, mesh.t)
    basis = Basis(mesh, ElementVector(ElementTetP2()))
    E, nu, rho = material.youngs_modulus_pa, material.poisson_ratio, material.density_kg_m3
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    K = asm(linear_elasticity(lam, mu), basis)

    @BilinearForm
    def mass(u, v, w):
        return rho * dot(u, v)

    M = asm(mass, basis)
    sigma = -((2 * math.pi * 100.0) ** 2)
    # Shift-invert with K - sigma M (sigma < 0: positive definite) factorized on its symmetric
    # pattern (MMD on A + A^T, diagonal pivots), not eigsh's default SuperLU (COLAMD, partial
    # pivoting): the same operator, less fill. The can at 4 mm (58,152 dof): eigsh 18.5 against
    # 41.0 CPU s, frequencies equal to 1e-10 relative.
    A = (K - sigma * M).tocsc()
    lu = scipy.sparse.linalg.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    op_inv = scipy.sparse.linalg.LinearOperator(A.shape, matvec=lu.solve, dtype=A.dtype)
    vals = scipy.sparse.linalg.eigsh(K, k=n_modes + 6, M=M, sigma=sigma, which="LM", OPinv=op_inv,
                                     return_eigenvectors=False)
    vals = np.sort(vals)[6:]
    return np.sqrt(np.abs(vals)) / (2 * math.pi), int(K.shape[0])
