"""Issue 31, sensor side: every input checked before work starts, every cost bounded.

Each test reproduces one fault of the fault-injection pass. Builds that must not start are
replaced by a function that fails the test, so a check that comes too late fails fast here.
"""

import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh

from sensors._infra import atomic, cache as cache_mod
from sensors.fluid import filled
from sensors.fluid.cavity import AxisymmetricCavity, cavity_of
from sensors.mesh import surface as surface_mod, tets as tets_mod
from sensors.mesh.surface import MeshScaleError, MeshSeveralBodiesError, MeshTooLargeError, check_surface
from sensors.mesh.tets import MeshError
from sensors.modal.contact import Contact
from sensors.objects.catalog import ObjectSpec, get_object
from sensors.signals.excitation import Excitation
from sensors.signals.features import spectral_features


# ---------------------------------------------------------------- 1. cost bounded before work

def test_wall_thickness_check_casts_a_bounded_number_of_ray_face_pairs(monkeypatch, caplog):
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.05)  # 20,480 faces
    n_faces = len(sphere.faces)
    batches = []
    cast = type(sphere.ray).intersects_id

    def counting(self, origins, directions, **kwargs):
        batches.append(len(origins))
        return cast(self, origins, directions, **kwargs)

    monkeypatch.setattr(type(sphere.ray), "intersects_id", counting)
    with caplog.at_level("INFO", logger="sensors.mesh.surface"):
        thickness = surface_mod.min_thickness_m(sphere)
    assert thickness == pytest.approx(0.1, rel=2e-3)  # a solid ball: its diameter
    assert sum(batches) * n_faces <= surface_mod.THICKNESS_RAY_FACE_PAIRS
    assert max(batches) * n_faces <= 2_000_000  # memory: one batch's candidate arrays
    assert "rays instead of" in caplog.text  # it says what it did


def test_a_surface_above_the_face_limit_is_refused_at_once():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.05)  # 1,280 faces
    with pytest.raises(MeshTooLargeError, match=r"1,280 faces, above the limit of 1,000.*MAX_SURFACE_FACES"):
        check_surface(sphere, max_faces=1000)
    assert surface_mod.MAX_SURFACE_FACES >= 30_000  # the shipped containers' surfaces pass


def test_the_liquid_mesh_size_is_refused_before_the_container_is_built(no_build):
    with pytest.raises(MeshTooLargeError, match=r"up to [\d,]+ nodes.*limit of 200,000.*liquid_element_size_m"):
        filled("mug", 0.5, liquid_element_size_m=1e-5)
    cav = cavity_of(get_object("mug").solid())
    # The estimate bounds the mesh it guards (here a coarse one, built for real).
    built = cav.liquid_mesh(0.9 * cav.volume_m3, cav.upright_up, element_size_m=0.004)
    assert len(built.nodes_m) <= cav.liquid_mesh_nodes(16, 0.004) <= 1.3 * len(built.nodes_m)


def test_one_max_dof_default():
    assert surface_mod.DEFAULT_MAX_DOF == tets_mod.DEFAULT_MAX_DOF == 300_000
    surface_mod.check_dof(250_000, None, "a model")  # below the one default: allowed


# ---------------------------------------------------------------- 2. inputs checked before the build

def test_a_fill_out_of_range_or_an_object_without_cavity_is_refused_before_building(no_build):
    with pytest.raises(ValueError, match=r"fill_fraction must be in \[0, 1\], got 1.5"):
        filled("mug", 1.5)
    with pytest.raises(TypeError, match="not a container"):
        filled("spoon", 0.5)
    assert not no_build.exists() or not any(no_build.glob("*.npz"))


def two_boxes():
    a = trimesh.creation.box((0.03, 0.03, 0.03))
    b = trimesh.creation.box((0.03, 0.03, 0.03))
    b.apply_translation((0.06, 0.0, 0.0))
    return trimesh.util.concatenate([a, b])


def test_a_two_body_mesh_is_refused_by_from_mesh_and_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "two.obj"
    two_boxes().export(path)
    with pytest.raises(MeshSeveralBodiesError, match="2 separate closed shells"):
        get_object(f"{path}:steel")
    with pytest.raises(MeshSeveralBodiesError):
        ObjectSpec.from_mesh(two_boxes(), "steel", name="two")
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").glob("*.npz"))


# ---------------------------------------------------------------- 3. types and values

def test_booleans_are_not_numbers():
    with pytest.raises(TypeError, match="fill_fraction must be a number"):
        filled("mug", True)
    with pytest.raises(MeshScaleError, match="scale must be a positive number"):
        check_surface(trimesh.creation.box((0.03, 0.03, 0.03)), scale=True)
    with pytest.raises(TypeError, match="force_n"):
        Contact((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), True, 0.5)


@pytest.mark.parametrize("options, message", [
    (dict(correction_degree=-3), "correction_degree must be in"),
    (dict(correction_degree=2.5), "correction_degree must be a whole number"),
    (dict(liquid_n_theta=0), "liquid_n_theta must be in"),
    (dict(liquid_n_theta=12), "liquid_n_theta must be a multiple of 8"),
    (dict(liquid_element_size_m=float("nan")), "liquid_element_size_m must be finite"),
])
def test_container_options_are_checked_before_building(no_build, options, message):
    with pytest.raises(ValueError, match=message):
        filled("mug", 0.5, **options)


def test_huge_periods_and_points_give_clear_errors():
    with pytest.raises(ValueError, match="above the limit"):
        Excitation.impulse(period_s=1e308)
    with pytest.raises(ValueError, match="recording too short"):
        spectral_features(np.zeros(44100), period_s=1e308)
    from sensors.modal.basis import check_points_m

    with pytest.raises(ValueError, match="beyond"):
        check_points_m([[1e308, 0.0, 0.0]])
    with pytest.raises(TypeError, match="points_m must be numbers"):
        check_points_m([["0.1", "0", "0"]])


def tilted(cav: AxisymmetricCavity, degrees: float) -> np.ndarray:
    side = np.cross(cav.axis, (0.3, 0.5, 0.8))
    side /= np.linalg.norm(side)
    t = math.radians(degrees)
    return math.cos(t) * cav.axis + math.sin(t) * side


def test_small_tilted_and_tiny_upright_fills_say_what_is_wrong():
    cav = cavity_of(get_object("mug").solid())
    for fraction in (1e-9, 1e-3):  # scipy's "f(a) and f(b) must have different signs" before
        with pytest.raises(MeshError, match="leaves part of the bottom dry at this tilt"):
            cav.liquid_mesh(fraction * cav.volume_m3, tilted(cav, 55))
    with pytest.raises(MeshError, match="too little liquid") as refused:
        cav.liquid_mesh(1e-9 * cav.volume_m3, cav.upright_up)
    assert "tilt" not in str(refused.value)


def test_a_nan_vertex_in_a_file_is_reported_as_such(tmp_path):
    box = trimesh.creation.box((0.05, 0.05, 0.05))
    v = box.vertices.copy()
    v[0, 0] = np.nan
    path = tmp_path / "nan.obj"
    path.write_text("".join(f"v {a} {b} {c}\n" for a, b, c in v)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in box.faces))
    with pytest.raises(MeshError, match="non-finite"):
        get_object(f"{path}:steel")


def test_from_mesh_without_a_name(tmp_path, monkeypatch):
    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))
    spec = ObjectSpec.from_mesh(trimesh.creation.box((0.04, 0.03, 0.02)), "steel")
    assert spec.name.startswith("mesh-") and spec.label == f"steel_{spec.name}"
    assert ObjectSpec.from_text(spec.to_text()) == spec


# ---------------------------------------------------------------- 4. leftovers of killed writers

def test_a_killed_writers_temporary_files_are_removed_on_the_next_write(tmp_path):
    folder = tmp_path / "cache"
    folder.mkdir()
    # A writer killed with -9 while writing (its pid gone), as atomic_open names the file.
    code = ("import os, sys; sys.path.insert(0, sys.argv[2]); from sensors._infra.atomic import atomic_open\n"
            "with atomic_open(os.path.join(sys.argv[1], 'k.npz')) as fh:\n"
            "    fh.write(b'half'); fh.flush(); os.kill(os.getpid(), 9)\n")
    subprocess.run([sys.executable, "-c", code, str(folder), os.getcwd()], check=False)
    killed = list(folder.glob(".k.npz.*.tmp"))
    assert len(killed) == 1
    old = folder / ".old.npz.abc123.tmp"  # no pid in its name, older than any write
    old.write_bytes(b"x")
    os.utime(old, (time.time() - 2 * atomic.STALE_TEMP_AGE_S,) * 2)
    live = folder / f".live.npz.{os.getppid()}.abc123.tmp"  # a live writer's: kept
    live.write_bytes(b"x")
    cache_mod.save_arrays("fresh", {"a": np.arange(3)}, folder)
    assert not killed[0].exists() and not old.exists()
    assert live.exists()
    assert cache_mod.load_arrays("fresh", folder)["a"].tolist() == [0, 1, 2]


# ---------------------------------------------------------------- 5. one solid, one mass

def test_a_shell_inside_a_shell_is_refused():
    outer = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    inner = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    inner.invert()  # a hollow ball: the inner shell faces the void
    with pytest.raises(MeshSeveralBodiesError, match="a shell inside another"):
        check_surface(trimesh.util.concatenate([outer, inner]))


@pytest.mark.parametrize("liquid, error", [(True, TypeError), (None, TypeError), (1e300, ValueError),
                                           (float("nan"), ValueError), (-1000.0, ValueError)])
def test_a_liquid_is_a_name_a_plausible_density_or_a_liquid(liquid, error):
    from sensors.materials import get_liquid

    with pytest.raises(error, match="liquid"):
        get_liquid(liquid)
    assert get_liquid(1000.0).density_kg_m3 == 1000.0 and get_liquid(" Water").name == "water"
