"""Starting roots for :mod:`sensors.synthesis.low_rank_modes`: quasi-degenerate perturbation theory.

The state matrix A = A0 + dA has A0 = [[0, Omega], [-Omega, -diag(d)]] (closed-form poles
l+_i, l-_i, eigenvector columns [w_i e_i; l_i e_i]) and the contact damping
dA = [[0, 0], [0, -G]], G = Q^T Q. In A0's eigenbasis dA has the entries

    P[(i,+), (j,+-)] = a_i l+-_j G_ij,   P[(i,-), (j,+)] = -a_i l+_j G_ij,   a_i = w_i / det_i,

with det_i = w_i (l-_i - l+_i). First order moves l+_i by P[(i,+), (i,+)] only; that is 1e-4
off for the nearly repeated pairs of a symmetric object, whose coupling through G is as large
as their gap. Here modes are grouped into clusters (neighbours in frequency whose mutual
second-order shift exceeds ``CLUSTER_SHIFT`` of the frequency); every cluster's roots are the
eigenvalues of its effective matrix

    H_ij = delta_ij l+_i + P[(i,+), (j,+)] + sum_b P[(i,+), b] P[b, (j,+)] / (l+_i - pole_b)

over the poles b outside the cluster (Loewdin partitioning to second order), which for an
isolated mode is second-order perturbation theory. The roots start 1e-8 off instead of 1e-4,
and the Aberth iteration converges in two sweeps instead of six. Only a start: every root is
iterated to convergence and checked afterwards.
"""
from __future__ import annotations

import numpy as np

from .._infra.jit import jitted

# Second-order shift, relative to the frequency, above which two neighbours form a cluster.
CLUSTER_SHIFT = 1e-8


def start_roots(lp: np.ndarray, lm: np.ndarray, w: np.ndarray, det: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Approximate eigenvalues (Im > 0), one per mode, of the state matrix with damping
    diag(d) + Q^T Q, from the undamped-contact poles ``lp`` (Im > 0), ``lm``, the angular
    frequencies ``w`` [rad/s], ``det = w (lm - lp)`` and the contact factor ``Q`` (k, r)."""
    r = lp.size
    G = Q.T @ Q
    a = w / det
    order = np.argsort(lp.imag, kind="stable")
    i, j = order[:-1], order[1:]
    shift_x_gap = np.abs(a[i] * lp[j] * a[j] * lp[i]) * G[i, j] ** 2   # second-order shift * gap
    link = shift_x_gap > CLUSTER_SHIFT * np.abs(lp[i]) * np.abs(lp[i] - lp[j])
    cluster_sorted = np.concatenate([[0], np.cumsum(~link)])
    cluster = np.empty(r, int)
    cluster[order] = cluster_sorted
    KG = np.empty((r, r), complex)
    second = jitted(globals(), "_second_order", cache=True, error_model="numpy")(lp, lm, a, G, cluster, KG)
    lam = lp + a * lp * (np.diag(G) + second)
    sizes = np.bincount(cluster_sorted)
    first = np.cumsum(sizes) - sizes
    pairs = np.flatnonzero(sizes == 2)
    if pairs.size:  # the usual cluster (a symmetric object's pair): closed-form 2 x 2 eigenvalues
        members = order[first[pairs][:, None] + np.arange(2)]
        H = _effective(members, a, lp, G, KG, lam)
        half_trace = 0.5 * (H[:, 0, 0] + H[:, 1, 1])
        root = np.sqrt(0.25 * (H[:, 0, 0] - H[:, 1, 1]) ** 2 + H[:, 0, 1] * H[:, 1, 0])
        lam[members[:, 0]], lam[members[:, 1]] = half_trace + root, half_trace - root
    # larger clusters padded to a power of two (few eigen-solve calls) with rows and columns
    # that hold only a far diagonal entry: an exact eigenvalue of its own, dropped below
    big = np.flatnonzero(sizes > 2)
    bins = 2 ** np.ceil(np.log2(sizes[big])).astype(int)
    for m in np.unique(bins):
        cl = big[bins == m]
        slot = np.arange(m)
        valid = slot < sizes[cl][:, None]                                   # (clusters, m)
        members = order[np.minimum(first[cl][:, None] + slot, r - 1)]
        H = _effective(members, a, lp, G, KG, lam)
        H[~(valid[:, :, None] & valid[:, None, :])] = 0.0
        centre = lam[members[:, 0]]
        H[:, slot, slot] = np.where(valid, H[:, slot, slot], 1e3 * centre[:, None])
        ev = np.linalg.eigvals(H)
        nearest = np.take_along_axis(ev, np.argsort(np.abs(ev - centre[:, None]), axis=1), axis=1)
        lam[members[valid]] = nearest[valid]
    return lam


def _effective(members, a, lp, G, KG, lam):
    """Effective matrices (clusters, m, m) of the clusters ``members`` (clusters, m)."""
    I, J = members[:, :, None], members[:, None, :]
    H = a[I] * lp[J] * (G[I, J] + KG[members] @ G[members].transpose(0, 2, 1))
    diag = np.arange(members.shape[1])
    H[:, diag, diag] = lam[members]
    return H


# compiled by numba on first use (sensors._infra.jit; error_model="numpy": a zero gap gives inf,
# a start the iteration's checks reject, never an exception)
def _second_order(lp, lm, a, G, cluster, KG):
    """KG[i, b] = K[i, b] G_ib with K[i, b] = a_b (l+_b / (l+_i - l+_b) [b outside i's
    cluster] - l-_b / (l+_i - l-_b)), so that the second-order coupling of modes i and j is
    a_i l+_j sum_b KG[i, b] G_bj; returns its diagonal sums sum_b KG[i, b] G_ib."""
    r = lp.size
    out = np.empty(r, np.complex128)
    for i in range(r):
        acc = 0j
        for b in range(r):
            if G[i, b] == 0.0:  # no coupling (also between exactly repeated, unlinked poles)
                KG[i, b] = 0.0
                continue
            k = -a[b] * lm[b] / (lp[i] - lm[b])
            if cluster[b] != cluster[i]:
                k += a[b] * lp[b] / (lp[i] - lp[b])
            kg = k * G[i, b]
            KG[i, b] = kg
            acc += kg * G[i, b]
        out[i] = acc
    return out
