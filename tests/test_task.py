"""The grasp task's rules (``sensors.task``), MuJoCo-free: what an action means, the reward
terms, when a step records and when an episode succeeds, and the acoustic configuration."""

from __future__ import annotations

import numpy as np
import pytest

import sensors
from sensors.task import (GRASP_REWARD_TERMS, AcousticConfig, GraspHold, decode_grasp_action, grasp_reward_terms,
                          next_tcp_target, records_this_step, reward_total, step_success, tcp_object_distance_m)


def test_an_action_is_clipped_and_scaled_and_its_switches_open_at_zero():
    act = decode_grasp_action(np.array([0.5, -3.0, 1.0, 0.2, 0.0, 1e-6], np.float32))
    assert act.tcp_delta == pytest.approx((0.005, -0.01, 0.01, 0.01))
    assert not act.open_gripper and act.sense          # 0 closes; anything above 0 senses
    act = decode_grasp_action([0, 0, 0, 0, 1e-6, 0])
    assert act.open_gripper and not act.sense
    for bad in ([np.nan] + [0] * 5, [0] * 5, [[0] * 6] * 2):
        with pytest.raises(ValueError, match="action"):
            decode_grasp_action(np.array(bad, float))


def test_the_tcp_target_moves_by_the_delta_within_the_limits():
    assert next_tcp_target([0.0, 0.1, 0.3, 0.0], (0.01, -0.01, 0.01, 0.05)) == pytest.approx([0.01, 0.09, 0.31, 0.05])
    low, high = [-0.1, -0.1, 0.0, -1.0], [0.1, 0.1, 0.305, 1.0]
    assert next_tcp_target([0.095, -0.095, 0.3, 0.0], (0.01, -0.01, 0.01, 0.05), low, high) == \
        pytest.approx([0.1, -0.1, 0.305, 0.05])


def test_reward_terms_have_fixed_keys_and_sum_to_the_reward():
    rng = np.random.default_rng(0)
    for grasped, success in ((False, False), (True, False), (True, True)):
        tcp, obj = rng.normal(size=4), rng.normal(size=7)
        d = tcp_object_distance_m(tcp, obj)
        assert d == pytest.approx(np.linalg.norm(tcp[:3] - obj[:3]), rel=1e-15)
        terms = grasp_reward_terms(d, grasped, success)
        assert tuple(terms) == GRASP_REWARD_TERMS and all(type(v) is float for v in terms.values())
        assert reward_total(terms) == pytest.approx(-d + grasped + 10 * success, rel=1e-15)


def test_the_cadence_decides_what_a_step_records():
    assert records_this_step("every_step", False) and records_this_step("action", True)
    assert not records_this_step("action", False)
    assert not records_this_step("never", True) and not records_this_step("stream", True)


def test_success_needs_the_sense_action_the_grasp_and_the_cadence_s_evidence():
    for cadence, evidence in (("action", "recording_grasped"), ("stream", "heard_whole_period")):
        assert step_success(cadence, sense=True, grasped=True, **{evidence: True})
        assert not step_success(cadence, sense=True, grasped=True, **{evidence: False})
        assert not step_success(cadence, sense=False, grasped=True, **{evidence: True})
        assert not step_success(cadence, sense=True, grasped=False, **{evidence: True})
    for cadence in ("every_step", "never"):  # no decision to stop, or no sound: no success
        assert not step_success(cadence, sense=True, grasped=True, recording_grasped=True, heard_whole_period=True)


def test_a_whole_period_counts_from_the_end_of_the_step_that_first_saw_the_grasp():
    """Periods of 10 samples, steps of 4: samples [kP, (k+1)P) must all follow the step end
    at which the grasp was first reported, and a break in the grasp starts over."""
    hold = GraspHold(10)
    ends, grasped = [4, 8, 12, 16, 20, 24, 28, 32], [False, False, True, True, True, True, False, True]
    seen = []
    for end, g in zip(ends, grasped):
        hold.update(g, end)
        latest = end // 10 - 1                     # the latest complete period
        seen.append(hold.heard_whole_period(latest))
    # grasp first seen at the end of the step ending at 12 (it may have closed at 9):
    # period 1 = [10, 20) started before 12 -> not heard; period 2 = [20, 30) complete at
    # 30 would be, but the grasp broke at 28; after it, nothing.
    assert seen == [False] * 8
    hold.reset()
    for end in range(4, 44, 4):
        hold.update(True, end)
    assert hold.since_sample == 4 and hold.heard_whole_period(1) and not hold.heard_whole_period(0)
    assert not hold.heard_whole_period(-1)


def test_acoustic_config_cadence_in_effect_and_checks(tmp_path):
    assert AcousticConfig(enabled=False, cadence="every_step").active_cadence == "never"
    assert AcousticConfig(cadence="stream").active_cadence == "stream"
    with pytest.raises(ValueError, match="at least one excitation period"):
        AcousticConfig(duration_s=0.25)
    with pytest.raises(TypeError, match="leak"):
        AcousticConfig(leak=3)
    with pytest.raises(TypeError, match="FingertipModel"):
        AcousticConfig(fingertip={"grip_force_n": 1})
    cfg = AcousticConfig(excitation="impulse", duration_s=0.5)
    assert cfg.excitation == sensors.Excitation.impulse() and cfg.n_samples == 22050
    assert cfg == AcousticConfig.coerce({"excitation": sensors.Excitation.impulse(), "duration_s": 0.5})
    # a leak: equal by path, a loaded recording by identity (arrays have no truth value)
    ex = sensors.Excitation.by_name("linear")
    rec = sensors.LeakRecording(np.zeros(ex.period_samples), ex.sample_rate_hz, ex)
    assert AcousticConfig(leak=rec) == AcousticConfig(leak=rec) != AcousticConfig(leak=sensors.LeakRecording(
        np.zeros(ex.period_samples), ex.sample_rate_hz, ex))
    assert AcousticConfig(leak=tmp_path / "a.npz") == AcousticConfig(leak=str(tmp_path / "a.npz"))
    assert isinstance(hash(AcousticConfig(leak={"linear": rec})), int)


def test_the_task_modules_need_no_mujoco():
    import subprocess
    import sys

    code = "import sys, sensors.task, real.env; print('mujoco' in sys.modules, 'aas_gym' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]
