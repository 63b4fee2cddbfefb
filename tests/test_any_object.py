"""Any object in the scenes: a mesh nobody in the project made, the everyday set, bad meshes.

The mesh is built here from trimesh primitives (a 30 mm square post with a round 40 mm cap),
written to an STL file and named to ``get_object`` as ``<file>:<material>``, as a user would.
"""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import trimesh

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.grasp import Hand, planar_grasp
from aas_gym.scenario import DomainRandomization, place_objects, settle, target_grasp
from aas_gym.object_bodies import object_specs_from_model
from aas_gym.object_grasps import grasp_span_m
from aas_gym.scene import build_scene
from sensors.mesh.tets import MeshError
from sensors.objects import ObjectSpec, get_object


def _post() -> trimesh.Trimesh:
    body = trimesh.creation.box((0.03, 0.03, 0.12))
    cap = trimesh.creation.cylinder(0.02, 0.05)
    cap.apply_translation((0.0, 0.0, 0.07))
    return trimesh.boolean.union([body, cap], engine="manifold")


@pytest.fixture(scope="module")
def post_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("user") / "post.stl"
    _post().export(path)
    return path


def test_a_foreign_mesh_goes_through_get_object_into_gym_make_and_passes_check_env(post_file):
    from gymnasium.utils.env_checker import check_env

    spec = get_object(f"{post_file}:aluminium")
    assert spec.label == "aluminium_post" and spec.shape == "mesh"
    # The scene describes it by its stored surface: a fresh lookup finds the same object.
    assert object_specs_from_model(build_scene([spec]))["aluminium_post"] == spec
    env = gym.make("aas_gym/GraspPosition-v0", objects=[f"{post_file}:aluminium"], n_positions=4, spacing_m=0.005,
                   acoustic={"duration_s": 0.5})
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert info["grasp_success"] and info["recording_grasped"]
    assert np.abs(obs["acoustic"]).max() > 0
    env.close()


def _grasp_and_hold(spec: ObjectSpec, position_m: float, grip_force_n: float = 40.0):
    model = build_scene([spec])
    data = mujoco.MjData(model)
    hand = Hand(model)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, spec.label)
    joint = model.body_jntadr[bid]
    joints = [(int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint]))]
    layout = place_objects(model, data, [spec], joints, np.random.default_rng(0), DomainRandomization.off())
    settle(model, data)
    grasp = target_grasp(spec, position_m, layout)
    result = planar_grasp(model, data, spec.label, position_m, grip_force_n, hand=hand, grasp=grasp, lift_m=0.02)
    before = data.xmat[bid].reshape(3, 3).T @ (data.site_xpos[hand.tcp_site] - data.xpos[bid])
    mujoco.mj_step(model, data, nstep=int(round(1.0 / model.opt.timestep)))  # a 1 s recording, held up
    after = data.xmat[bid].reshape(3, 3).T @ (data.site_xpos[hand.tcp_site] - data.xpos[bid])
    return result, float(np.linalg.norm(after - before)), float(data.xpos[bid][2])


@pytest.mark.parametrize("name", ["post", "l_bracket"])
def test_grasp_forces_settle_at_the_grip_force_and_the_object_does_not_slip(post_file, name):
    spec = get_object(f"{post_file}:aluminium") if name == "post" else get_object(name)
    lo, hi = grasp_span_m(spec)
    for position in (lo, 0.5 * (lo + hi), hi):
        result, slip_m, _ = _grasp_and_hold(spec, position)
        assert result.success and result.settled
        # Each pad presses with the commanded force (thin walls included: the bracket's 3 mm flange).
        assert result.actuator_force_n == pytest.approx(40.0, rel=0.05)
        assert result.mic_force_n == pytest.approx(40.0, rel=0.05)
        assert slip_m < 0.5e-3, f"{spec.label} at {position * 1e3:.1f} mm moved {slip_m * 1e3:.2f} mm in the hand"


def test_everyday_names_and_materials():
    assert get_object("mug") == get_object("ceramic_mug") == ObjectSpec("mug", "ceramic")
    steel_mug = get_object("steel_mug")
    assert steel_mug.label == "steel_mug" and steel_mug.solid().material.name == "steel"
    assert get_object("l_bracket").label == "aluminium_l_bracket"
    assert ObjectSpec.from_text(steel_mug.to_text()) == steel_mug
    with pytest.raises(ValueError, match="unknown shape 'sphere'"):
        get_object("steel_sphere")
    with pytest.raises(ValueError, match="needs its material"):
        get_object("part.stl")


def _bad_meshes():
    box = trimesh.creation.box((0.04, 0.03, 0.02))
    open_box = box.copy()
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)
    inverted = box.copy()
    inverted.invert()
    degenerate = trimesh.Trimesh(np.r_[box.vertices, [[0.0, 0.0, 0.0]]],
                                 np.r_[box.faces, [[0, 0, 8]]], process=False)
    tiny = trimesh.creation.box((0.001, 0.001, 0.001))
    huge = trimesh.creation.box((1.0, 0.04, 0.04))
    return {"open": (open_box, "watertight"), "inverted": (inverted, "inside out"),
            "degenerate": (degenerate, "zero-area"), "1 mm": (tiny, "scale="), "1 m": (huge, "larger than the hand")}


@pytest.mark.parametrize("case", list(_bad_meshes()))
def test_bad_meshes_give_a_clear_error_and_leave_nothing_in_the_cache(tmp_path, monkeypatch, case):
    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))
    mesh, words = _bad_meshes()[case]
    with pytest.raises(MeshError, match=words):
        ObjectSpec.from_mesh(mesh, "abs", name="bad")
    cache = tmp_path / "cache"
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))


def test_a_mesh_the_hand_cannot_grasp_is_refused_before_its_scene_is_built(tmp_path, monkeypatch):
    monkeypatch.setenv("AAS_GYM_CACHE", str(tmp_path / "cache"))
    block = trimesh.creation.box((0.12, 0.12, 0.05))  # 120 mm across both ways: wider than the 80 mm hand
    spec = ObjectSpec.from_mesh(block, "wood", name="block")  # a sound solid: the catalog keeps it
    with pytest.raises(MeshError, match="no antipodal grasp"):
        build_scene([spec])
    with pytest.raises(MeshError, match="no antipodal grasp"):
        grasp_span_m(spec)
    # Only its checked surface is stored: no grasps, no collision pieces.
    written = [p.name for p in (tmp_path / "cache").rglob("*") if p.is_file()]
    assert len(written) == 1 and written[0].startswith("surface-")


def test_a_missing_or_foreign_mesh_file_says_so(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        get_object(f"{tmp_path / 'nothing.stl'}:abs")
    junk = tmp_path / "junk.stl"
    junk.write_bytes(b"\x00\x01 not a mesh at all" * 3)
    with pytest.raises((MeshError, ValueError)):
        get_object(f"{junk}:abs")
