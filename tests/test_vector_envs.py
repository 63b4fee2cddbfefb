"""Every env under ``gym.make_vec``: each ``info`` entry stacks across the envs, through
episodes whose contact counts differ between the envs (the padded contacts of
``aas_gym.envs.info``), and the modal models are shared by the envs of a sync vector env.

Step counts (vector steps of 2 envs) keep the file near half a minute on an idle 2-core machine:
AcousticGrasp-v0 and ContactFormation-v0 run 1,200 env steps each (the crash of the unpadded
contacts needed about 4,000 only because it waited for two envs with different contact counts
in one step: the multi-object scene gives them within tens of steps, and the test asserts that
it happened); the probe envs (each step or reset a scripted grasp, FillLevel-v0 a new fill) run
tens of episodes.
"""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.envs.info import MAX_INFO_CONTACTS

ROOT = Path(__file__).resolve().parent.parent
OFF = {"acoustic": {"enabled": False}}

# env id, make kwargs, vector steps of 2 envs
CASES = [
    # multi: distractors lean on the target, so its contact count differs from env to env;
    # cadence "action": random actions record about every other step, each adding contacts
    ("AcousticGrasp-v0", {"scene": "multi"}, 600),
    ("ContactFormation-v0", OFF, 600),
    ("GraspPosition-v0", {"scene": "multi", **OFF}, 40),
    ("ObjectRecognition-v0", {"scene": "multi", **OFF}, 30),
    ("FillLevel-v0", OFF, 6),
]


def _contact_counts(info: dict) -> list[np.ndarray]:
    """The ``n_contacts`` arrays (one entry per env) of every body in a stacked info."""
    contacts = info.get("contacts", {})
    return [np.asarray(c["n_contacts"])[np.asarray(contacts[f"_{body}"])] for body, c in contacts.items()
            if not body.startswith("_")]


def _run(venv, steps: int) -> dict:
    venv.action_space.seed(0)
    obs, info = venv.reset(seed=0)
    seen = {"counts": set(), "differ": False, "success": 0, "steps": 0}

    def note(info):
        for n in _contact_counts(info):
            seen["counts"].update(n.tolist())
            seen["differ"] |= len(set(n.tolist())) > 1
        assert all(0 <= int(n.max(initial=0)) <= MAX_INFO_CONTACTS for n in _contact_counts(info))

    note(info)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = venv.step(venv.action_space.sample())
        assert venv.observation_space.contains(obs)
        note(info)
        mask = info.get("_is_success", np.zeros(venv.num_envs, bool))
        seen["success"] += int(np.sum(np.asarray(info.get("is_success", np.zeros(venv.num_envs)))[mask]))
        seen["steps"] += venv.num_envs
    return seen


@pytest.mark.parametrize("env_id, kwargs, steps", CASES, ids=[c[0] for c in CASES])
def test_every_info_entry_stacks_under_make_vec_sync(env_id, kwargs, steps):
    venv = gym.make_vec(f"aas_gym/{env_id}", num_envs=2, vectorization_mode="sync", **kwargs)
    try:
        seen = _run(venv, steps)
    finally:
        venv.close()
    assert seen["steps"] == 2 * steps
    if env_id != "ContactFormation-v0":  # it reports no contacts, only its formation
        # the case that crashed before padding: two envs with different contact counts in one step
        assert seen["differ"] and len(seen["counts"]) > 1, seen["counts"]


def test_async_vector_env_stacks_acoustic_grasp_info():
    # the workers import this checkout (not the venv's editable install) through PYTHONPATH
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), old) if p)
    try:
        venv = gym.make_vec("aas_gym/AcousticGrasp-v0", num_envs=2, vectorization_mode="async", scene="multi")
        try:
            seen = _run(venv, 300)
        finally:
            venv.close()
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH")
        else:
            os.environ["PYTHONPATH"] = old
    assert seen["steps"] == 600 and seen["differ"]


def test_sync_vector_env_shares_modal_models():
    from aas_gym.sim_sensor import MODAL_MODELS

    venv = gym.make_vec("aas_gym/GraspPosition-v0", num_envs=2, vectorization_mode="sync")
    try:
        venv.reset(seed=0)
        a, b = (e.unwrapped for e in venv.envs)
        body = a.sensor.bodies[0]
        assert a.sensor is not b.sensor  # each env its own scene and sensor ...
        assert a.sensor.modal_model(body) is b.sensor.modal_model(body)  # ... one modal model
        assert a.sensor.models is b.sensor.models is MODAL_MODELS
    finally:
        venv.close()
