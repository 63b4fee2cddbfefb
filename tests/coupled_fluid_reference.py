"""Independent reference for the everyday mug's wet modes (tests/test_fluid_coupled.py,
benchmarks/fluid_coupled.py): a fully coupled structure-liquid FEM solve, written with
scikit-fem independently of ``sensors.fluid`` (no modal reduction, no static correction, no
project liquid mesh or quadrature):

* Wall: the mug's own tet mesh at a given resolution (the one its dry model at that
  resolution is built on, its P2 nodes curved onto the wall's cylinders likewise), quadratic
  P2 displacement u, stiffness K and mass M from scikit-fem's linear-elasticity and mass forms.
* Liquid: a structured cylinder of its own (``rod_mesh``, the inner radius, floor to the fill
  height), P2 displacement potential psi (liquid displacement grad psi, pressure
  p = rho w^2 psi), mid-edge nodes on the exact cylinder, psi = 0 on the free surface.
* Coupling on the wetted wall and floor: C[u, psi] = integral (u . n) psi dS, with the wall's
  P2 basis functions evaluated at the liquid's facet quadrature points (the two meshes do not
  match there; the points are moved 0.2 mm into the wall and located in its curved elements).

The compressible liquid (``compressible_coupled_frequencies_hz``) is the same FEM with the
liquid's mass matrix over c^2 added, solved as an unsymmetric pencil by shift-invert Arnoldi.

The coupled eigenproblem (Morand & Ohayon, Fluid-Structure Interaction, Wiley 1995, ch. 5,
incompressible liquid) K u = w^2 (M u + rho C psi), H psi = C^T u is solved in full, as
K u = w^2 M_tot u with M_tot = M + rho C H^-1 C^T applied exactly (a sparse factorization of H
per fill): block Krylov vectors of (K - s M)^-1 M_tot (one factorization of the wall for all
fills, a tiny shift s; the free mug's six rigid-body modes are kept exact and M_tot-orthogonal
to the rest) with Rayleigh-Ritz on the exact K and M_tot, until the Ritz values stop moving
(1e-9) with residuals ||K u - w^2 M_tot u|| / ||K u|| small. The operator only steers the
search space; Rayleigh-Ritz on the full matrices makes the frequencies the coupled model's.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from sensors.mesh.prisms import rod_mesh

RHO_WATER = 998.2
PROBE_DEPTH_M = 2e-4  # liquid quadrature points moved this far into the wall
LIQUID_ELEMENT_M = 0.005
#: The compressible reference's shift-invert operator from a symmetric-mode factorization of the
#: symmetrized pencil (True) or a partial-pivoting LU of A - s B (False). Read at each call.
SYMMETRIC_LU = True


def splu(A):
    return scipy.sparse.linalg.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                    options={"SymmetricMode": True})


def wall_fem(mug, resolution=1.0):
    """scikit-fem P2 elasticity on the mug's tet mesh: K, M, rigid-body modes, a factorization
    of K - s M, and the scalar basis for probes, on the mug's tet mesh at ``resolution`` (the
    mesh its dry model at that resolution is built on)."""
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    tm = mug.tet_mesh(resolution)
    d = mug.dimensions_m
    mesh = curved_p2_mesh(tm.vertices_m, tm.tets, (d["inner_radius_m"], d["outer_radius_m"]))
    mat = mug.material
    ub = Basis(mesh, ElementVector(ElementTetP2()))
    K = asm(linear_elasticity(mat.lame_lambda_pa, mat.shear_modulus_pa), ub).tocsc()

    @BilinearForm
    def mass(u, v, w):
        return mat.density_kg_m3 * dot(u, v)

    M = asm(mass, ub).tocsc()
    scalar = Basis(mesh, ElementTetP2())
    # Points are located in the straight-sided twin of the mesh (the same elements; skfem's own
    # search inverts every curved element for every point at once, 24 GB here), then mapped
    # into their element's curved geometry (wall_probes).
    straight = MeshTet(tm.vertices_m.T.copy(), tm.tets.T.copy())
    assert np.array_equal(straight.t, mesh.t)
    x = scalar.doflocs.T - scalar.doflocs.mean(axis=1)  # vector dof 3 a + c at scalar dof a
    R = np.zeros((3 * len(x), 6))
    for c in range(3):
        R[c::3, c] = 1.0
    R[1::3, 3], R[2::3, 3] = -x[:, 2], x[:, 1]
    R[0::3, 4], R[2::3, 4] = x[:, 2], -x[:, 0]
    R[0::3, 5], R[1::3, 5] = -x[:, 1], x[:, 0]
    lu = splu(K + (2 * math.pi * 10.0) ** 2 * M)
    return {"mesh": mesh, "K": K, "M": M, "R": R, "lu": lu, "scalar": scalar, "straight": straight}


def wall_probes(wall, x):
    """Sparse (points, wall scalar P2 dofs) matrix of the wall's scalar basis at points ``x``
    (3, n) inside the wall. Each point's element is found in the straight-sided twin and the
    point mapped into that element's curved geometry (Newton); near a curved face the twin may
    name the neighbour, whose P2 field, continuous with it, is then extrapolated by less than
    the face's sagitta (an error of second order in it)."""
    scalar = wall["scalar"]
    cells = wall["straight"].element_finder()(*x)
    # Newton on the curved map from the point's straight-element coordinates (skfem's invF
    # clips to the reference element, so it cannot extrapolate).
    xq = x[:, :, None]
    ref = wall["straight"].mapping().invF(xq, tind=cells)
    for _ in range(20):
        step = np.einsum("ijkl,jkl->ikl", scalar.mapping.invDF(ref, tind=cells), xq - scalar.mapping.F(ref, tind=cells))
        ref = ref + step
        if np.abs(step).max() < 1e-12:
            break
    else:
        raise AssertionError(f"curved wall map not inverted: last step {np.abs(step).max():.1e}")
    phis = np.array([scalar.elem.gbasis(scalar.mapping, ref, k, tind=cells)[0] for k in range(scalar.Nbfun)])
    n = x.shape[1]
    rows = np.tile(np.arange(n), scalar.Nbfun)
    cols = scalar.element_dofs[:, cells].ravel()
    return scipy.sparse.csr_matrix((phis.reshape(scalar.Nbfun, n).ravel(), (rows, cols)), shape=(n, scalar.N))


def curved_p2_mesh(vertices_m, tets, radii_m):
    """skfem's P2 mesh of a tet mesh, the mid-edge nodes of edges on a cylinder about x (one of
    ``radii_m``) moved radially onto it."""
    from skfem import MeshTet, MeshTet2

    m2 = MeshTet2.from_mesh(MeshTet(vertices_m.T.copy(), tets.T.copy()))
    doflocs = m2.doflocs.copy()
    nv = len(vertices_m)
    r_v = np.hypot(vertices_m[:, 1], vertices_m[:, 2])
    mid = doflocs[:, nv:]
    for radius in radii_m:
        on = np.abs(r_v - radius) < 1e-9 * radius
        both = on[m2.edges[0]] & on[m2.edges[1]]
        mid[1:, both] *= radius / np.hypot(mid[1, both], mid[2, both])
    doflocs[:, nv:] = mid
    return MeshTet2(doflocs, m2.t)


def liquid_mesh(mug, height_m, element_m=LIQUID_ELEMENT_M):
    """P2 mesh of the liquid cylinder (floor to ``height_m`` above it), curved onto the wall."""
    d = mug.dimensions_m
    ri, floor = d["inner_radius_m"], d["floor_m"]
    rod = rod_mesh(height_m, ri, element_size_m=element_m)
    v = rod.vertices_m.copy()
    v[:, 0] += floor - v[:, 0].min()  # rod_mesh starts at x = 0
    return curved_p2_mesh(v, rod.tets, (ri,)), floor + height_m


def liquid_fem(mug, wall, height_m, liquid_element_m=LIQUID_ELEMENT_M):
    """The liquid's P2 matrices on its free dofs (psi = 0 on the free surface): coupling C
    (wall dofs, liquid dofs), Laplacian H and mass matrix Q0 (integral psi_a psi_b dV)."""
    from skfem import Basis, BilinearForm, ElementTetP2, FacetBasis, asm
    from skfem.helpers import dot, grad

    mesh, top = liquid_mesh(mug, height_m, liquid_element_m)
    pb = Basis(mesh, ElementTetP2())

    @BilinearForm
    def laplace(u, v, w):
        return dot(grad(u), grad(v))

    @BilinearForm
    def mass(u, v, w):
        return u * v

    H = asm(laplace, pb)
    Q0 = asm(mass, pb)
    boundary = mesh.boundary_facets()
    on_top = np.all(np.abs(mesh.p[0, mesh.facets[:, boundary]] - top) < 1e-9, axis=0)
    free, wet = boundary[on_top], boundary[~on_top]
    fb = FacetBasis(mesh, ElementTetP2(), facets=wet)
    x = np.asarray(fb.global_coordinates())  # (3, f, q)
    n = np.asarray(fb.normals)  # (3, f, q), out of the liquid
    dS = fb.dx  # (f, q)
    # Probe points just inside the wall: radially out on the side wall, down on the floor.
    d = mug.dimensions_m
    r = np.hypot(x[1], x[2])
    on_floor = np.abs(x[0] - d["floor_m"]) < 1e-9
    probe = x.copy()
    probe[1:] *= np.where(on_floor, 1.0, (r + PROBE_DEPTH_M) / np.where(r > 0, r, 1.0))[None]
    probe[0] -= np.where(on_floor, PROBE_DEPTH_M, 0.0)
    P = wall_probes(wall, probe.reshape(3, -1))  # (points, wall scalar dofs)
    # Liquid basis values at the same points: (local dof, f, q) with global dofs (local dof, f).
    psi_vals = np.stack([np.asarray(fb.basis[i][0]) for i in range(fb.Nbfun)])
    psi_dofs = fb.element_dofs
    n_pts = P.shape[0]
    point = np.arange(n_pts).reshape(x.shape[1:])
    W = scipy.sparse.csr_matrix((psi_vals.ravel(), (np.broadcast_to(point, psi_vals.shape).ravel(),
                                                    np.broadcast_to(psi_dofs[:, :, None], psi_vals.shape).ravel())),
                                shape=(n_pts, pb.N))
    blocks = []
    for c in range(3):
        weight = scipy.sparse.diags((n[c] * dS).ravel())
        blocks.append((P.T @ weight @ W).tocoo())  # (wall scalar dofs, psi dofs)
    rows = np.concatenate([3 * b.row + c for c, b in enumerate(blocks)])
    cols = np.concatenate([b.col for b in blocks])
    vals = np.concatenate([b.data for b in blocks])
    C = scipy.sparse.csc_matrix((vals, (rows, cols)), shape=(wall["K"].shape[0], pb.N))
    dirichlet = np.unique(pb.get_dofs(facets=free).all())
    keep = np.setdiff1d(np.arange(pb.N), dirichlet)
    return C[:, keep].tocsc(), H[keep][:, keep].tocsc(), Q0[keep][:, keep].tocsc()


def coupled_frequencies_hz(mug, wall, height_m, rho, n_modes, liquid_element_m=LIQUID_ELEMENT_M):
    """The lowest ``n_modes`` elastic frequencies (Hz) of the mug's wall (``wall_fem``) coupled
    to ``height_m`` of incompressible liquid of density ``rho`` (kg/m^3), the liquid meshed at
    ``liquid_element_m``."""
    C, H, _ = liquid_fem(mug, wall, height_m, liquid_element_m)
    Hlu = splu(H)
    return eigen_block_krylov(wall, lambda X: wall["M"] @ X + rho * (C @ Hlu.solve(np.asarray(C.T @ X))), n_modes)


def compressible_coupled_frequencies_hz(mug, wall, height_m, rho, speed_of_sound_m_per_s, up_to_hz,
                                        liquid_element_m=LIQUID_ELEMENT_M, shift_hz=200.0):
    """Every elastic frequency (Hz) up to ``up_to_hz`` of the wall coupled to ``height_m`` of a
    compressible liquid (density ``rho``, speed of sound c), and the next one above, solved in
    full: the unsymmetric pencil

        [K  0; -C^T  H] [u; psi] = w^2 [M  rho C; 0  Q0 / c^2] [u; psi]

    (wall: K u = w^2 (M u + rho C psi), pressure p = rho w^2 psi; liquid: Helmholtz'
    equation H psi - (w / c)^2 Q0 psi = C^T u with psi = 0 on the free surface) by shift-invert
    Arnoldi on all its dofs (one sparse LU of A - s B at a small shift s), no modal reduction.
    The six rigid-body modes (w = 0) are dropped."""
    C, H, Q0 = liquid_fem(mug, wall, height_m, liquid_element_m)
    K, M = wall["K"], wall["M"]
    n_u, n_p = K.shape[0], H.shape[0]
    # Balanced: psi = alpha psi' puts rho C beside M, the liquid's rows times gamma put H beside
    # K. Unbalanced (entries 1e11 apart) the LU and Arnoldi return pressure-only vectors that
    # violate the liquid's equation, with complex "eigenvalues".
    alpha = abs(M).max() / (rho * abs(C).max())
    gamma = abs(K).max() / (alpha * abs(H).max())
    A = scipy.sparse.bmat([[K, None], [-gamma * C.T, gamma * alpha * H]], format="csc")
    B = scipy.sparse.bmat([[M, rho * alpha * C], [None, gamma * alpha / speed_of_sound_m_per_s**2 * Q0]],
                          format="csc")
    s = (2 * math.pi * shift_hz) ** 2
    if SYMMETRIC_LU:
        # The liquid's rows of A - s B times s rho alpha / gamma make it symmetric (-s rho alpha C
        # above, its transpose below; the liquid's block s rho alpha^2 (H - s Q0 / c^2)): one
        # symmetric-mode factorization, no pivoting, on MMD of its pattern; (A - s B)^-1 = S^-1 D.
        # Only the shift-invert operator changes (it steers Arnoldi); the residual checks below
        # are on A and B themselves.
        d = np.ones(n_u + n_p)
        d[n_u:] = s * rho * alpha / gamma
        lu = splu(scipy.sparse.diags(d) @ (A - s * B))
        op = scipy.sparse.linalg.LinearOperator((n_u + n_p,) * 2, matvec=lambda x: lu.solve(d * (B @ x)),
                                                dtype=np.float64)
    else:
        # A - s B is structurally symmetric (C beside C^T): ordering on A + A^T's pattern fills less
        # than SuperLU's default COLAMD (full cup: 59 against 88 million LU entries, 53 against 63
        # CPU s); partial pivoting.
        lu = scipy.sparse.linalg.splu((A - s * B).tocsc(), permc_spec="MMD_AT_PLUS_A")
        op = scipy.sparse.linalg.LinearOperator((n_u + n_p,) * 2, matvec=lambda x: lu.solve(B @ x),
                                                dtype=np.float64)
    limit = (2 * math.pi * up_to_hz) ** 2
    k = 24
    while True:
        nu, X = scipy.sparse.linalg.eigs(op, k=k, which="LM", tol=1e-12, v0=np.ones(n_u + n_p))
        lam = s + 1.0 / nu
        order = np.argsort(lam.real)
        lam, X = lam[order], X[:, order]
        if lam[-1].real > limit:
            break
        k += 16
    assert np.all(np.abs(lam.real[:6]) < 1e-4 * limit), f"the six rigid-body modes are not at zero: {lam[:6]}"
    lam, X = lam[6:], X[:, 6:]
    assert np.all(np.abs(lam.imag) <= 1e-8 * lam.real), f"complex coupled modes: {lam}"
    u, psi = X[:n_u], alpha * X[n_u:]
    wall_res = np.linalg.norm(K @ u - (M @ u + rho * (C @ psi)) * lam, axis=0) / np.linalg.norm(K @ u, axis=0)
    liquid_res = (np.linalg.norm(H @ psi - C.T @ u - (Q0 @ psi) * (lam / speed_of_sound_m_per_s**2), axis=0)
                  / np.linalg.norm(H @ psi, axis=0))
    assert max(wall_res.max(), liquid_res.max()) < 1e-6, f"residuals {wall_res}, {liquid_res}"
    lam = lam.real
    n = int(np.searchsorted(lam, limit, side="right"))
    return np.sqrt(lam[: n + 1]) / (2 * math.pi)


def eigen_block_krylov(wall, mtot, n_modes, block=24, rtol=1e-9, residual_tol=1e-4, max_blocks=12):
    """Lowest ``n_modes`` elastic eigenpairs of K u = w^2 M_tot u (M_tot given as an operator).

    Converged when no wanted Ritz value moves by more than ``rtol`` (relative) when a block is
    added and every residual ||K u - w^2 M_tot u|| / ||K u|| is below ``residual_tol`` (the
    residuals stall near 1e-6 in floating point; Ritz values are then accurate to ~ their
    square over the gap)."""
    K, R, lu = wall["K"], wall["R"], wall["lu"]
    MR = mtot(R)
    G = R.T @ MR
    V, MV = np.zeros((K.shape[0], 0)), np.zeros((K.shape[0], 0))

    def orthonormal(X):
        """X made M_tot-orthonormal and M_tot-orthogonal to R and V; returns (X, M_tot X)."""
        MX = mtot(X)
        for _ in range(2):  # twice is enough (Kahan)
            c = np.linalg.solve(G, MR.T @ X)
            X, MX = X - R @ c, MX - MR @ c
            d = V.T @ MX
            X, MX = X - V @ d, MX - MV @ d
        w, Q = np.linalg.eigh(0.5 * (X.T @ MX + MX.T @ X))
        keep = w > 1e-12 * w.max()
        scale = Q[:, keep] / np.sqrt(w[keep])
        return X @ scale, MX @ scale

    rng = np.random.default_rng(0)
    X, MX = orthonormal(lu.solve(mtot(rng.standard_normal((K.shape[0], block)))))
    previous = None
    for _ in range(max_blocks):
        V, MV = np.concatenate([V, X], axis=1), np.concatenate([MV, MX], axis=1)
        Kr = V.T @ (K @ V)
        lam, Q = np.linalg.eigh(0.5 * (Kr + Kr.T))
        lam = lam[:n_modes]
        if previous is not None and np.max(np.abs(lam / previous - 1)) < rtol:
            U = V @ Q[:, :n_modes]
            KU = K @ U
            res = np.linalg.norm(KU - (MV @ Q[:, :n_modes]) * lam, axis=0) / np.linalg.norm(KU, axis=0)
            assert res.max() < residual_tol, f"coupled modes converged to wrong pairs: residuals {res}"
            return np.sqrt(lam) / (2 * math.pi)
        previous = lam
        X, MX = orthonormal(lu.solve(MX))
    raise AssertionError(f"coupled eigen-solve did not converge in {V.shape[1]} vectors")
