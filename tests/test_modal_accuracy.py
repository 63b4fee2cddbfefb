"""Modal accuracy against independent references.

* Beam theory: Timoshenko bending (solved here with a fine 1D Timoshenko finite-element model,
  shear coefficients after Cowper 1966), exact torsion (Saint-Venant J of a rectangle by its
  series, J = I_p for circular sections) and axial modes with the Rayleigh-Love lateral
  inertia correction.
* An independent quadratic (P2) solve with scikit-fem on a finer mesh.

FE modes are classified (axial, bending, torsion, other) from their displacement on rings
around the axis; repeated pairs are compared as a set, never vector by vector.
The reference helpers are reused by ``benchmarks/modal_accuracy.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg

from sensors import MATERIALS, Material, ModalModel

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


def classify_modes(model: ModalModel, n_stations: int = 21, n_angles: int = 16) -> list[str]:
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


def compare_to_beam(model: ModalModel, max_hz: float) -> list[tuple[str, float, float]]:
    """(family, reference Hz, FE Hz) for every beam-theory mode below ``max_hz``."""
    ref = beam_reference_hz(model.kind, model.dimensions_m, model.material, max_hz)
    labels = classify_modes(model)
    rows = []
    for family, fr in ref.items():
        fe = sorted(f for f, lab in zip(model.frequencies_hz, labels) if lab == family)
        for i, f in enumerate(fr):
            rows.append((family, f, fe[i] if i < len(fe) else float("nan")))
    return rows


# ----------------------------------------------------------------------------- scikit-fem reference


def skfem_p2_frequencies_hz(kind: str, dims: dict, material: Material, n_modes: int, resolution: float = 2.0):
    """Independent P2 solve with scikit-fem (curved boundary nodes for cylinders)."""
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, MeshTet2, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    from sensors.meshing import bar_mesh, tube_mesh

    tm = bar_mesh(**dims, resolution=resolution) if kind == "bar" else tube_mesh(**dims, resolution=resolution)
    mesh = MeshTet2.from_mesh(MeshTet(tm.vertices_m.T.copy(), tm.tets.T.copy()))
    if kind == "tube":
        doflocs = mesh.doflocs.copy()
        nv = tm.vertices_m.shape[0]
        edges = mesh.edges
        r_v = np.hypot(tm.vertices_m[:, 1], tm.vertices_m[:, 2])
        mid = doflocs[:, nv:]
        assert np.allclose(mid, 0.5 * (doflocs[:, edges[0]] + doflocs[:, edges[1]]))
        for radius in (dims["inner_radius_m"], dims["outer_radius_m"]):
            on = np.abs(r_v - radius) < 1e-9 * radius
            both = on[edges[0]] & on[edges[1]]
            rm = np.hypot(mid[1, both], mid[2, both])
            mid[1:, both] *= radius / rm
        doflocs[:, nv:] = mid
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
    vals = scipy.sparse.linalg.eigsh(K, k=n_modes + 6, M=M, sigma=sigma, which="LM", return_eigenvectors=False)
    vals = np.sort(vals)[6:]
    return np.sqrt(vals) / (2 * math.pi)


# ----------------------------------------------------------------------------- tests


@pytest.fixture(scope="module")
def default_models(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    models = {}
    for name in TABLE:
        models["bar", name] = ModalModel.bar(**BAR, material=name, cache_dir=cache, max_frequency_hz=10500)
        models["tube", name] = ModalModel.tube(**TUBE, material=name, cache_dir=cache, max_frequency_hz=10500)
    return models


def test_timoshenko_reference_reduces_to_euler_bernoulli_for_slender_beams():
    # Independent check of the reference itself: L/h = 1000 makes shear negligible.
    E, G, rho, A, I = 2e11, 8e10, 7850.0, 1e-4, 1e-4**2 / 12
    f = timoshenko_free_free_hz(10.0, E, G, rho, A, I, 0.85, n_modes=3)
    roots = np.array([4.730041, 7.853205, 10.995608])
    eb = roots**2 / (2 * math.pi * 10.0**2) * math.sqrt(E * I / (rho * A))
    np.testing.assert_allclose(f, eb, rtol=2e-4)


@pytest.mark.parametrize("kind", ["bar", "tube"])
@pytest.mark.parametrize("name", TABLE)
def test_default_objects_match_beam_theory_within_1_percent(default_models, kind, name):
    model = default_models[kind, name]
    rows = compare_to_beam(model, 10000.0)
    assert rows, "no beam modes below 10 kHz?"
    for family, ref, fe in rows:
        assert abs(fe / ref - 1) < 0.01, f"{kind} {name} {family}: FE {fe:.1f} Hz vs beam theory {ref:.1f} Hz"


@pytest.mark.parametrize("kind", ["bar", "tube"])
def test_same_mesh_matches_independent_skfem_p2(kind):
    # Same mesh and geometry (curved mid-edge nodes for the tube), independent assembly and
    # solve: the discrete eigenvalues must agree to solver precision. This checks our
    # assembly, quadrature and eigen-solve; the beam tests check the discretization error.
    dims = BAR if kind == "bar" else TUBE
    build = ModalModel.bar if kind == "bar" else ModalModel.tube
    model = build(**dims, material="abs", resolution=0.5, cache=False, max_frequency_hz=12000)
    ref = skfem_p2_frequencies_hz(kind, dims, MATERIALS["abs"], model.n_modes + 2, resolution=0.5)
    # Straight elements are integrated exactly by both codes; curved ones (tube) with
    # different quadrature rules, which leaves ~1e-4 on this deliberately coarse mesh.
    np.testing.assert_allclose(model.frequencies_hz, ref[: model.n_modes], rtol=1e-7 if kind == "bar" else 5e-4)


def test_p1_locks_and_p2_converges(tmp_path):
    # Bending of P1 tets is much too stiff on the same mesh; P2 is within 1 %.
    ref = beam_reference_hz("bar", BAR, MATERIALS["steel"], 4000.0)["bending"][0]
    p1 = ModalModel.bar(**BAR, material="steel", element="p1", cache=False, max_frequency_hz=4000)
    p2 = ModalModel.bar(**BAR, material="steel", element="p2", cache=False, max_frequency_hz=4000)
    assert p1.frequencies_hz[0] / ref - 1 > 0.05
    assert abs(p2.frequencies_hz[0] / ref - 1) < 0.01
