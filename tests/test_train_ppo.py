"""examples/train_ppo.py: its action re-expression decodes to what it claims, and a tiny budget
runs end to end and writes its log, policy and figure."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "examples" / "train_ppo.py"


def _load_script():
    spec = importlib.util.spec_from_file_location("train_ppo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_discrete_actions_probe_then_answer_with_the_chosen_position_excitation_and_label():
    train_ppo = _load_script()
    env = train_ppo.make_env("ObjectRecognition-v0")
    base = env.unwrapped
    assert list(env.action_space.nvec) == [len(train_ppo.PROBE_POSITIONS), 3, 7]
    for probes_done, command in ((0, 0), (1, 1)):  # one probe, then the answer
        env.probes_done = probes_done
        for p, fraction in enumerate(train_ppo.PROBE_POSITIONS):
            for e in range(3):
                for label in range(7):
                    decoded = base.decode_action(env.action(np.array([p, e, label])))
                    assert decoded[0] == command and decoded[2] == e and decoded[3] == label
                    assert decoded[1] == pytest.approx(fraction)
    env.close()


def test_tiny_budget_writes_log_policy_and_figure(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    figure = tmp_path / "curves.png"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--env", "GraspPosition-v0", "--minutes", "0.05",
                           "--eval-episodes", "4", "--eval-every", "128", "--out", str(tmp_path),
                           "--figure", str(figure)], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    log = json.loads((tmp_path / "ppo_GraspPosition-v0.json").read_text())
    assert log["steps"] >= 8 and len(log["evaluations"]) >= 2
    final = log["evaluations"][-1]
    assert len(final["estimates_m"]) == 4
    # every estimate lies on the action's span, 0 .. 60 mm, so the RMSE cannot exceed 60 mm
    assert all(0.0 <= x <= 0.060 + 1e-9 for x in final["estimates_m"])
    assert 0.0 < final["rmse_mm"] <= 60.0
    assert (tmp_path / "ppo_GraspPosition-v0.zip").stat().st_size > 0
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
