"""Analytic references for free-free beams and the mode-family classifier that matches FEM
modes to them: beam theory (Rayleigh-Love axial, Saint-Venant torsion, Timoshenko bending with
Cowper's shear coefficients, see DESIGN.md) for the accuracy tests and
``benchmarks/modal_accuracy.py``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from ..materials.solids import Material

#: The paper's default objects' dimensions and materials.
BAR = dict(length_m=0.2, width_m=0.025, height_m=0.025)
TUBE = dict(length_m=0.2, outer_radius_m=0.0125, inner_radius_m=0.0095)
TABLE = ("abs", "aluminium", "steel", "wood")


# ----------------------------------------------------------------------------- beam theory


def section(kind: str, dims: dict, nu: float) -> dict:
    """Area, second moments, torsion constant, polar moment and Cowper shear coefficients."""
    if kind == "bar":
        b, h = dims["width_m"], dims["height_m"]
        area = b * h
        iy, iz = b * h**3 / 12, h * b**3 / 12  # iy: bending in z (about y), iz: bending in y
        a, c = max(b, h), min(b, h)
        s = sum(math.tanh(n * math.pi * a / (2 * c)) / n**5 for n in range(1, 200, 2))
        j = a * c**3 / 3 * (1 - 192 / math.pi**5 * c / a * s)
        kappa = 10 * (1 + nu) / (12 + 11 * nu)
        return dict(area=area, i_bend=(iy, iz), j=j, ip=iy + iz, kappa=kappa)
    ro, ri = dims["outer_radius_m"], dims.get("inner_radius_m", 0.0)
    area = math.pi * (ro**2 - ri**2)
    i = math.pi * (ro**4 - ri**4) / 4
    m = ri / ro
    kappa = 6 * (1 + nu) * (1 + m**2) ** 2 / ((7 + 6 * nu) * (1 + m**2) ** 2 + (20 + 12 * nu) * m**2)
    return dict(area=area, i_bend=(i, i), j=2 * i, ip=2 * i, kappa=kappa)


def timoshenko_free_free_hz(length_m, E, G, rho, area, inertia, kappa, n_modes=8, n_el=400):
    """Free-free Timoshenko beam frequencies [Hz] (1D FE, Richardson-extrapolated, ~1e-6 rel)."""

    def solve(ne):
        h = length_m / ne
        nd = 2 * (ne + 1)
        K = np.zeros((nd, nd))
        Mm = np.zeros((nd, nd))
        kb = E * inertia / h * np.array([[1, -1], [-1, 1]])
        bs = np.array([-1 / h, -0.5, 1 / h, -0.5])  # shear strain w' - theta, one-point rule
        ks = kappa * G * area * h * np.outer(bs, bs)
        ml = h / 6 * np.array([[2, 1], [1, 2]])
        for e in range(ne):
            d = np.array([2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3])  # w1, th1, w2, th2
            K[np.ix_(d, d)] += ks
            K[np.ix_(d[[1, 3]], d[[1, 3]])] += kb
            Mm[np.ix_(d[[0, 2]], d[[0, 2]])] += rho * area * ml
            Mm[np.ix_(d[[1, 3]], d[[1, 3]])] += rho * inertia * ml
        lam = scipy.linalg.eigh(K, Mm, eigvals_only=True, subset_by_index=[0, n_modes + 1])
        return np.sqrt(np.abs(lam[2:])) / (2 * math.pi)

    f1, f2 = solve(n_el), solve(2 * n_el)
    return (4 * f2 - f1) / 3  # the element converges as h^2


def beam_reference_hz(kind: str, dims: dict, material: Material, max_hz: float) -> dict:
    """Beam-theory frequencies below ``max_hz`` by family: axial, bending, torsion."""
    E, G, rho, nu = material.youngs_modulus_pa, material.shear_modulus_pa, material.density_kg_m3, material.poisson_ratio
    L = dims["length_m"]
    s = section(kind, dims, nu)
    out = {"axial": [], "bending": [], "torsion": []}
    r_p = math.sqrt(s["ip"] / s["area"])  # polar radius of gyration
    for n in range(1, 100):
        k = n * math.pi / L
        f = n / (2 * L) * math.sqrt(E / rho) / math.sqrt(1 + (nu * k * r_p) ** 2)  # Rayleigh-Love
        if f > max_hz:
            break
        out["axial"].append(f)
    for n in range(1, 100):
        f = n / (2 * L) * math.sqrt(G * s["j"] / (rho * s["ip"]))
        if f > max_hz:
            break
        out["torsion"].append(f)
    for inertia in s["i_bend"]:
        fb = timoshenko_free_free_hz(L, E, G, rho, s["area"], inertia, s["kappa"], n_modes=10)
        out["bending"] += [f for f in fb if f <= max_hz]
    return {k: sorted(v) for k, v in out.items()}


# ----------------------------------------------------------------------------- classification


def classify_modes(model, n_stations: int = 21, n_angles: int = 16) -> list[str]:
    """Label each mode axial / bending / torsion / other from rigid cross-section motion.

    On rings of surface points at stations along x, the displacement is least-squares fitted
    by a rigid motion of the cross-section (u_x, u_y, u_z, rotation about x); the family with
    the most energy wins, and modes the fit explains poorly (shell/ring modes) are "other".
    """
    L = model.dimensions_m["length_m"]
    if model.kind == "bar":
        b, h = model.dimensions_m["width_m"], model.dimensions_m["height_m"]
        t = np.linspace(0, 2 * math.pi, n_angles, endpoint=False) + 0.1
        # Points on the rectangle boundary along rays.
        c, s_ = np.cos(t), np.sin(t)
        scale = np.minimum(0.5 * b / np.maximum(np.abs(c), 1e-12), 0.5 * h / np.maximum(np.abs(s_), 1e-12))
        yz = np.stack([c * scale, s_ * scale], 1)
    else:
        r = model.dimensions_m.get("outer_radius_m", model.dimensions_m.get("radius_m"))
        t = np.linspace(0, 2 * math.pi, n_angles, endpoint=False)
        yz = r * np.stack([np.cos(t), np.sin(t)], 1)
    xs = np.linspace(-0.45 * L, 0.45 * L, n_stations)
    pts = np.array([[x, y, z] for x in xs for (y, z) in yz])
    U = model.mode_shapes_at(pts).reshape(n_stations, n_angles, 3, -1)  # (s, a, 3, r)
    rot = (yz[:, 0, None] * U[:, :, 2] - yz[:, 1, None] * U[:, :, 1]) / np.sum(yz**2, axis=1)[None, :, None]
    radius = np.sqrt(np.mean(np.sum(yz**2, axis=1)))
    energy = {
        "axial": np.sum(U[:, :, 0].mean(axis=1) ** 2, axis=0),
        "bending": np.sum(U[:, :, 1].mean(axis=1) ** 2 + U[:, :, 2].mean(axis=1) ** 2, axis=0),
        "torsion": np.sum((radius * rot.mean(axis=1)) ** 2, axis=0),
    }
    total = np.sum(U**2, axis=(0, 1, 2)) / n_angles
    labels = []
    for j in range(U.shape[-1]):
        e = {k: v[j] for k, v in energy.items()}
        best = max(e, key=e.get)
        # Bending also moves u_x (plane sections rotate), so judge the fit by the winner only.
        labels.append(best if e[best] > 0.3 * total[j] else "other")
    return labels


def compare_to_beam(model, max_hz: float) -> list[tuple[str, float, float]]:
    """(family, reference Hz, FE Hz) for every beam-theory mode below ``max_hz``."""
    ref = beam_reference_hz(model.kind, model.dimensions_m, model.material, max_hz)
    labels = classify_modes(model)
    rows = []
    for family, fr in ref.items():
        fe = sorted(f for f, lab in zip(model.frequencies_hz, labels) if lab == family)
        for i, f in enumerate(fr):
            rows.append((family, f, fe[i] if i < len(fe) else float("nan")))
    return rows


