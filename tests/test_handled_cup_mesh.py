"""The mug's structured mesh (a revolved cup with a swept D handle): one conforming solid of
genus one whose volume is the exact volume of the shape it stands for."""

import math

import numpy as np
import pytest
import scipy.integrate

from sensors.objects.everyday import surface_of, mug
from sensors.mesh.layered import handled_cup_mesh
from sensors.mesh.quadratic import quadratic_mesh
from sensors.mesh.tets import P2_EDGES, boundary_faces, check_tet_quality


@pytest.fixture(scope="module")
def cup():
    return mug()


def exact_volume_m3(d) -> float:
    """Cup minus cavity, plus two stubs (box minus the cylinder's cap) and a half annulus."""
    ro, ri, h, floor = d["outer_radius_m"], d["inner_radius_m"], d["height_m"], d["floor_m"]
    w, t, stub = d["handle_width_m"], d["handle_thickness_m"], d["handle_stub_m"]
    r_out = 0.5 * (d["handle_top_m"] - d["handle_bottom_m"])
    cap, _ = scipy.integrate.quad(lambda z: ro + stub - math.sqrt(ro ** 2 - z ** 2), -w / 2, w / 2)
    return (math.pi * ro ** 2 * h - math.pi * ri ** 2 * (h - floor) + 2 * t * cap
            + 0.5 * math.pi * (r_out ** 2 - (r_out - t) ** 2) * w)


@pytest.mark.parametrize("resolution", [1.0, 1.5])
def test_mesh_is_one_conforming_solid_with_a_handle_hole(cup, resolution):
    tm = cup.tet_mesh(resolution)
    check_tet_quality(tm.vertices_m, tm.tets)
    # A joint whose diagonals disagreed would leave its faces on the boundary: not watertight.
    surface = surface_of(tm)
    assert surface.is_watertight and surface.is_winding_consistent
    assert surface.euler_number == 0, "one hole through the handle: genus one"
    assert len(surface.split(only_watertight=False)) == 1
    # The joints reuse the wall's vertices: no two vertices coincide.
    rounded = np.round(tm.vertices_m / 1e-9).astype(np.int64)
    assert len(np.unique(rounded, axis=0)) == len(tm.vertices_m)
    # Every face is shared by two tets or lies on the surface.
    faces, _ = boundary_faces(tm.tets)
    assert len(faces) == len(surface.faces)


def test_volume_converges_to_the_exact_shape(cup):
    exact = exact_volume_m3(cup.dimensions_m)
    errors = [abs(cup.tet_mesh(r).volume_m3() / exact - 1) for r in (1.0, 1.5)]
    # Straight-sided (chordal) tets inside the curved wall: a little under (48 around: a 48-gon
    # holds 0.29 % less area than its circle), less when finer (72 around: 0.13 %).
    assert errors[0] < 3.5e-3 and errors[1] < 0.6 * errors[0]


def test_p2_nodes_on_the_joints_lie_on_the_wall_cylinder(cup):
    tm = cup.tet_mesh()
    nodes, tets10 = quadratic_mesh(tm)
    ro = cup.dimensions_m["outer_radius_m"]
    v = tm.vertices_m
    r_v = np.hypot(v[:, 1], v[:, 2])
    on = np.abs(r_v - ro) <= 1e-9 * ro
    # Joint edges: both ends on the wall's outer cylinder, in a tet that reaches into the handle.
    in_handle = (r_v[tets10[:, :4]] > ro * (1 + 1e-6)).any(axis=1)
    pairs = tets10[in_handle][:, P2_EDGES].reshape(-1, 2)
    mids = tets10[in_handle][:, 4:].reshape(-1)
    joint = on[pairs[:, 0]] & on[pairs[:, 1]]
    assert joint.sum() > 0
    r_mid = np.hypot(nodes[mids[joint], 1], nodes[mids[joint], 2])
    np.testing.assert_allclose(r_mid, ro, rtol=1e-12)  # curved like the wall, not on the chord


def test_handle_dimensions_are_checked():
    with pytest.raises(ValueError, match="stubs"):
        mug(handle_top_m=0.03, handle_bottom_m=0.025)
    with pytest.raises(ValueError, match="handle_width_m"):
        mug(handle_width_m=0.1)
    levels = np.linspace(0, 0.1, 11)
    with pytest.raises(ValueError, match="equal stub heights"):
        handled_cup_mesh(levels, 0.03, 0.035, 1, (2, 3, 6, 8), 0.1, 2, 0.005, 1, 8)
    with pytest.raises(ValueError, match="even"):
        handled_cup_mesh(levels, 0.03, 0.035, 1, (2, 3, 6, 7), 0.1, 3, 0.005, 1, 8)
