"""The compressible liquid: its own acoustic modes and their coupling to the wall's basis.

Used by :func:`sensors.fluid.filled` (``compressible=True``, the default); the physics is
described in :mod:`sensors.fluid.filled_model`.

* :func:`liquid_mass_matrix` - Q0 = integral N_a N_b dV on P2 tets (the compressibility is Q0 / c^2).
* :func:`liquid_modes` - the liquid's acoustic modes with rigid walls and p = 0 on the free
  surface: H psi = (w / c)^2 Q0 psi, on the liquid mesh the added mass already uses.
* :func:`acoustic_loading` - added mass, wall slip and the modal coupling B of the wall's basis
  to those modes, from one factorization of the liquid's Laplacian.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .added_mass import unit_potential_flow, wall_coupling
from ..fem.assembly import QUADRATURE, shape_functions, shape_gradients_ref

__all__ = ["liquid_mass_matrix", "liquid_modes", "acoustic_loading", "LIQUID_MODES_BAND_FACTOR", "MAX_LIQUID_MODES",
           "check_liquid_mode_count"]

#: The liquid's modes are kept up to this factor times the wet model's band limit: a mode at
#: twice the band's top still shifts a mode at the top by a third of its static share (that
#: share is in the added mass already; see :mod:`sensors.fluid.filled_model`).
LIQUID_MODES_BAND_FACTOR = 2.0
#: The most acoustic modes a liquid may bring, as Weyl's law estimates them before any solve
#: (water in the everyday containers: 33-45 estimated, 41-65 found). A much lower speed of sound
#: or a much larger volume would ask for thousands: a dense eigenproblem of the whole liquid mesh
#: (minutes and gigabytes) for modes finer than that mesh resolves.
MAX_LIQUID_MODES = 1000


def weyl_mode_count(volume_m3: float, k2_max: float) -> float:
    """Weyl's estimate N(k) ~ V k^3 / (6 pi^2) of the acoustic modes of ``volume_m3`` of liquid up
    to the wavenumber^2 ``k2_max`` [1/m^2]."""
    return float(volume_m3) * k2_max**1.5 / (6 * math.pi**2)


def check_liquid_mode_count(volume_m3: float, speed_of_sound_m_per_s: float, max_frequency_hz: float,
                            limit: float = MAX_LIQUID_MODES) -> None:
    """Refuse (ValueError), before any solve, a liquid whose acoustic modes up to ``max_frequency_hz``
    Weyl's law counts above ``limit`` (:data:`MAX_LIQUID_MODES`)."""
    c = float(speed_of_sound_m_per_s)
    if not math.isfinite(c) or volume_m3 <= 0.0:
        return
    n = weyl_mode_count(volume_m3, (2.0 * math.pi * max_frequency_hz / c) ** 2)
    if n > limit:
        raise ValueError(
            f"{volume_m3 * 1e6:.4g} ml of a liquid with a speed of sound of {c:g} m/s would have about {n:,.0f} "
            f"acoustic modes below {max_frequency_hz:.0f} Hz, above the limit of {limit:,.0f} "
            "(sensors.fluid.acoustic.MAX_LIQUID_MODES): check the speed of sound (water's is 1482 m/s), or fill "
            "with compressible=False")


def liquid_mass_matrix(nodes_m: np.ndarray, tets10: np.ndarray) -> scipy.sparse.csr_matrix:
    """Q0[a, b] = integral N_a N_b dV [m^3] for P2 tets (degree-5 rule, exact on straight tets)."""
    xi, w = QUADRATURE["deg5"]
    N = shape_functions(np.concatenate([1.0 - xi.sum(axis=1, keepdims=True), xi], axis=1), "p2")  # (q, 10)
    dN = shape_gradients_ref(xi, "p2")
    det = np.linalg.det(np.einsum("mai,qak->mqik", nodes_m[tets10], dN))
    Me = np.einsum("mq,qa,qb->mab", det * w, N, N)
    rows = np.repeat(tets10, 10, axis=1).ravel()
    cols = np.tile(tets10, (1, 10)).ravel()
    n = len(nodes_m)
    Q = scipy.sparse.coo_matrix((Me.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    return ((Q + Q.T) * 0.5).tocsr()


def liquid_modes(laplace_free, mass_free, speed_of_sound_m_per_s: float, max_frequency_hz: float, lu=None,
                 v0=None, max_modes: float = MAX_LIQUID_MODES):
    """The liquid's acoustic modes up to ``max_frequency_hz`` (rigid walls, p = 0 on the free surface).

    Args:
        laplace_free, mass_free: H and Q0 on the nodes off the free surface.
        speed_of_sound_m_per_s: c (``math.inf``: no modes).
        lu: A factorization of ``laplace_free`` (``solve``), reused as the shift-invert operator.
        max_modes: Refuse (ValueError, :func:`check_liquid_mode_count`) more modes than this, as
            Weyl's law counts them before the solve.
        v0: ARPACK's start vector (default: ARPACK's own, which depends on its earlier calls in
            the process; a fixed one makes the result's bytes reproducible).

    Returns:
        (w^2 (m,) [rad^2/s^2] ascending, psi (n_free, m)) with psi^T (Q0 / c^2) psi = I, so that
        psi^T H psi = diag(w^2).
    """
    c = float(speed_of_sound_m_per_s)
    n = laplace_free.shape[0]
    if not math.isfinite(c) or n == 0:
        return np.zeros(0), np.zeros((n, 0))
    k2_max = (2.0 * math.pi * max_frequency_hz / c) ** 2
    check_liquid_mode_count(float(mass_free.sum()), c, max_frequency_hz, max_modes)
    if lu is None:
        lu = scipy.sparse.linalg.splu(laplace_free.tocsc())
    op = scipy.sparse.linalg.LinearOperator((n, n), matvec=lu.solve, matmat=lu.solve, dtype=np.float64)
    # Weyl's law, N(k) ~ V k^3 / (6 pi^2) (the volume from Q0's entries, a partition of unity):
    # one Lanczos run asks for all of them with a margin, instead of restarting as k doubles.
    weyl = weyl_mode_count(float(mass_free.sum()), k2_max)
    k = min(int(1.5 * weyl) + 16, n - 1)
    while True:
        if k >= n - 1:  # a tiny mesh: all of it, dense
            lam, vec = scipy.linalg.eigh(laplace_free.toarray(), mass_free.toarray())
            break
        lam, vec = scipy.sparse.linalg.eigsh(laplace_free, k=k, M=mass_free, sigma=0.0, which="LM", OPinv=op,
                                             tol=1e-10, v0=v0)
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        if lam[-1] > k2_max:
            break
        k = min(int(1.5 * k), n - 1)
    keep = lam <= k2_max
    # Q0-normalized from eigsh; for Q = Q0 / c^2: psi = c psi0.
    return c * c * lam[keep], c * vec[:, keep]


def acoustic_loading(nodes_m: np.ndarray, tets10: np.ndarray, free_surface: np.ndarray, shapes_at,
                     density_kg_m3: float, speed_of_sound_m_per_s: float, max_frequency_hz: float, flow=None):
    """Everything a compressible liquid adds to a basis of wall motions.

    Args:
        nodes_m, tets10, free_surface, shapes_at, density_kg_m3: As
            :func:`~sensors.fluid.added_mass.liquid_loading`.
        speed_of_sound_m_per_s: The liquid's c.
        max_frequency_hz: Keep the liquid's modes up to this frequency.
        flow: The mesh's :class:`~sensors.fluid.added_mass.LiquidFlow` if known (another
            liquid or the incompressible model of the same fill solved it); default solved here.

    Returns:
        (M_a (k, k), S (k, k), B (k, m), w_l^2 (m,)): the incompressible added mass and wall slip
        (as ``liquid_loading``), and the coupling of the basis to the liquid's m modes,
        B[:, l] = sqrt(rho) C^T psi_l / w_l with C the wall's Neumann load
        (:class:`~sensors.fluid.added_mass.WallCoupling` ``.load``), and their w_l^2.
    """
    if flow is None:
        flow = unit_potential_flow(wall_coupling(nodes_m, tets10, free_surface, shapes_at))
    free = flow.free
    Q0 = liquid_mass_matrix(nodes_m, tets10)[free][:, free]
    # A fixed start vector: the same fill gives the same bytes whatever ARPACK ran before.
    w2, psi = liquid_modes(flow.laplace_free, Q0, speed_of_sound_m_per_s, max_frequency_hz, flow.lu,
                           v0=np.ones(len(free)))
    B = math.sqrt(density_kg_m3) * (flow.load_free.T @ psi) / np.sqrt(w2)[None, :]
    return flow.added_mass(density_kg_m3), flow.slip, B, w2
