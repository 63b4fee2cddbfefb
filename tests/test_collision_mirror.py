"""CoACD on a half or quarter of a mirror-symmetric solid (issue 30): the mirror planes found are
the solid's, and the mirrored pieces cover the whole solid."""

import manifold3d
import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from aas_gym.collision import decompose, mirror_planes
from convex_coverage import coverage
from sensors.objects import get_object


def test_the_mirror_planes_of_an_offset_box_are_its_three_mid_planes():
    box = trimesh.creation.box([0.03, 0.02, 0.01])
    box.apply_translation([0.1, 0.2, 0.3])
    planes = mirror_planes(box.vertices, box.faces)
    assert [axis for axis, _ in planes] == [0, 1, 2]
    assert [offset for _, offset in planes] == pytest.approx([0.1, 0.2, 0.3], abs=1e-12)


def test_a_chamfered_corner_leaves_only_the_plane_it_does_not_cross():
    box = manifold3d.Manifold.cube([0.04, 0.03, 0.02], center=True).trim_by_plane([-1.0, -1.0, 0.0], -0.02)
    mesh = box.to_mesh()
    planes = mirror_planes(np.asarray(mesh.vert_properties[:, :3], float), np.asarray(mesh.tri_verts))
    assert [axis for axis, _ in planes] == [2]  # the chamfer runs along z: the z mid-plane still mirrors it


def test_mirrored_vertices_alone_do_not_make_a_mirror_plane():
    # The spoon's vertices mirror onto vertices about y = 0, but its bowl's non-planar quads are split
    # along one diagonal only, so the mirrored solid is a different solid.
    spoon = get_object("spoon").solid().surface
    v = np.asarray(spoon.vertices)
    mirrored = v * [1.0, -1.0, 1.0]
    assert cKDTree(v).query(mirrored)[0].max() < 1e-12
    assert 1 not in [axis for axis, _ in mirror_planes(spoon.vertices, spoon.faces)]


def test_the_pieces_of_a_mirrored_box_are_mirror_images_that_cover_it():
    box = get_object("box").solid().surface
    planes = mirror_planes(box.vertices, box.faces)
    assert [axis for axis, _ in planes] == [1, 2]  # open along x: mirrored about its two side mid-planes
    pieces = decompose(box.vertices, box.faces)
    keys = {tuple(np.round(np.sort(p, axis=0), 9).ravel()) for p in pieces}
    for axis, offset in planes:
        for piece in pieces:
            image = piece.copy()
            image[:, axis] = 2 * offset - image[:, axis]
            assert tuple(np.round(np.sort(image, axis=0), 9).ravel()) in keys
    lo, hi = box.bounds
    points = np.random.default_rng(2).uniform(lo, hi, size=(4000, 3))
    inside = points[box.contains(points)]
    covered, volume = coverage(pieces, inside)
    assert covered > 0.99
    assert volume < 1.1 * box.volume, "the walls' pieces do not close the box's cavity"
