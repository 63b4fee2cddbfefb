"""Passive sound in a MuJoCo scene (issue 26, item 4): the contact datastream hands the stream
every contact's force, and a knock on the table is heard while a still grasp is not changed."""

import mujoco
import numpy as np
import pytest

from aas_gym.grasp import Hand, planar_grasp
from aas_gym.scenario import settle
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from aas_gym.sim_stream import SimAcousticStream, span_bounds
from sensors import PassiveSound
from sensors.task import AcousticConfig

STEP = 2205


def _held():
    m = build_scene(["aluminium_bar"], contact_signature=True)
    d = mujoco.MjData(m)
    sensor = SimAcousticSensor(m, d, on_no_grasp="silence")
    hand = Hand(m)
    settle(m, d, 0.3)
    assert planar_grasp(m, d, sensor.bodies[0], 0.02, 40.0, hand=hand).success
    return m, d, sensor, hand


def _run(passive):
    """Hold, lift 2 cm, bring the bar down at once onto the table (the knock), hold."""
    m, d, sensor, hand = _held()
    stream = SimAcousticStream(sensor, "linear", rng=0, passive=passive)
    home = hand.tcp(d).copy()
    out, states = [], []
    spans = np.diff(span_bounds(STEP, 25))
    for dz, steps in ((0.0, 6), (0.02, 10), (-0.002, 10)):
        hand.command(d, tcp=home + np.array([0, 0, dz, 0]))
        for _ in range(steps):
            samples = []
            for n in spans:                      # physics step by physics step: every read seen
                samples.append(stream.step_physics(1, int(n)))
                states.append(stream.grasp_state())
            out.append(np.concatenate(samples))
    return np.array(out, dtype=float), states, stream


def test_a_knock_is_heard_and_a_still_grasp_is_not_changed():
    on, states, stream = _run(PassiveSound())
    off, _, _ = _run(None)
    diff = np.abs(on - off).max(axis=1)
    assert np.all(np.isfinite(on))
    # the first steps: the grasp is still, its loads are the reference: the same samples
    assert np.all(diff[:6] == 0.0)
    # the knock (the table contact comes back) is heard: a step with an impact contact
    impacts = [i for i, g in enumerate(states) if g.loads is not None and g.loads.impact.any() and i >= 16 * 25]
    assert impacts, "the bar never touched the table again"
    k = impacts[0] // 25                         # the env step of the knock
    assert diff[k] > 1e-3 * np.abs(off).max()
    loads = states[k].loads
    # the table's forces carry friction: not all along the normals
    assert np.abs(loads.friction_n()).max() > 0
    assert stream.metadata["passive"]["rise_time_s"] == PassiveSound().rise_time_s


@pytest.mark.parametrize("cadence,passive", [("stream", True), ("action", False)])
def test_passive_sound_is_on_when_streaming_by_default(cadence, passive):
    cfg = AcousticConfig(cadence=cadence)
    assert (cfg.passive is not None) == passive
    assert AcousticConfig(cadence="stream", passive_sound=False).passive is None
    assert AcousticConfig(cadence="stream", passive_sound=PassiveSound(rise_time_s=1e-3)).passive.rise_time_s == 1e-3
    with pytest.raises(TypeError):
        AcousticConfig(passive_sound="yes")
    with pytest.raises(ValueError):
        AcousticConfig(drive="zoh")
