"""Mirror-symmetric meshes and the eigenproblem split by symmetry class (sensors.fem.mirror):
the everyday meshes mirror onto themselves, the classes' modes are the whole problem's (against
the whole problem's own solve and residuals), none lost or doubled, bit for bit run to run."""

import numpy as np
import pytest

from sensors.fem import mirror
from sensors.fem.assembly import assemble
from sensors.fem.eigen import mode_residuals, solve_modes
from sensors.materials.solids import get_material
from sensors.mesh.layered import grid_template, layered_mesh
from sensors.mesh.quadratic import quadratic_mesh
from sensors.mesh.tets import boundary_faces
from sensors.objects import get_object

SYMMETRIC = {"mug": (2,), "bottle": (1, 2), "can": (1, 2), "glass": (1, 2), "box": (1, 2)}


def _mirrored_index(points: np.ndarray, axis: int) -> np.ndarray:
    """Index of each point's mirror image across the plane ``axis`` = 0 (by rounded coordinates)."""
    scale = 1e-9 * np.abs(points).max()
    key = {tuple(k): i for i, k in enumerate(np.round(points / scale).astype(np.int64))}
    image = points.copy()
    image[:, axis] *= -1
    return np.array([key[tuple(k)] for k in np.round(image / scale).astype(np.int64)])


@pytest.mark.parametrize("name", sorted(SYMMETRIC))
def test_everyday_meshes_mirror_onto_themselves(name):
    tm = get_object(name).solid().tet_mesh()
    assert tm.mirror_axes == SYMMETRIC[name]
    tets = {tuple(sorted(t)) for t in tm.tets.tolist()}
    for axis in tm.mirror_axes:
        image = _mirrored_index(tm.vertices_m, axis)
        assert {tuple(sorted(t)) for t in image[tm.tets].tolist()} == tets


def test_the_mug_collides_on_its_plain_split_surface():
    """The mug's modes come from its mirror-split mesh, its collision pieces and mass from the
    surface of its plain split: the same vertices, other diagonals (CoACD's pieces of the mirror
    split's surface left the mug trembling on the table, tests/test_settle_until_rest.py)."""
    solid = get_object("mug").solid()
    mirrored, plain = solid.tet_mesher(2.0), solid.tet_mesher(2.0, mirror_split=False)
    assert (mirrored.mirror_axes, plain.mirror_axes) == ((2,), ())
    np.testing.assert_array_equal(mirrored.vertices_m, plain.vertices_m)

    def corners(vertices, triangles):  # each triangle as its set of corner points
        return {tuple(sorted(map(tuple, t))) for t in np.asarray(vertices)[triangles].round(12).tolist()}

    surface = corners(solid.surface.vertices, solid.surface.faces)
    assert surface == corners(plain.vertices_m, boundary_faces(plain.tets)[0])
    assert surface != corners(mirrored.vertices_m, boundary_faces(mirrored.tets)[0])


def test_asymmetric_meshes_take_the_whole_problem():
    for name in ("spoon", "l_bracket"):
        assert get_object(name).solid().tet_mesh().mirror_axes == ()
    # The spoon's vertices mirror across x-z, its tets do not: no split.
    tm = get_object("spoon").solid().tet_mesh()
    nodes, elements = quadratic_mesh(tm)
    assert mirror.mirror_split(nodes, elements, (1,)) is None


def _square_bar(n_cells: int = 4, n_layers: int = 10):
    """A 12 mm square ABS bar, 90 mm long, mirror-split about y and z: its y and z bending
    modes are pairs, one in each of two classes."""
    lines = np.linspace(-0.006, 0.006, n_cells + 1)
    tpl = grid_template(lines, lines, lambda u, v: np.zeros(len(u), int))
    levels = np.linspace(0.0, 0.09, n_layers + 1)
    tm = layered_mesh(tpl, n_layers, np.ones((n_layers, len(tpl.triangles)), bool),
                      lambda p, k: np.column_stack([np.full(len(p), levels[k]), p]), "bar", mirror_axes=(1, 2))
    return quadratic_mesh(tm), get_material("abs")


def _both(nodes, elements, material, band_hz, solver=None):
    K, M = assemble(nodes, elements, material, "p2")
    whole = solve_modes(K, M, nodes, band_hz, solver=solver)
    split = mirror.mirror_split(nodes, elements, (1, 2))
    info = {}
    split_modes = mirror.solve_mirrored_modes(split, nodes, split.assemble(nodes, material), band_hz, solver=solver,
                                              info=info)
    return K, M, whole, split_modes, split, info


@pytest.mark.parametrize("solver", ["pardiso", "superlu"])
def test_classes_give_the_whole_problems_modes(solver):
    from sensors.fem.direct_solver import available_solvers

    if solver not in available_solvers():
        pytest.skip(f"{solver} not installed")
    (nodes, elements), material = _square_bar()
    K, M, (lam, U), (lam_s, U_s), split, info = _both(nodes, elements, material, 12000.0, solver)
    assert len(lam_s) == len(lam) >= 6
    np.testing.assert_allclose(lam_s, lam, rtol=1e-9)
    assert mode_residuals(K, M, lam_s, U_s).max() <= 1e-6  # the whole problem's own check
    np.testing.assert_allclose(U_s.T @ (M @ U_s), np.eye(len(lam_s)), atol=1e-10)
    # Each class's share of the six rigid-body modes: all six, once.
    assert sorted(sum((c.rigid for c in split.classes), ())) == list(range(6))
    assert sum(len(c.dofs) for c in split.classes) == K.shape[0]
    assert sum(len(d["dof"] * [0]) for d in info["classes"]) == K.shape[0]


def test_a_pair_cut_by_the_band_is_completed_across_classes():
    """Band limit between the two members of a bending pair (one per class): the whole solve
    keeps the pair (a cluster is never cut), and so must the split."""
    (nodes, elements), material = _square_bar()
    K, M = assemble(nodes, elements, material, "p2")
    lam, _ = solve_modes(K, M, nodes, 12000.0)
    f = np.sqrt(lam) / (2 * np.pi)
    pair = int(np.flatnonzero(np.diff(f) / f[:-1] < 1e-3)[0])  # the first bending pair
    band_hz = 0.5 * (f[pair] + f[pair + 1])
    assert f[pair] < band_hz < f[pair + 1]
    K, M, (lam, _), (lam_s, _), _, _ = _both(nodes, elements, material, band_hz)
    assert len(lam) == len(lam_s) == pair + 2
    np.testing.assert_allclose(lam_s, lam, rtol=1e-9)


def test_bit_for_bit_whatever_the_threads_and_core_slots(monkeypatch):
    (nodes, elements), material = _square_bar(n_cells=2, n_layers=8)
    split = mirror.mirror_split(nodes, elements, (1, 2))
    runs = []
    for threads in (2, 1, 2):
        monkeypatch.setattr(mirror, "THREADS", threads)
        runs.append(mirror.solve_mirrored_modes(split, nodes, split.assemble(nodes, material), 15000.0))
    # The classes one at a time, as beside CoACD (aas_gym.object_build holds a core).
    import threading

    token = mirror.CORE_SLOTS.set(threading.BoundedSemaphore(1))
    try:
        runs.append(mirror.solve_mirrored_modes(split, nodes, split.assemble(nodes, material), 15000.0))
    finally:
        mirror.CORE_SLOTS.reset(token)
    for lam, U in runs[1:]:
        assert np.array_equal(lam, runs[0][0]) and np.array_equal(U, runs[0][1])


def test_a_mirror_mesh_changes_the_cache_key():
    (nodes, elements), _ = _square_bar(n_cells=2, n_layers=4)
    import dataclasses

    lines = np.linspace(-0.006, 0.006, 3)
    tpl = grid_template(lines, lines, lambda u, v: np.zeros(len(u), int))
    tm = layered_mesh(tpl, 4, np.ones((4, len(tpl.triangles)), bool),
                      lambda p, k: np.column_stack([np.full(len(p), 0.02 * k), p]), "bar", mirror_axes=(1, 2))
    assert tm.digest() != dataclasses.replace(tm, mirror_axes=()).digest()


def test_a_model_of_a_mirror_mesh_is_built_per_class_and_a_plain_mesh_whole(tmp_path):
    import dataclasses

    from sensors.modal.model import ModalModel

    lines = np.linspace(-0.006, 0.006, 5)
    tpl = grid_template(lines, lines, lambda u, v: np.zeros(len(u), int))
    tm = layered_mesh(tpl, 10, np.ones((10, len(tpl.triangles)), bool),
                      lambda p, k: np.column_stack([np.full(len(p), 0.009 * k), p]), "bar", mirror_axes=(1, 2))
    split = ModalModel.from_tet_mesh(tm, "abs", max_frequency_hz=12000.0, cache_dir=tmp_path, progress=False)
    whole = ModalModel.from_tet_mesh(dataclasses.replace(tm, mirror_axes=()), "abs", max_frequency_hz=12000.0,
                                     cache_dir=tmp_path, progress=False)
    assert not whole.metadata.get("cache_hit")  # another key: not served the split model
    assert tuple(split.metadata["eigensolve"]["mirror_axes"]) == (1, 2)
    assert "mirror_axes" not in whole.metadata["eigensolve"]
    assert split.metadata["n_dof"] == whole.metadata["n_dof"]
    np.testing.assert_allclose(split.frequencies_hz, whole.frequencies_hz, rtol=1e-9)


def test_class_mass_product_is_the_class_mass_matrix_product_bit_for_bit():
    (nodes, elements), material = _square_bar(n_cells=2, n_layers=8)
    split = mirror.mirror_split(nodes, elements, (1, 2))
    orthant = split.assemble(nodes, material)
    rng = np.random.default_rng(3)
    for c in split.classes:
        _, M_c = split.class_matrices(orthant, c)
        product = split.class_mass_product(split.weighted_node_mass(orthant), c)
        for X in (rng.standard_normal((len(c.dofs), 3)), np.asfortranarray(rng.standard_normal((len(c.dofs), 6)))):
            assert np.array_equal(product(X), M_c @ X)


def test_padded_class_factorization_solves_the_class_and_counts_its_inertia():
    """The class matrix padded to node blocks: its solves are the class's (against SciPy's own
    sparse solve) and its negative pivots the class's eigenvalues below the shift (against a
    dense generalized eigen-solve)."""
    import scipy.linalg
    import scipy.sparse.linalg

    from sensors.fem.direct_solver import available_solvers

    if "pardiso" not in available_solvers():
        pytest.skip("pardiso not installed")
    (nodes, elements), material = _square_bar()
    split = mirror.mirror_split(nodes, elements, (1, 2))
    orthant = split.assemble(nodes, material)
    n_full = 3 * len(split.orthant_nodes)
    rng = np.random.default_rng(4)
    for c in split.classes:
        assert len(c.dofs) < n_full  # every class here has padded dofs (on a mirror plane)
        K_c, M_c = split.class_matrices(orthant, c)
        lam = scipy.linalg.eigvalsh(K_c.toarray(), M_c.toarray())
        sigma = 0.5 * (lam[9] + lam[10])  # between two modes: 10 below (the rigid ones among them)
        fact = mirror.PaddedFactorization.shifted(K_c, M_c, sigma, c.dofs, n_full, "pardiso")
        assert fact.n_negative == 10
        B = rng.standard_normal((len(c.dofs), 3))
        expected = scipy.sparse.linalg.spsolve((K_c - sigma * M_c).tocsc(), B)
        np.testing.assert_allclose(fact.solve(B), expected, rtol=0, atol=1e-9 * np.abs(expected).max())
