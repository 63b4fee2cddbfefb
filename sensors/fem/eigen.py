"""Generalized eigenproblem K u = lambda M u for the elastic modes of a free body.

* The six rigid-body modes are known in closed form; they are projected out of the
  shift-invert operator instead of being computed and thrown away, so a zero eigenvalue
  (which shift-invert near 0 resolves poorly) never has to be found.
* The shift sits inside the band, at half its top eigenvalue: the modes on both sides of it
  are extremes of the shifted-and-inverted spectrum, and the band's top, which converges
  slowest, is twice as far from the unwanted modes above the band in relative terms (ABS bar,
  46 modes: 132 solved vectors instead of 336 with a shift at zero). If that factorization
  fails or the iteration stagnates, the solve is repeated with a small negative shift (K - sigma M
  positive definite). Shifts are scaled to the problem: an SI problem has K/M ~ 1e12..1e14,
  where a shift of -1 vanishes in round-off and silently returns wrong modes.
* Every returned mode is Rayleigh-Ritz refined (exactly mass-orthonormal) and its residual
  ||K u - lambda M u|| / ||K u|| checked; the mode set is extended past the band limit
  until it does not cut a cluster of near-repeated eigenvalues (symmetric objects have
  pairs whose basis is arbitrary).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from .direct_solver import FactorizationError, default_solver, factorize

__all__ = ["EigenSolveError", "band_cut", "krylov_block", "rigid_body_modes", "solve_modes", "mode_residuals"]

log = logging.getLogger(__name__)

#: Below this many dofs a dense solve is both faster and more robust than ARPACK.
DENSE_MAX_DOF = 1200
# The shift-invert shift as a fraction of the band's top eigenvalue (2 pi f_max)^2, and the
# full Krylov block size (see _block_krylov); both measured on the default objects.
BAND_SHIFT = 0.5
FULL_BLOCK = 6
#: Krylov block for a sparse band: at most :data:`SPARSE_BAND_BELOW` modes below the shift (the
#: factorization's inertia says so before the iteration starts). A block of 6 costs PARDISO
#: about 2x a block of 3 per solve, while a band of a few modes converges in nearly as many
#: solves with either (mug, 6 modes below 10 kHz: 10 solves of 3 against 8 of 6; bottle 15 of 3
#: against 11 of 6); a dense band needs the wider block (box, 46 modes: 32 solves of 3 against
#: 20 of 6). A block of b vectors cannot separate more than b copies of a repeated eigenvalue,
#: so a cluster as large as the small block sends the solve back to the full one
#: (:func:`_hides_copies`).
SPARSE_BAND_BLOCK = 3
SPARSE_BAND_BELOW = 8
#: Ritz values this close (relative, eigenvalue) count as copies of one repeated eigenvalue.
REPEATED_RTOL = 1e-5


class EigenSolveError(RuntimeError):
    """The eigen-solve failed or produced modes that do not satisfy K u = lambda M u."""


def rigid_body_modes(nodes_m: np.ndarray, centre_m: np.ndarray | None = None) -> np.ndarray:
    """(3 n, 6) translations x, y, z and rotations about x, y, z (about ``centre_m``, by default
    the centroid)."""
    n = len(nodes_m)
    x, y, z = (nodes_m - (nodes_m.mean(axis=0) if centre_m is None else np.asarray(centre_m))).T
    R = np.zeros((3 * n, 6))
    for i in range(3):
        R[i::3, i] = 1.0
    R[1::3, 3], R[2::3, 3] = -z, y
    R[0::3, 4], R[2::3, 4] = z, -x
    R[0::3, 5], R[1::3, 5] = -y, x
    return R


def _m_orthonormalize(V: np.ndarray, M) -> np.ndarray:
    G = V.T @ (M @ V)
    L = np.linalg.cholesky(0.5 * (G + G.T))
    return np.linalg.solve(L, V.T).T


def mode_residuals(K, M, lambdas: np.ndarray, U: np.ndarray) -> np.ndarray:
    """Relative residual ||K u - lambda M u|| / ||K u|| of every column of U."""
    KU = K @ U
    return np.linalg.norm(KU - (M @ U) * lambdas, axis=0) / np.maximum(np.linalg.norm(KU, axis=0), 1e-300)


def band_cut(lam: np.ndarray, lam_max: float, cluster_rtol: float) -> int | None:
    """Number of modes to keep: all with lam <= lam_max plus the rest of a cluster at the cut.

    Returns None if the computed set ends inside the band or inside the cluster (need more).
    """
    n = int(np.searchsorted(lam, lam_max, side="right"))
    # Eigenvalue ratio tolerance is twice the frequency one.
    while n < len(lam) and n > 0 and lam[n] <= lam[n - 1] * (1.0 + 2.0 * cluster_rtol):
        n += 1
    if n >= len(lam):
        return None
    return n


#: A Ritz value that moved by more than this (relative) in the last basis step is not checked.
#: Ritz values converge about as the square of the residual (measured on the everyday objects:
#: every pair at residual <= 1e-6 had moved by < 1e-11, every one above 3e-4 by > 1e-8), so a
#: pair that still moves this much cannot pass ``residual_tol`` and its check would be wasted.
SETTLED_RTOL = 1e-8


def _settled(theta: np.ndarray, prev_theta: np.ndarray) -> np.ndarray:
    """Which Ritz values lie within :data:`SETTLED_RTOL` of one of the previous step's (the
    nearest one: a mode newly found below shifts the indices of those above)."""
    if len(prev_theta) == 0:
        return np.ones(len(theta), bool)
    i = np.searchsorted(prev_theta, theta)  # both ascending (eigh)
    above = prev_theta[np.minimum(i, len(prev_theta) - 1)]
    below = prev_theta[np.maximum(i - 1, 0)]
    nearest = np.minimum(np.abs(above - theta), np.abs(below - theta))
    return nearest <= SETTLED_RTOL * np.abs(theta)


def krylov_block(n_below: int | None) -> int:
    """Block size of the Krylov iteration given the elastic modes below the shift (None:
    unknown): the small block for a sparse band, else the full one."""
    return SPARSE_BAND_BLOCK if n_below is not None and n_below <= SPARSE_BAND_BELOW else FULL_BLOCK


def _hides_copies(lam: np.ndarray, block: int) -> bool:
    """Whether ``lam`` (ascending) holds a run of ``block`` or more copies of one eigenvalue
    (within :data:`REPEATED_RTOL`): a Krylov block of that size may have missed further copies."""
    run = 1
    for a, b in zip(lam[:-1], lam[1:]):
        run = run + 1 if b <= a + REPEATED_RTOL * abs(a) else 1
        if run >= block:
            return True
    return False


class _Stagnated(EigenSolveError):
    """The Krylov iteration stopped improving the residuals (try another shift)."""


def _block_krylov(K, M, op, lam_max, cluster_rtol, residual_tol, cap, say, block=FULL_BLOCK, shift=0.0,
                  n_below=None, mass=None):
    """Shift-invert block Krylov with full M-reorthogonalization and Rayleigh-Ritz.

    Small blocks of right-hand sides: a block of 6 costs SuperLU 1.3x more per vector than
    one of 24, but the Krylov space reaches a higher polynomial degree for the same number of
    vectors (ABS bar: 132 vectors instead of 240 at 12 and 336 at 24); a sparse band takes a
    block of 3 (:func:`krylov_block`). The basis B, M B and K B
    are kept (column-major: only the filled columns are ever touched), so neither the
    orthogonalization nor the Ritz residuals need a sparse product. ``op`` returns the solved
    block with its product with K (derived from the solve: see _shift_invert_modes), which
    follows it through the orthogonalization; each new block needs two products with M. The basis grows until the Ritz pairs of every mode up to the band limit
    (plus the cluster at the cut and one mode beyond) have converged, and as many of them lie
    below the shift as the factorization's inertia counts (``n_below``; Ritz values approach
    the eigenvalues from above, so a missing one shows as too few below the shift); residuals
    are computed for the pairs not yet converged whose Ritz value has settled (:func:`_settled`).
    """
    import scipy.linalg  # deferred as in solve_modes

    mass = mass or M.__matmul__  # X -> M X
    n = K.shape[0]
    rng = np.random.default_rng(12345)  # deterministic start -> reproducible mode bases
    max_basis = min(n - 6, cap + 4 * block, 3000, max(4 * block, int(6e7 / n)))  # B, M B, K B <= ~0.5 GB each
    B = np.empty((n, max_basis + block), order="F")
    MB = np.empty((n, max_basis + block), order="F")
    KB = np.empty((n, max_basis + block), order="F")
    stalls = 0
    max_stalls = max(3, 72 // block)  # no 10% progress over ~72 added vectors: round-off floor

    def orthonormalize(Y, KY, s):
        """Y M-orthonormalized against B[:, :s] and itself, with M Y and K Y (K Y follows Y
        through the same linear combinations: the basis's K B is kept)."""
        for _ in range(2):  # twice is enough (Kahan)
            if s:
                C = MB[:, :s].T @ Y
                Y = Y - B[:, :s] @ C
                KY = KY - KB[:, :s] @ C
        MY = mass(Y)
        G = Y.T @ MY
        w, Q = np.linalg.eigh(0.5 * (G + G.T))
        keep = w > 1e-12 * max(w.max(), 1e-300)  # drop directions the Krylov space already has
        T = Q[:, keep] / np.sqrt(w[keep])
        return Y @ T, MY @ T, KY @ T

    Y, MY, KY = orthonormalize(*op(mass(rng.standard_normal((n, block)))), 0)
    Y, MY, KY = orthonormalize(Y, KY, 0)
    s = Y.shape[1]
    B[:, :s], MB[:, :s], KB[:, :s] = Y, MY, KY
    Kr = Y.T @ KB[:, :s]
    last = slice(0, s)
    prev_count = -1
    converged = np.zeros(0, bool)
    prev_theta = np.zeros(0)
    while True:
        theta, Q = scipy.linalg.eigh(0.5 * (Kr + Kr.T))
        n_want = band_cut(theta, lam_max, cluster_rtol)
        # An empty band counts as settled only once the lowest Ritz value has: Ritz values approach
        # from above, so a mode just below the band limit shows only late (a square bar's first
        # bending pair cut by the band was returned as no mode at all).
        if (n_want is not None and n_want == prev_count and n_want < len(theta) - 1
                and (n_want > 0 or _settled(theta[:1], prev_theta).all())):
            # The band's mode count has settled: now pay for true residuals.
            if converged.size != n_want:
                converged = np.zeros(n_want, bool)
                best_res = np.full(n_want, np.inf)
            # True residuals cost two (n, s) x (s, k) products: only for pairs whose Ritz value
            # has settled (see _settled); the others are far from the tolerance.
            check = np.flatnonzero(~converged & _settled(theta[:n_want], prev_theta))
            KU = KB[:, :s] @ Q[:, check]
            res = (np.linalg.norm(KU - (MB[:, :s] @ Q[:, check]) * theta[check], axis=0)
                   / np.maximum(np.linalg.norm(KU, axis=0), 1e-300))
            converged[check] = res <= residual_tol
            if converged.all() and (n_below is None or np.count_nonzero(theta[:n_want + 1] < shift) >= n_below):
                return theta[: n_want + 1], B[:, :s] @ Q[:, : n_want + 1]
            # Stagnation: no checked pair improved on its own best residual by 10% (pairs join
            # the check as they settle, so the worst over the checked set is no measure).
            seen = np.isfinite(best_res[check])
            if seen.any():
                stalls = 0 if np.any(res[seen] <= 0.9 * best_res[check][seen]) else stalls + 1
                if stalls >= max_stalls:
                    raise _Stagnated(
                        f"eigen-solve stagnates at residual {float(res.max()):.3g} > {residual_tol:g} with {n_want} "
                        "modes in band (ill-conditioned problem, e.g. Poisson ratio near 0.5 or extremely thin "
                        "elements)")
            best_res[check] = np.minimum(best_res[check], res)
        prev_count = -1 if n_want is None else n_want
        prev_theta = theta
        if s >= max_basis:
            if n_want is None:
                raise EigenSolveError(f"more than {cap} modes below the band limit; raise max_modes or lower "
                                      "max_frequency_hz")
            return theta[: n_want + 1], B[:, :s] @ Q[:, : n_want + 1]
        say(f"eigensolve: basis {s}, {0 if n_want is None else n_want} modes in band")
        Y, MY, KY = orthonormalize(*op(MB[:, last]), s)
        if Y.shape[1] == 0:  # invariant subspace: the basis holds every mode it can
            return theta, B[:, :s] @ Q
        Y, MY, KY = Y[:, : max_basis + block - s], MY[:, : max_basis + block - s], KY[:, : max_basis + block - s]
        C = B[:, :s].T @ KY  # K symmetric: the lower block is C^T
        Kr = np.block([[Kr, C], [C.T, Y.T @ KY]])
        B[:, s:s + Y.shape[1]], MB[:, s:s + Y.shape[1]], KB[:, s:s + Y.shape[1]] = Y, MY, KY
        last = slice(s, s + Y.shape[1])
        s += Y.shape[1]


def _shift_invert_modes(K, M, R, lam_max, lam_scale, cluster_rtol, residual_tol, cap, say, solver, info,
                        factorize_shifted=None, mass=None):
    """Modes by shift-invert block Krylov: the shift inside the band first, then (if that
    factorization fails or the iteration stagnates) the safe negative shift.

    Returns (lambdas, U, shift, n_below): n_below is the number of elastic eigenvalues below
    the shift by the factorization's inertia (Sylvester), or None where it is not known.
    """
    safe = -min(max(1e-3 * lam_max, 1e-10 * lam_scale), 1e-3 * lam_scale)
    mass = mass or M.__matmul__  # X -> M X
    MR = M @ R
    KR = K @ R  # round-off only (rigid-body modes store no energy), kept so K Z stays exact
    failure = None
    solver = solver or default_solver()
    for sigma in (BAND_SHIFT * lam_max, safe):
        say(f"factorizing ({solver})")
        start = time.perf_counter()
        try:
            fact = factorize(K - sigma * M, solver) if factorize_shifted is None else factorize_shifted(sigma, solver)
        except FactorizationError as exc:
            failure = EigenSolveError(f"factorization of K - sigma M failed ({exc}); is the mesh valid?")
            continue
        info.update(solver=fact.name, factor_mb=fact.factor_mb, factor_s=time.perf_counter() - start, solves=0,
                    solved_vectors=0)
        # Below a positive shift lie the six rigid-body modes (eigenvalue 0) and the elastic ones.
        n_below = None if fact.n_negative is None else fact.n_negative - (len(R.T) if sigma > 0 else 0)

        def op(X, fact=fact, sigma=sigma):
            """(Z, K Z): Z = P (K - sigma M)^-1 X, P the M-orthogonal projection off the rigid-body
            modes. K Z = X + sigma M W - (K R) c with W the solve and c = (M R)^T W: one product
            with M (a third of K's entries) instead of one with K, exact where the solve is
            (``fact.exact_solves``); else the product with K."""
            info["solves"] += 1
            info["solved_vectors"] += X.shape[1]
            W = fact.solve(X)
            c = MR.T @ W
            Z = W - R @ c
            if not fact.exact_solves:  # the derived K Z is off by the solve's residual
                return Z, K @ Z
            return Z, X + sigma * mass(W) - KR @ c

        block = krylov_block(n_below)
        try:
            lam, U = _block_krylov(K, M, op, lam_max, cluster_rtol, residual_tol, cap, say, block=block,
                                   shift=sigma, n_below=n_below, mass=mass)
            if block < FULL_BLOCK and _hides_copies(lam, block):
                say("eigensolve: a repeated eigenvalue fills the block: again with the full block")
                block = FULL_BLOCK
                lam, U = _block_krylov(K, M, op, lam_max, cluster_rtol, residual_tol, cap, say, block=block,
                                       shift=sigma, n_below=n_below, mass=mass)
            info["block"] = block
            return lam, U, sigma, n_below
        except _Stagnated as exc:
            failure = exc
    raise failure


def solve_modes(K, M, nodes_m: np.ndarray, max_frequency_hz: float, *, cluster_rtol: float = 2e-3,
                residual_tol: float = 1e-6, max_modes: int | None = None, progress=None, solver: str | None = None,
                info: dict | None = None, factorize_shifted=None, mass_product=None,
                rigid_modes: np.ndarray | None = None):
    """Elastic modes of a free body with frequency up to ``max_frequency_hz``.

    Args:
        K, M: Sparse stiffness and mass (3 n_nodes square, node-major dofs).
        nodes_m: (n_nodes, 3) node coordinates (for the rigid-body modes), or None with
            ``rigid_modes``.
        max_frequency_hz: Band limit; the set may extend past it to complete a cluster.
        cluster_rtol: Modes whose frequencies differ by less than this (relative) count as one
            cluster, which is never cut.
        residual_tol: Largest accepted ||K u - lambda M u|| / ||K u||.
        max_modes: Safety cap on the number of modes (default: no cap below the dof count).
        progress: Optional callable(str) for status messages.
        solver: Sparse direct solver of the shift-invert, ``"pardiso"`` or ``"superlu"``
            (default :func:`sensors.fem.direct_solver.default_solver`); both give the same modes.
        info: Optional dict that receives how the modes were solved: ``solver`` (``"dense"``
            below :data:`DENSE_MAX_DOF`), ``factor_mb`` (memory of the factorization), and for
            shift-invert ``factor_s`` (wall time of the factorization), ``block`` (Krylov block
            size), ``solves`` and ``solved_vectors`` (block solves and their columns).
        factorize_shifted: Optional callable ``(sigma, solver)`` returning the factorization of
            K - sigma M, the same as ``direct_solver.factorize(K - sigma * M, solver)`` (e.g.
            :meth:`sensors.fem.assembly.NodeBlocks.factorize_shifted`, from the node blocks).
        mass_product: Optional callable ``X -> M @ X``, bit for bit the same, for the Krylov
            iteration's products (e.g. :meth:`sensors.fem.assembly.NodeBlocks.mass_product`).
        rigid_modes: (n_dof, r) the zero-energy modes to project out instead of the six of
            ``nodes_m`` (a symmetry class's share of them, :mod:`sensors.fem.mirror`).

    Returns:
        (lambdas (r,) ascending [rad^2/s^2], U (3 n_nodes, r) with U^T M U = I).

    Raises:
        EigenSolveError: spurious zero-energy modes, failed convergence, or residuals above
            ``residual_tol``.
    """
    # scipy.linalg and scipy.sparse.linalg cost ~0.4 s to import: only a model build needs them
    import scipy.linalg
    import scipy.sparse

    if not (math.isfinite(max_frequency_hz) and max_frequency_hz > 0):
        raise ValueError(f"max_frequency_hz must be a positive number, got {max_frequency_hz!r}")
    K = scipy.sparse.csr_matrix(K)
    M = scipy.sparse.csr_matrix(M)
    n_dof = K.shape[0]
    if not (np.all(np.isfinite(K.data)) and np.all(np.isfinite(M.data))):
        raise EigenSolveError("stiffness or mass matrix has non-finite entries")
    lam_max = (2.0 * math.pi * max_frequency_hz) ** 2
    d_k, d_m = K.diagonal(), M.diagonal()
    if np.any(d_m <= 0) or np.any(d_k <= 0):
        raise EigenSolveError("stiffness or mass matrix has non-positive diagonal entries (unused nodes?)")
    lam_scale = float(np.median(d_k / d_m))  # ~ (highest mesh frequency)^2
    R = _m_orthonormalize(rigid_body_modes(nodes_m) if rigid_modes is None else np.asarray(rigid_modes, float), M)
    n_elastic = n_dof - R.shape[1]
    cap = n_elastic if max_modes is None else min(max_modes, n_elastic)
    say = progress or (lambda msg: None)
    info = {} if info is None else info

    if n_dof <= DENSE_MAX_DOF:
        say("dense eigensolve")
        info.update(solver="dense")
        MR = M @ R
        lift = 10.0 * lam_scale  # move the rigid modes far above the band
        Kd = K.toarray() + lift * (MR @ MR.T)
        lam, U = scipy.linalg.eigh(Kd, M.toarray())
        keep = np.abs(lam - lift) > 1e-6 * lift
        lam, U = lam[keep], U[:, keep]
        n_below = None  # every eigenvalue computed: nothing to count
    else:
        lam, U, shift, n_below = _shift_invert_modes(K, M, R, lam_max, lam_scale, cluster_rtol, residual_tol, cap,
                                                     say, solver, info, factorize_shifted, mass_product)

    if len(lam) and lam[0] <= 1e-9 * lam_scale:
        raise EigenSolveError(
            f"found a zero-energy elastic mode (lambda = {lam[0]:.3g}, scale {lam_scale:.3g}): the mesh has a "
            "mechanism or a disconnected part"
        )
    if n_below is not None:
        found = int(np.count_nonzero(lam < shift))
        if found != n_below:
            raise EigenSolveError(f"the factorization counts {n_below} modes below the shift "
                                  f"{math.sqrt(max(shift, 0)) / (2 * math.pi):.4g} Hz, the eigen-solve found {found}")
    n = band_cut(lam, lam_max, cluster_rtol)
    if n is None:
        n = len(lam)
        if n < cap:
            raise EigenSolveError(f"could not compute all modes below {max_frequency_hz} Hz (got {n}); "
                                  "raise max_modes or lower max_frequency_hz")
    lam, U = lam[:n], U[:, :n]
    res = mode_residuals(K, M, lam, U)
    bad = np.flatnonzero(~(res <= residual_tol))
    if len(bad):
        raise EigenSolveError(
            f"{len(bad)} of {n} modes fail the residual check ||K u - lambda M u|| / ||K u|| <= {residual_tol:g} "
            f"(worst {np.nanmax(res):.3g} at {math.sqrt(max(lam[bad[0]], 0)) / (2 * math.pi):.4g} Hz)"
        )
    if not np.all(np.isfinite(U)):
        raise EigenSolveError("eigenvectors contain non-finite values")
    return lam, U
