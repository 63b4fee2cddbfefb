"""Modal accuracy against independent references.

* Beam theory: Timoshenko bending (solved here with a fine 1D Timoshenko finite-element model,
  shear coefficients after Cowper 1966), exact torsion (Saint-Venant J of a rectangle by its
  series, J = I_p for circular sections) and axial modes with the Rayleigh-Love lateral
  inertia correction.
* An independent quadratic (P2) solve with scikit-fem on a finer mesh.

FE modes are classified (axial, bending, torsion, other) from their displacement on rings
around the axis; repeated pairs are compared as a set, never vector by vector.
The beam-theory references live in ``sensors.fem.beam_theory`` (shared with
``benchmarks/modal_accuracy.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg

from sensors import MATERIALS, Material, ModalModel

from sensors.fem.beam_theory import (BAR, TABLE, TUBE, beam_reference_hz,  # noqa: F401
                                 compare_to_beam, timoshenko_free_free_hz)

# ----------------------------------------------------------------------------- scikit-fem reference


def skfem_p2_frequencies_hz(kind: str, dims: dict, material: Material, n_modes: int, resolution: float = 2.0):
    """Independent P2 solve with scikit-fem (curved boundary nodes for cylinders)."""
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, MeshTet2, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    from sensors.mesh.prisms import bar_mesh, tube_mesh

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


@pytest.mark.slow
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


@pytest.mark.slow
def test_p1_locks_and_p2_converges(tmp_path):
    # Bending of P1 tets is much too stiff on the same mesh; P2 is within 1 %.
    ref = beam_reference_hz("bar", BAR, MATERIALS["steel"], 4000.0)["bending"][0]
    p1 = ModalModel.bar(**BAR, material="steel", element="p1", cache=False, max_frequency_hz=4000)
    p2 = ModalModel.bar(**BAR, material="steel", element="p2", cache=False, max_frequency_hz=4000)
    assert p1.frequencies_hz[0] / ref - 1 > 0.05
    assert abs(p2.frequencies_hz[0] / ref - 1) < 0.01
