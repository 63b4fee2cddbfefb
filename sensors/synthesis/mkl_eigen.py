"""The eigen-decomposition of a small dense real matrix by MKL's LAPACK, when MKL is installed.

A new contact system's discretisation (:func:`sensors.synthesis.lti.lti_parts`) is one dense
nonsymmetric eigen-solve of its state matrix (2 r rows: 42 for GraspPosition-v0's wood bar, 74
for FillLevel-v0's mug).  MKL's ``dgeev`` on one thread takes about half the time of the
OpenBLAS LAPACK that SciPy ships (0.43 against 0.88 ms at 42 rows, 2.2 against 3.9 ms at 74);
both are backward stable, and their eigenvalues agree to a few 1e-15 of the largest.  MKL is
already loaded for PARDISO (``sensors.fem.pardiso.mkl_library``); without it SciPy's path is
taken.
"""

from __future__ import annotations

import ctypes

import numpy as np

__all__ = ["mkl_eig"]

_COLUMN_MAJOR = 102


def _dgeev():
    """(mkl_rt, its LAPACKE_dgeev), or (None, None) without MKL."""
    from ..fem.pardiso import mkl_library  # deferred: its subpackage loads with the first model

    lib = mkl_library()
    f = getattr(lib, "LAPACKE_dgeev", None) if lib is not None else None
    if f is None:
        return None, None
    if f.argtypes is None:
        f.restype = ctypes.c_int
        f.argtypes = [ctypes.c_int, ctypes.c_char, ctypes.c_char, ctypes.c_int, ctypes.c_void_p, ctypes.c_int,
                      ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
    return lib, f


def mkl_eig(A: np.ndarray):
    """``(lam, V)`` of the real square matrix ``A`` as ``scipy.linalg.eig`` gives them
    (eigenvalues in LAPACK's order, conjugate pairs as complex columns, each of unit 2-norm),
    computed by MKL on one thread; ``None`` without MKL or when it fails."""
    lib, f = _dgeev()
    if f is None:
        return None
    n = A.shape[0]
    a = np.array(A, dtype=float, order="F")
    wr, wi = np.empty(n), np.empty(n)
    vr = np.empty((n, n), order="F")
    previous = lib.MKL_Set_Num_Threads_Local(1)     # one thread, as the rest of a build
    try:
        info = f(_COLUMN_MAJOR, b"N", b"V", n, a.ctypes.data, n, wr.ctypes.data, wi.ctypes.data, None, 1,
                 vr.ctypes.data, n)
    finally:
        lib.MKL_Set_Num_Threads_Local(previous)
    if info != 0:
        return None
    lam = wr + 1j * wi
    V = vr.astype(complex)
    # a pair's columns hold the real and imaginary parts of its first eigenvector
    pair = np.flatnonzero(wi > 0)
    pair = pair[pair + 1 < n]
    V[:, pair] = vr[:, pair] + 1j * vr[:, pair + 1]
    V[:, pair + 1] = vr[:, pair] - 1j * vr[:, pair + 1]
    return lam, V
