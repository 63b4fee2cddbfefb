"""``info`` that explains itself (success, ground truth, reward terms), the timing metadata of
the probe envs, ``copy.deepcopy`` of an env, and the documented count of registered envs."""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.envs.base import PROBE_RENDER_FPS

ROOT = Path(__file__).resolve().parent.parent
OFF = {"acoustic": {"enabled": False}}

# env id, kwargs, the ground-truth keys of a step's info
CASES = [
    ("AcousticGrasp-v0", {"acoustic": {"cadence": "never"}}, ("label", "distance_m", "grasped")),
    ("GraspPosition-v0", OFF, ("label", "grasp_position_m", "position_index", "abs_error_m")),
    ("ObjectRecognition-v0", OFF, ("label", "label_index")),
    ("ContactFormation-v0", OFF, ("label", "formation", "formation_index")),
    ("FillLevel-v0", OFF, ("label", "fill_fraction", "liquid", "abs_error")),
]


@pytest.mark.parametrize("env_id, kwargs, truth", CASES, ids=[c[0] for c in CASES])
def test_step_info_has_success_truth_and_reward_terms(env_id, kwargs, truth):
    env = gym.make(f"aas_gym/{env_id}", **kwargs)
    try:
        env.reset(seed=1)
        env.action_space.seed(1)
        names = env.unwrapped.reward_term_names
        assert names
        for _ in range(3):
            _, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert type(info["is_success"]) is bool
            assert set(truth) <= set(info)
            assert tuple(info["reward_terms"]) == names
            assert math.isclose(sum(info["reward_terms"].values()), reward, abs_tol=1e-12)
            if terminated or truncated:
                env.reset()
    finally:
        env.close()


def test_success_means_what_the_docs_say():
    env = gym.make("aas_gym/GraspPosition-v0", **OFF)
    try:
        u = env.unwrapped
        _, info = env.reset(seed=2, options={"position_index": 4})
        true_m = info["grasp_position_m"]
        # the action that names the true position exactly, then one a whole spacing off
        for offset_m, success in ((0.0, True), (u.spacing_m, False)):
            env.reset(seed=2, options={"position_index": 4})
            target_m = true_m + offset_m
            action = np.array([target_m / u.positions_m[-1] * 2 - 1], np.float32)
            _, _, _, _, step_info = env.step(action)
            assert step_info["abs_error_m"] == pytest.approx(offset_m, abs=1e-6)
            assert step_info["is_success"] is success
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["GraspPosition-v0", "ObjectRecognition-v0", "FillLevel-v0"])
def test_probe_envs_have_no_control_period(env_id):
    env = gym.make(f"aas_gym/{env_id}", **OFF)
    try:
        assert not hasattr(env.unwrapped, "dt")
        assert env.unwrapped.metadata["render_fps"] == PROBE_RENDER_FPS
    finally:
        env.close()


def test_control_envs_keep_their_period():
    env = gym.make("aas_gym/AcousticGrasp-v0", **OFF)
    try:
        assert env.unwrapped.dt == pytest.approx(0.002 * 25)
        assert env.unwrapped.metadata["render_fps"] == 20
    finally:
        env.close()


def test_deepcopy_after_reset_gives_an_independent_equal_env():
    env = gym.make("aas_gym/GraspPosition-v0", objects=["wood_bar"])
    try:
        obs, _ = env.reset(seed=0)
        twin = copy.deepcopy(env)  # recursed forever in MaterialView.__getattr__
        action = np.array([0.1], np.float32)
        a, b = env.step(action), twin.step(action)
        assert a[1] == b[1] and a[4]["grasp_position_m"] == b[4]["grasp_position_m"]
        assert twin.unwrapped.sensor is not env.unwrapped.sensor
        twin.close()
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["AcousticGrasp-v0", "ObjectRecognition-v0", "ContactFormation-v0", "FillLevel-v0"])
def test_every_env_deepcopies_after_reset_and_steps_alike(env_id):
    env = gym.make(f"aas_gym/{env_id}")
    try:
        env.reset(seed=0)
        twin = copy.deepcopy(env)
        env.action_space.seed(0)
        action = env.action_space.sample()
        a, b = env.step(action), twin.step(action)
        assert a[1] == b[1]
        for key in a[0]:
            np.testing.assert_array_equal(a[0][key], b[0][key])
        twin.close()
    finally:
        env.close()


def test_documented_env_count_matches_the_registry():
    ids = sorted(k for k in gym.registry if k.startswith("aas_gym/"))
    words = {3: "three", 4: "four", 5: "five", 6: "six", 7: "seven"}
    text = (ROOT / "docs" / "envs.md").read_text()
    said = re.search(r"`import aas_gym` registers (\w+) environments", text)
    assert said and said.group(1) == words[len(ids)], (said and said.group(1), ids)
    for env_id in ids:
        assert env_id.removeprefix("aas_gym/") in text[:600]
        assert f"``{env_id}``" in aas_gym.__doc__


def _bodies_in_frame(env, camera: str) -> set[str]:
    """Names of the bodies whose geoms cover a pixel of ``camera``'s image (segmentation)."""
    import mujoco

    u = env.unwrapped
    renderer = mujoco.Renderer(u.model, 240, 320)
    try:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(u.data, camera=camera)
        seg = renderer.render()
    finally:
        renderer.close()
    geoms = np.unique(seg[..., 0][seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)])
    return {mujoco.mj_id2name(u.model, mujoco.mjtObj.mjOBJ_BODY, int(u.model.geom_bodyid[g])) for g in geoms}


@pytest.mark.parametrize("robot", ["floating_hand", "panda"])
def test_acoustic_grasp_default_camera_shows_the_hand_and_the_object_at_reset(robot):
    env = gym.make("aas_gym/AcousticGrasp-v0", robot=robot, render_mode="rgb_array", width=320, height=240, **OFF)
    try:
        env.reset(seed=0)
        assert env.unwrapped.camera_name == "workspace"
        assert env.render().shape == (240, 320, 3)
        seen = _bodies_in_frame(env, env.unwrapped.camera_name)
        assert {"hand", "left_fingertip", "right_fingertip", "aluminium_bar"} <= seen, seen
        assert "hand" not in _bodies_in_frame(env, "closeup")  # the old default missed the hand
    finally:
        env.close()


def _contacts(n: int):
    from aas_gym.contacts import ObjectContacts

    rng = np.random.default_rng(n)
    forces = rng.permutation(n).astype(float)
    return ObjectContacts("bar", rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), forces, rng.normal(size=(n, 3)),
                          np.full(n, 0.5), np.zeros(n), np.array(["table"] * n), np.array([f"b{i}" for i in range(n)]),
                          np.array([f"g{i}" for i in range(n)]))


def test_padded_contacts_have_fixed_shapes_and_keep_the_strongest():
    from aas_gym.envs.info import MAX_INFO_CONTACTS, padded_contacts

    few, many = _contacts(3), _contacts(MAX_INFO_CONTACTS + 6)
    a, b = padded_contacts(few), padded_contacts(many)
    for key in a:
        assert np.shape(a[key]) == np.shape(b[key])
    assert (a["n_contacts"], a["n_dropped"]) == (3, 0)
    np.testing.assert_array_equal(a["positions_m"][:3], few.positions_m)
    assert not a["positions_m"][3:].any() and list(a["kinds"][3:]) == [""] * (MAX_INFO_CONTACTS - 3)
    assert (b["n_contacts"], b["n_dropped"]) == (MAX_INFO_CONTACTS, 6)
    # the six weakest (forces 0..5) are the ones left out
    assert sorted(b["normal_forces_n"]) == list(range(6, MAX_INFO_CONTACTS + 6))
    kept = np.isin(many.normal_forces_n, b["normal_forces_n"])
    np.testing.assert_array_equal(b["positions_m"], many.positions_m[kept])  # rows in their original order
