"""Intel MKL PARDISO for a real symmetric indefinite matrix, called through ctypes.

MKL comes from the ``mkl`` wheel (x86-64 Linux and Windows); nothing is compiled. PARDISO
orders by METIS nested dissection, factorizes A = P L D L^T P^T with supernodal dense blocks
and 1x1 diagonal pivots (Bunch-Kaufman 2x2 pivots when a 1x1 pivot is too small), and solves for a block of right-hand sides at once.
It also reports the inertia of A (the counts of its positive and negative eigenvalues), which
:mod:`sensors.fem.eigen` uses to check that no mode was missed.

Only the upper triangle is passed, zero-based (``iparm[34] = 1``): in 3 x 3 node blocks (BSR)
when the size is a multiple of 3 (node-major FE dofs), else as CSR. The 32-bit integer
interface (LP64) covers every model the project builds (factor entries are counted in 64 bits
by MKL itself; the matrix's own entries stay far below 2**31).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import glob
import os
import sys
import threading

import numpy as np

__all__ = ["PardisoAnalysis", "PardisoError", "PardisoLDLT", "mkl_library", "upper_triangle"]

_MTYPE_REAL_SYMMETRIC_INDEFINITE = -2
_ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
           -4: "zero pivot, numerical factorization or iterative refinement problem",
           -5: "unclassified (internal) error", -6: "reordering failed", -7: "diagonal matrix is singular",
           -8: "32-bit integer overflow problem", -9: "not enough memory for out-of-core",
           -10: "error opening out-of-core files", -11: "read/write error with out-of-core files",
           -12: "pardiso_64 called from 32-bit library", -13: "interrupted by the mkl_progress function",
           -15: "reordering failed (METIS)"}


class PardisoError(RuntimeError):
    """PARDISO returned an error code (the factorization failed or MKL is unusable)."""


#: The MKL library once looked up: [library or None] (a test sets [None] to act as a machine without MKL).
LIBRARY: list = []


def _candidate_paths() -> list[str]:
    names = ("libmkl_rt.so*", "libmkl_rt.*.dylib", "mkl_rt*.dll")
    env = os.environ.get("AAS_GYM_MKL_RT")
    found = [env] if env else []
    # The `mkl` wheel installs into the environment's lib/ (Library/bin on Windows); a user
    # install into the user base. Shorter names first: libmkl_rt.so.2 before libmkl_rt.so.2.dbg.
    for base in dict.fromkeys((sys.prefix, sys.base_prefix, getattr(__import__("site"), "USER_BASE", "") or "")):
        for sub in ("lib", "Library/bin"):
            for pattern in names:
                found += sorted(glob.glob(os.path.join(base, sub, pattern)), key=len)
    return found


_LOADING = threading.Lock()  # one lookup, also when a build's preload thread races the build


def mkl_library():
    """The loaded ``mkl_rt`` library, or None when MKL is not installed (looked up once)."""
    if LIBRARY:
        return LIBRARY[0]
    with _LOADING:
        return LIBRARY[0] if LIBRARY else _load_mkl()


def _load_mkl():
    lib = None
    paths = _candidate_paths()
    if not paths:  # a system-wide MKL (slow: find_library may run ldconfig)
        name = ctypes.util.find_library("mkl_rt")
        paths = [name] if name else []
    for path in paths:
        if path.endswith(".dbg"):
            continue
        try:
            lib = ctypes.CDLL(path)
            lib.pardiso  # noqa: B018 - raises AttributeError when this is not MKL
            break
        except (OSError, AttributeError):
            lib = None
    if lib is not None:
        i32p = ctypes.POINTER(ctypes.c_int32)
        lib.pardiso.restype = None
        lib.pardiso.argtypes = [ctypes.c_void_p, i32p, i32p, i32p, i32p, i32p, ctypes.c_void_p, ctypes.c_void_p,
                                ctypes.c_void_p, ctypes.c_void_p, i32p, ctypes.c_void_p, i32p, ctypes.c_void_p,
                                ctypes.c_void_p, i32p]
        lib.MKL_Set_Num_Threads_Local.restype = ctypes.c_int  # the C name (mkl_set_... takes a pointer)
        lib.MKL_Set_Num_Threads_Local.argtypes = [ctypes.c_int]
    LIBRARY.append(lib)
    return lib


def upper_triangle(indptr: np.ndarray, indices: np.ndarray):
    """(keep, indptr, indices) of the upper triangle of a square CSR or BSR pattern (sorted
    rows): ``keep`` selects its entries, the two others (32-bit) are the pattern PARDISO gets
    (a mask on the arrays: scipy's triu goes through COO, 3x slower)."""
    n_rows = len(indptr) - 1
    rows = np.repeat(np.arange(n_rows, dtype=np.int32), np.diff(indptr))
    keep = indices >= rows
    upper_indptr = np.zeros(n_rows + 1, dtype=np.int32)
    np.cumsum(np.bincount(rows[keep], minlength=n_rows), out=upper_indptr[1:])
    return keep, upper_indptr, np.ascontiguousarray(indices[keep], dtype=np.int32)


def _settings(bunch_kaufman: bool, block: int) -> np.ndarray:
    """PARDISO's iparm for this solver."""
    ip = np.zeros(64, dtype=np.int32)
    ip[0] = 1    # these settings, not the defaults
    ip[1] = 2    # METIS nested-dissection ordering
    ip[7] = 0    # iterative refinement only after perturbed pivots (a positive count refines every solve)
    ip[9] = 8    # pivot perturbation 1e-8 (the default for symmetric indefinite matrices)
    ip[10] = 0   # no scaling and no weighted matching
    ip[12] = 0
    # 1x1 diagonal pivots, as SuperLU's path takes them: the factorization of K - sigma M
    # is 1.4x faster than with Bunch-Kaufman 1x1 and 2x2 pivots (mug, 99k dof: 1.6 s
    # against 2.3 s) for the same factor and inertia. A pivot that had to be perturbed
    # sends the caller back to Bunch-Kaufman.
    ip[20] = 1 if bunch_kaufman else 0
    ip[34] = 1   # zero-based indices
    # Node blocks: given as 3 x 3 BSR (above), or else variable block rows, where PARDISO
    # finds blocks itself (rows 90 % alike): factorization 25-40 % faster on the project's
    # matrices than scalar rows, the same factor.
    ip[36] = 3 if block == 3 else -90
    return ip


class _Handle:
    """A PARDISO handle and the arrays it was given (PARDISO keeps pointers to them between
    phases: they are held on the object)."""

    _factorized = False

    def _call(self, phase: int, B: np.ndarray, X: np.ndarray | None = None) -> None:
        # One OpenMP thread in every phase, whatever MKL_NUM_THREADS says: the factor depends on
        # the thread count MKL actually runs (mug: 337.8 MB on one thread, 336.7 MB on two, the
        # solutions equal to round-off only), and MKL runs fewer threads than asked on a loaded
        # machine, so more than one would make the modes differ from run to run. The setting is
        # this thread's own; the caller's comes back after the call.
        previous = self._lib.MKL_Set_Num_Threads_Local(1)
        try:
            self._pardiso(phase, B, X)
        finally:
            self._lib.MKL_Set_Num_Threads_Local(previous)

    def _pardiso(self, phase: int, B: np.ndarray, X: np.ndarray | None) -> None:
        one, err = ctypes.c_int32(1), ctypes.c_int32(0)
        self._lib.pardiso(self._pt.ctypes.data, ctypes.byref(one), ctypes.byref(one),
                          ctypes.byref(ctypes.c_int32(_MTYPE_REAL_SYMMETRIC_INDEFINITE)), ctypes.byref(ctypes.c_int32(phase)),
                          ctypes.byref(ctypes.c_int32(self.n // self.block)), self._data.ctypes.data, self._indptr.ctypes.data,
                          self._indices.ctypes.data, None, ctypes.byref(ctypes.c_int32(B.shape[1])),
                          self._iparm.ctypes.data, ctypes.byref(ctypes.c_int32(0)), B.ctypes.data,
                          (B if X is None else X).ctypes.data, ctypes.byref(err))
        if err.value:
            raise PardisoError(f"PARDISO phase {phase}: error {err.value} ({_ERRORS.get(err.value, 'unknown')})")

    def release(self) -> None:
        """Free MKL's memory for this handle (also done when the object is collected)."""
        if self._factorized:
            self._factorized = False
            self._call(-1, np.zeros((self.n, 1), order="F"))

    def __del__(self):
        try:
            self.release()
        except Exception:  # interpreter shutdown: MKL may already be gone
            pass


class PardisoAnalysis(_Handle):
    """PARDISO's analysis (METIS ordering and symbolic factorization, phase 11) of a 3 x 3
    node-block pattern, made before its values exist: a :class:`PardisoLDLT` of a matrix with
    that pattern then only factorizes numerically. The analysis reads no values (with no
    scaling or matching, as set here): the factor is bit for bit that of the whole factorization
    (checked on the mug with three sets of values). Used once.

    Args:
        indptr, indices: Node-level pattern of a symmetric matrix (sorted rows); the upper
            triangle is analysed.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray):
        lib = mkl_library()
        if lib is None:
            raise PardisoError("MKL (mkl_rt) not found: pip install mkl")
        self._lib = lib
        self.block = 3
        self.n = 3 * (len(indptr) - 1)
        _, self._indptr, self._indices = upper_triangle(indptr, indices)
        self._data = np.ones(9 * len(self._indices))  # not read by the analysis
        self._pt = np.zeros(64, dtype=np.int64)  # opaque solver handle (64 pointers)
        self._iparm = _settings(bunch_kaufman=False, block=3)
        self._factorized = True  # from here on the handle holds memory to free
        self._call(11, np.zeros((self.n, 1), order="F"))

    def take(self, n: int, indptr: np.ndarray, indices: np.ndarray):
        """The handle and pattern arrays for a factorization of size ``n`` with this upper
        pattern, or None when it differs or the analysis was taken before."""
        if not self._factorized or n != self.n or not (np.array_equal(indptr, self._indptr)
                                                       and np.array_equal(indices, self._indices)):
            return None
        self._factorized = False  # the factorization frees it now
        return self._pt, self._iparm, self._indptr, self._indices


class PardisoLDLT(_Handle):
    """A = P L D L^T P^T of a sparse real symmetric (indefinite) matrix, factorized once.

    Args:
        A: scipy sparse matrix, symmetric; only its upper triangle is read. A BSR matrix of
            3 x 3 blocks is taken as it is (sorted block indices); any other is converted.
        analysis: Optional :class:`PardisoAnalysis` of A's node-block pattern (used when the
            pattern is the same; else A is analysed here).

    Attributes:
        n_positive, n_negative: Inertia of A (eigenvalue signs) as counted by the factorization.
        n_perturbed_pivots: Pivots PARDISO had to perturb (0 for a well-posed shift).
        pivoting: ``"diagonal"`` (1x1 pivots) or ``"bunch-kaufman"`` (1x1 and 2x2, used when
            a 1x1 pivot had to be perturbed or failed).
        factor_mb: Memory of the numerical factorization [MB] (with block rows, PARDISO counts
            blocks, not entries).
        block: Rows per block as passed to PARDISO (3: node-block BSR; 1: CSR).
        analysed_before: Whether the analysis came from a :class:`PardisoAnalysis`.
    """

    def __init__(self, A, analysis: PardisoAnalysis | None = None):
        import scipy.sparse

        lib = mkl_library()
        if lib is None:
            raise PardisoError("MKL (mkl_rt) not found: pip install mkl")
        self._lib = lib
        given_blocks = isinstance(A, scipy.sparse.bsr_matrix) and A.blocksize == (3, 3)
        if not given_blocks:
            A = scipy.sparse.csr_matrix(A)
        A.sort_indices()
        self.n = A.shape[0]
        if A.nnz >= 2**31:
            raise PardisoError("matrix too large for the 32-bit PARDISO interface")
        # PARDISO keeps pointers to the arrays between phases: hold them on the object.
        if given_blocks:  # node blocks as assembled (fem.assembly.NodeBlocks.shifted): no CSR round trip
            Ab = A
            self.block = 3
        elif self.n % 3 == 0:
            # Node-major FE dofs: the upper triangle of 3 x 3 blocks in BSR form (iparm[36] = 3).
            # PARDISO's analysis then orders the node graph as given instead of finding the
            # blocks itself (variable block rows): mug, 99k dof, 0.2 s less of 0.6-0.7 s.
            Ab = A.tobsr(blocksize=(3, 3))
            Ab.sort_indices()
            self.block = 3
        else:
            Ab = A
            self.block = 1
        keep, self._indptr, self._indices = upper_triangle(Ab.indptr, Ab.indices)
        self._data = np.ascontiguousarray(Ab.data[keep], dtype=np.float64)  # blocks row-major
        taken = None if analysis is None or self.block != 3 else analysis.take(self.n, self._indptr, self._indices)
        self.analysed_before = taken is not None
        self._factorized = False
        self.pivoting = "diagonal"
        try:
            self._factorize(bunch_kaufman=False, analysed=taken)
            retry = self.n_perturbed_pivots > 0
        except PardisoError:
            retry = True
        if retry:
            # A pivot too small for 1x1 pivoting: again with Bunch-Kaufman 2x2 pivots, which
            # need no perturbation where a 1x1 pivot would (the inertia stays exact).
            self._factorized = True  # free whatever the first attempt holds
            self.release()
            self.pivoting = "bunch-kaufman"
            self._factorize(bunch_kaufman=True)

    def _factorize(self, bunch_kaufman: bool, analysed=None) -> None:
        if analysed is None:
            self._pt = np.zeros(64, dtype=np.int64)  # opaque solver handle (64 pointers)
            self._iparm = _settings(bunch_kaufman, self.block)
            phase = 12  # analysis + numerical factorization
        else:  # the same settings, analysed already (the arrays equal to this object's)
            self._pt, self._iparm, self._indptr, self._indices = analysed
            phase = 22  # numerical factorization
        self._factorized = True  # the handle holds memory from here on (freed by release)
        ip = self._iparm
        self._call(phase, np.zeros((self.n, 1), order="F"))
        self.factor_mb = float(ip[16]) / 1024  # the factorization's memory (PARDISO's own count)
        self.n_perturbed_pivots = int(ip[13])
        self.n_positive, self.n_negative = int(ip[21]), int(ip[22])

    def solve(self, B: np.ndarray) -> np.ndarray:
        """A^-1 B for a vector or an (n, k) block of right-hand sides."""
        if not self._factorized:
            raise PardisoError("the factorization has been released")
        B = np.asarray(B, dtype=np.float64)
        vector = B.ndim == 1
        Bf = np.asfortranarray(B.reshape(self.n, -1))
        X = np.empty_like(Bf, order="F")
        self._call(33, Bf, X)
        return X.ravel() if vector else X
