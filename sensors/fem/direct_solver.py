"""The sparse direct solver behind shift-invert: factorizations of K - sigma M and the choice
between them.

Two paths give the same modes (to the eigen-solve's residual tolerance):

* ``"pardiso"``: Intel MKL PARDISO, symmetric indefinite LDL^T with a METIS nested-dissection
  ordering (:mod:`sensors.fem.pardiso`; needs the ``mkl`` wheel, x86-64 only). The default
  where MKL is installed: on the project's K - sigma M (one thread) it factorizes 2.3-5x faster
  than SuperLU at 11-48k dof and 11x at 143k, holding a fifth of the memory; SuperLU in a METIS
  order, CHOLMOD's LDL^T and MUMPS gained at most 2.2x (docs/benchmarks/modal_accuracy.md).
* ``"superlu"``: SciPy's SuperLU with a minimum-degree ordering, pivots kept on the diagonal
  (the matrix is symmetric and the shift makes it well conditioned); works everywhere.

``$AAS_GYM_SOLVER`` (``pardiso`` or ``superlu``) overrides the choice for the whole process.
Both report the inertia of K - sigma M (how many of its eigenvalues are negative), which by
Sylvester's law counts the generalized eigenvalues below sigma: the eigen-solve checks that it
found every one of them.
"""

from __future__ import annotations

import logging
import os
import threading

import numpy as np

__all__ = ["SOLVERS", "SOLVER_ENV", "FactorizationError", "analyze_pattern", "available_solvers", "default_solver",
           "factorize", "preload_in_background"]

log = logging.getLogger(__name__)

SOLVERS = ("pardiso", "superlu")
SOLVER_ENV = "AAS_GYM_SOLVER"
FAST_PATH_HINT = "pip install mkl (x86-64), or `python3 tasks.py setup`"
#: Whether the one line about the fast path was logged in this process.
HINT_SHOWN: list = []


class FactorizationError(RuntimeError):
    """The factorization of K - sigma M failed (singular, out of memory, or solver unusable)."""


def available_solvers() -> tuple[str, ...]:
    """The solvers this machine can run, fastest first."""
    from .pardiso import mkl_library

    return SOLVERS if mkl_library() is not None else ("superlu",)


def default_solver() -> str:
    """``$AAS_GYM_SOLVER`` if set, else PARDISO where MKL is installed, else SuperLU (saying once,
    in one log line, how to get the fast path)."""
    forced = os.environ.get(SOLVER_ENV, "").strip().lower()
    if forced:
        if forced not in SOLVERS:
            raise ValueError(f"${SOLVER_ENV} must be one of {SOLVERS}, got {forced!r}")
        return forced
    if "pardiso" in available_solvers():
        return "pardiso"
    if not HINT_SHOWN:
        HINT_SHOWN.append(True)
        log.warning("sparse solver: SciPy SuperLU (big models build several times slower); fast path: %s",
                    FAST_PATH_HINT)
    return "superlu"


class SuperLUFactorization:
    """SciPy SuperLU of a symmetric matrix with diagonal pivots (L D L^T in LU form).

    Attributes:
        n_negative: Negative pivots, which with diagonal pivoting is the matrix's inertia.
    """

    name = "superlu"
    #: Without pivoting (the inertia needs diagonal pivots) an indefinite K - sigma M loses
    #: digits in the solve: the spoon's residuals are 2e-10 of the right-hand side (PARDISO's
    #: 4e-12), and K Z derived from such solves left 2 of its 15 modes at 1.1e-6 > 1e-6 in the
    #: eigen-solve's final check. The eigen-solve forms K Z by a product with K instead.
    exact_solves = False

    def __init__(self, A):
        import scipy.sparse.linalg

        if isinstance(A, scipy.sparse.bsr_matrix):
            # Node blocks (fem.assembly.NodeBlocks.shifted): the entries a CSR difference of K and
            # sigma M holds, without its exact zeros, so SuperLU orders the same pattern.
            A = A.tocsr()
            A.eliminate_zeros()
        try:
            self._lu = scipy.sparse.linalg.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                                options={"SymmetricMode": True})
        except RuntimeError as exc:  # singular factor, or SuperLU out of memory
            raise FactorizationError(str(exc)) from exc
        # Diagonal pivoting (row permutation = column permutation): U = D L^T, so U's diagonal
        # carries D's signs. A pivot taken off the diagonal would void that.
        diagonal = np.array_equal(self._lu.perm_r, self._lu.perm_c)
        self.n_negative = int((self._lu.U.diagonal() < 0).sum()) if diagonal else None
        self.factor_nnz = int(self._lu.L.nnz + self._lu.U.nnz)
        self.factor_mb = self.factor_nnz * 12 / 2**20  # value and row index per entry

    def solve(self, B: np.ndarray) -> np.ndarray:
        """A^-1 B for a vector or an (n, k) block."""
        return self._lu.solve(np.asarray(B, dtype=np.float64))


class PardisoFactorization:
    """MKL PARDISO L D L^T (see :class:`sensors.fem.pardiso.PardisoLDLT`).

    Attributes:
        n_negative: Inertia from the factorization (None when pivots had to be perturbed,
            which can flip a sign).
        analysed_before: Whether PARDISO's analysis came from :func:`analyze_pattern`.
    """

    name = "pardiso"
    #: PARDISO's solves (pivoting, iterative refinement) leave residuals at rounding: K Z may be
    #: derived from the solve (one product with M instead of one with K, see fem.eigen).
    exact_solves = True

    def __init__(self, A, analysis=None):
        from .pardiso import PardisoError, PardisoLDLT

        try:
            self._f = PardisoLDLT(A, analysis)
        except PardisoError as exc:
            raise FactorizationError(str(exc)) from exc
        self.n_negative = self._f.n_negative if self._f.n_perturbed_pivots == 0 else None
        self.factor_nnz = None  # PARDISO counts its factor in blocks (see factor_mb)
        self.factor_mb = self._f.factor_mb
        self.analysed_before = self._f.analysed_before

    def solve(self, B: np.ndarray) -> np.ndarray:
        """A^-1 B for a vector or an (n, k) block."""
        return self._f.solve(B)


def factorize(A, solver: str | None = None, analysis=None):
    """Factorization of the symmetric sparse matrix ``A`` by ``solver`` (default:
    :func:`default_solver`), with ``solve(B)``, ``n_negative`` (inertia or None), ``factor_nnz``
    (entries of the factor, None where unknown), ``factor_mb`` and ``name``. ``analysis``: an
    :func:`analyze_pattern` result for A's pattern (used by PARDISO, ignored by SuperLU).

    Raises:
        FactorizationError: the factorization failed.
    """
    solver = default_solver() if solver is None else str(solver).lower()
    if solver == "pardiso":
        return PardisoFactorization(A, analysis)
    if solver == "superlu":
        return SuperLUFactorization(A)
    raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")


def analyze_pattern(indptr: np.ndarray, indices: np.ndarray, solver: str | None = None):
    """The solver's analysis of a symmetric 3 x 3 node-block pattern (node-level CSR arrays)
    before the matrix's values exist, for :func:`factorize` of a matrix with that pattern:
    PARDISO's METIS ordering and symbolic factorization (:class:`sensors.fem.pardiso.PardisoAnalysis`,
    mug: 0.5 of 2.5 CPU s). None for SuperLU (which analyses with its factorization) or when
    the analysis failed (the factorization then analyses, and reports any error)."""
    solver = default_solver() if solver is None else str(solver).lower()
    if solver != "pardiso":
        return None
    from .pardiso import PardisoAnalysis, PardisoError

    try:
        return PardisoAnalysis(indptr, indices)
    except PardisoError as exc:
        log.debug("PARDISO analysis ahead of the values failed: %s", exc)
        return None


#: The preload thread of this process, once started (see :func:`preload_in_background`).
PRELOAD: list = []


def _preload() -> None:
    import scipy.linalg  # noqa: F401 - the eigen-solve's first use
    import scipy.sparse

    try:
        if default_solver() == "pardiso":
            # mkl_rt loads MKL's computational libraries on the first call: a 3 x 3 factorization
            # makes that call.
            PardisoFactorization(scipy.sparse.identity(3, format="csr"))
        else:
            import scipy.sparse.linalg  # noqa: F401 - SuperLU
    except (FactorizationError, ValueError) as exc:  # the build's own factorization reports it
        log.debug("solver preload failed: %s", exc)


def preload_in_background() -> threading.Thread | None:
    """Load the default solver (MKL's libraries: ~0.3 s) and the eigen-solve's SciPy modules in
    a daemon thread, once per process, so that a model build's first factorization does not wait
    for them (the build meshes and assembles meanwhile). Returns the thread when started."""
    if PRELOAD:
        return None
    thread = threading.Thread(target=_preload, name="solver-preload", daemon=True)
    PRELOAD.append(thread)
    thread.start()
    return thread
