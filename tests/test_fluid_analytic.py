"""Physics check 1: ovalling modes of a partially filled cylindrical tank against a series solution.

Reference (implemented here, independently of ``sensors.fluid``): the Rayleigh-Ritz method of
Amabili, Paidoussis & Lakis, "Vibrations of partially filled cylindrical tanks with
ring-stiffeners and flexible bottom", J. Sound Vib. 213 (1998) 259-299 (and, for the wall
alone, Lindholm, Kana & Abramson, "Breathing vibrations of a circular cylindrical shell with an
internal liquid", J. Aerospace Sci. 29 (1962) 1052): the dry modes of the tank are the Ritz
basis, and the liquid's kinetic energy is the exact potential-flow solution in the cylinder
0 < r < a, 0 < s < h for each circumferential harmonic cos(n theta), sin(n theta):

    phi = sum_m A_m I_n(k_m r) cos(k_m s)                        (wall data, k_m = (2m-1) pi / 2h)
        + sum_j B_j J_n(kappa_j r) sinh(kappa_j (h - s)) / (kappa_j cosh(kappa_j h))
                                                                 (bottom data, J_n'(kappa_j a) = 0)

which satisfies Laplace's equation, phi = 0 on the free surface s = h, d(phi)/dr = u_r on the
wall (the bottom series has zero radial derivative there) and -d(phi)/ds = -u_s on the bottom
(the wall series has zero axial derivative there). The coefficients follow from the
orthogonality of cos(k_m s) on [0, h] and of J_n(kappa_j r) with weight r on [0, a]
(norm a^2/2 (1 - n^2 / (kappa_j a)^2) J_n(kappa_j a)^2). The added mass is
M_a[p, q] = rho integral phi_p (u_q . n) dS, and the wet modes solve
Lambda x = w^2 (I + M_a) x on the same dry modes.

Assumptions: inviscid, incompressible liquid; no gravity waves (phi = 0 on the free surface,
valid far above the sloshing frequencies, here > 1 kHz against < 10 Hz); linear motion; the
liquid domain is the exact cylinder (the project meshes it with P2 elements). The tank is a
free-free aluminium cup with a 2 mm wall and a 4 mm elastic bottom (the flexible-bottom case
of Amabili et al.; the everyday ``can`` builder with these sizes); ovalling modes (n = 2, 3)
do not couple to rigid-body motion. The reference's Ritz basis is the dry modes, as in
Amabili et al.; the project's basis adds its static correction (which moves ovalling modes
by well under 1 %).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.special

from sensors.objects.everyday import can
from sensors.fluid import Container, filled

FILLS = (0.2, 0.4, 0.6, 0.8, 1.0)
RHO_WATER = 998.2
#: Aluminium cup: 30 mm outer radius, 2 mm wall, 4 mm bottom, 80 mm tall (axis x, rim at +x).
CUP = dict(outer_radius_m=0.03, wall_m=0.002, height_m=0.08, floor_m=0.004, material="aluminium")
#: Dry modes: up to 20 kHz, about 4 times the highest wet mode checked.
CUP_MAX_FREQUENCY_HZ = 20000.0


def _ive_prime(n, x):
    return 0.5 * (scipy.special.ive(n - 1, x) + scipy.special.ive(n + 1, x))


class CylinderReference:
    """Exact potential-flow added mass of a cylindrical liquid column on given wall motions."""

    def __init__(self, dry, n_harmonics=10, n_theta=64, n_s=160, n_r=64, n_wall_terms=120, n_bottom_terms=60):
        self.dry = dry
        self.a = CUP["outer_radius_m"] - CUP["wall_m"]
        self.s0 = CUP["floor_m"]  # inner bottom (x)
        self.depth = CUP["height_m"] - CUP["floor_m"]
        self.n_harmonics, self.n_theta = n_harmonics, n_theta
        self.n_s, self.n_r = n_s, n_r
        self.M, self.J = n_wall_terms, n_bottom_terms
        self.theta = 2 * np.pi * np.arange(n_theta) / n_theta
        xr, wr = np.polynomial.legendre.leggauss(n_r)
        self.r, self.wr = 0.5 * self.a * (xr + 1), 0.5 * self.a * wr
        # Bottom data once (it does not depend on the fill).
        rr, tt = np.meshgrid(self.r, self.theta, indexing="ij")
        pts = np.stack([np.full(rr.size, self.s0), (rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()], 1)
        U = dry.mode_shapes_at(pts).reshape(n_r, n_theta, 3, -1)
        self.bottom = self._fourier(-U[:, :, 0, :])  # u . n_liquid, n = -x

    def _fourier(self, g):
        """g (..., n_theta, k) -> cos and sin coefficients (n_harm + 1, 2, ..., k)."""
        out = []
        for n in range(self.n_harmonics + 1):
            scale = 1.0 / self.n_theta if n == 0 else 2.0 / self.n_theta
            c = scale * np.tensordot(np.cos(n * self.theta), g, axes=([0], [-2]))
            s = scale * np.tensordot(np.sin(n * self.theta), g, axes=([0], [-2]))
            out.append(np.stack([c, s]))
        return np.stack(out)

    def added_mass(self, fill_height_m, rho=RHO_WATER):
        h, a = fill_height_m, self.a
        xs, ws = np.polynomial.legendre.leggauss(self.n_s)
        s, ws = 0.5 * h * (xs + 1), 0.5 * h * ws
        ss, tt = np.meshgrid(s, self.theta, indexing="ij")
        pts = np.stack([self.s0 + ss.ravel(), (a * np.cos(tt)).ravel(), (a * np.sin(tt)).ravel()], 1)
        U = self.dry.mode_shapes_at(pts).reshape(self.n_s, self.n_theta, 3, -1)
        radial = np.stack([np.zeros_like(tt), np.cos(tt), np.sin(tt)], -1)
        wall = self._fourier(np.einsum("stik,sti->stk", U, radial))  # u . n_liquid, n = radial
        k_modes = U.shape[-1]
        Ma = np.zeros((k_modes, k_modes))
        km = (2 * np.arange(1, self.M + 1) - 1) * np.pi / (2 * h)
        cos_ks = np.cos(np.outer(s, km))  # (n_s, M)
        for n in range(self.n_harmonics + 1):
            kappa = scipy.special.jnp_zeros(n, self.J) / a if n else np.concatenate(
                [[0.0], scipy.special.jnp_zeros(0, self.J - 1) / a])
            alpha = kappa * a
            Jn_r = scipy.special.jv(n, np.outer(self.r, kappa))  # (n_r, J)
            norm = np.where(alpha > 0, 0.5 * a**2 * (1 - n**2 / np.where(alpha > 0, alpha, 1) ** 2)
                            * scipy.special.jv(n, alpha) ** 2, 0.5 * a**2)
            # Wall series: A_m k_m I_n'(k_m a) h/2 = int g_w cos(k_m s) ds; values need I_n(k r)/I_n'(k a).
            ratio_a = scipy.special.ive(n, km * a) / _ive_prime(n, km * a)
            ratio_r = scipy.special.ive(n, np.outer(self.r, km)) * np.exp(np.outer(self.r - a, km)) \
                / _ive_prime(n, km * a)  # (n_r, M)
            # Bottom series: sinh(kappa (h - s)) / (kappa cosh(kappa h)) and its value at s = 0.
            with np.errstate(over="ignore"):
                decay = np.where(kappa > 0, np.exp(-np.outer(s, kappa)) * (1 - np.exp(-2 * np.outer(h - s, kappa)))
                                 / (1 + np.exp(-2 * kappa * h)) / np.where(kappa > 0, kappa, 1), (h - s)[:, None])
            at_bottom = np.where(kappa > 0, np.tanh(kappa * h) / np.where(kappa > 0, kappa, 1), h)
            factor = 2 * np.pi if n == 0 else np.pi
            for parity in range(2):
                gw = wall[n, parity]  # (n_s, k)
                gb = self.bottom[n, parity]  # (n_r, k)
                A = (2 / h) * (cos_ks.T @ (ws[:, None] * gw)) / km[:, None]  # A_m I_n'(k_m a) (M, k)
                B = (Jn_r.T @ ((self.r * self.wr)[:, None] * gb)) / norm[:, None]  # (J, k)
                phi_wall = cos_ks @ (A * ratio_a[:, None]) + (decay * scipy.special.jv(n, alpha)) @ B  # (n_s, k)
                phi_bottom = ratio_r @ A + (Jn_r * at_bottom) @ B  # (n_r, k)
                E = a * phi_wall.T @ (ws[:, None] * gw) + phi_bottom.T @ ((self.r * self.wr)[:, None] * gb)
                Ma += rho * factor * E
        return 0.5 * (Ma + Ma.T)


def _wet(eigenvalues, Ma):
    w2, X = scipy.linalg.eigh(np.diag(eigenvalues), np.eye(len(eigenvalues)) + Ma)
    return np.sqrt(w2) / (2 * np.pi), X


def dominant_harmonic(shapes_at, n_harmonics=10, n_theta=64, n_s=40):
    """The circumferential harmonic n carrying most of each shape's radial wall motion."""
    a, s0, depth = CUP["outer_radius_m"] - CUP["wall_m"], CUP["floor_m"], CUP["height_m"] - CUP["floor_m"]
    theta = 2 * np.pi * np.arange(n_theta) / n_theta
    s = s0 + depth * (np.arange(n_s) + 0.5) / n_s
    ss, tt = np.meshgrid(s, theta, indexing="ij")
    pts = np.stack([ss.ravel(), (a * np.cos(tt)).ravel(), (a * np.sin(tt)).ravel()], 1)
    U = shapes_at(pts).reshape(n_s, n_theta, 3, -1)
    radial = np.einsum("stik,ti->stk", U[:, :, 1:, :], np.stack([np.cos(theta), np.sin(theta)], 1))
    coef = np.fft.rfft(radial, axis=1)[:, : n_harmonics + 1]  # (n_s, n, k)
    return np.argmax(np.sum(np.abs(coef) ** 2, axis=0), axis=0)


def _first(freqs, harmonic, n, count=2):
    return freqs[harmonic == n][:count]


@pytest.fixture(scope="module")
def cup(tmp_path_factory):
    obj = can(**CUP)
    cache_dir = tmp_path_factory.getbasetemp() / "fluid-cache"
    dry = obj.modal_model(max_frequency_hz=CUP_MAX_FREQUENCY_HZ, cache_dir=cache_dir, progress=False)
    container = Container.of(obj, dry=dry, cache_dir=cache_dir)
    return dry, container, CylinderReference(dry)


@pytest.mark.slow
def test_reference_series_converged(cup):
    # The reference itself: doubling every truncation changes the ovalling added mass < 1e-3.
    dry, _, ref = cup
    h = 0.6 * ref.depth
    Ma = ref.added_mass(h)
    fine = CylinderReference(dry, n_theta=96, n_s=240, n_r=96, n_wall_terms=240, n_bottom_terms=120).added_mass(h)
    lam = dry.eigenvalues
    f, _ = _wet(lam, Ma)
    f2, _ = _wet(lam, fine)
    np.testing.assert_allclose(f[:12], f2[:12], rtol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("fill", FILLS)
def test_ovalling_wet_dry_ratios_match_series_solution(cup, fill):
    dry, container, ref = cup
    h = fill * ref.depth
    wet = filled(container, fill_height_m=h, compressible=False)
    f_ref, X_ref = _wet(dry.eigenvalues, ref.added_mass(h))
    dry_harm = dominant_harmonic(dry.mode_shapes_at)
    ref_harm = dominant_harmonic(lambda p: dry.mode_shapes_at(p) @ X_ref)
    got_harm = dominant_harmonic(wet.mode_shapes_at)
    for n in (2, 3):
        dry_n = _first(dry.frequencies_hz, dry_harm, n)
        ref_n = _first(f_ref, ref_harm, n)
        got_n = _first(wet.frequencies_hz, got_harm, n)
        assert len(dry_n) == len(ref_n) == len(got_n) == 2, (n, dry_n, ref_n, got_n)
        ratio_ref, ratio_got = ref_n / dry_n, got_n / dry_n
        assert np.all(ratio_ref < 1.0)
        np.testing.assert_allclose(ratio_got, ratio_ref, rtol=0.03,
                                   err_msg=f"n={n} at {fill:.0%}: wet/dry {ratio_got} vs series {ratio_ref}")
