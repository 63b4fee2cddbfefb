"""Contact datastream conventions and the grasp: MuJoCo contact forces reach the grip force."""

import mujoco
import numpy as np
import pytest

from aas_gym.contacts import ContactStream
from aas_gym.grasp import Hand, planar_grasp
from aas_gym.scene import build_scene

G = 9.81


def _box_on_static_box(object_first: bool) -> mujoco.MjModel:
    obj = ('<body name="obj" pos="0 0 0.0105" euler="0 0 0.4"><freejoint/>'
           '<geom name="obj" type="box" size="0.05 0.02 0.01" mass="0.5"/></body>')
    table = '<body name="table"><geom name="table" type="box" size="0.3 0.3 0.0005" pos="0 0 0"/></body>'
    body = obj + table if object_first else table + obj
    xml = f'<mujoco><option cone="elliptic"/><worldbody>{body}</worldbody></mujoco>'
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize("object_first", [True, False])
def test_table_contact_normal_points_out_of_the_object_and_carries_its_weight(object_first):
    m = _box_on_static_box(object_first)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, nstep=300)
    obj_geom = m.geom("obj").id
    assert (d.contact.geom[: d.ncon, 0 if object_first else 1] == obj_geom).all()  # both orders exercised
    c = ContactStream(m, ["obj"]).read(d)["obj"]
    assert len(c) >= 4 and set(c.kinds) == {"environment"}
    np.testing.assert_allclose(c.normals, np.tile([0, 0, -1.0], (len(c), 1)), atol=1e-6)  # out of the bottom face
    np.testing.assert_allclose(c.positions_m[:, 2], -0.01, atol=1e-3)  # on the bottom face
    assert c.total_normal_force_n() == pytest.approx(0.5 * G, rel=1e-3)
    # The table pushes the object up (object frame z is world z here up to yaw).
    assert np.sum(c.forces_n, axis=0) == pytest.approx([0, 0, 0.5 * G], abs=1e-3)


@pytest.fixture(scope="module")
def grasped_bar():
    m = build_scene(["aluminium_bar"])
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, nstep=50)
    result = planar_grasp(m, d, "aluminium_bar", 0.03, 40.0)
    return m, d, result


def test_grip_force_reaches_the_commanded_force_within_5_percent(grasped_bar):
    m, d, result = grasped_bar
    assert result.success and result.settled
    c = ContactStream(m, ["aluminium_bar"]).read(d)["aluminium_bar"]
    for kind in ("actuator", "mic"):
        assert c.total_normal_force_n(kind) == pytest.approx(40.0, rel=0.05)


@pytest.mark.parametrize("force", [10.0, 100.0])
def test_grip_force_is_controllable(force):
    m = build_scene(["steel_bar"])
    d = mujoco.MjData(m)
    result = planar_grasp(m, d, "steel_bar", 0.0, force, lift_m=0.03)
    assert result.actuator_force_n == pytest.approx(force, rel=0.05)
    assert result.mic_force_n == pytest.approx(force, rel=0.05)
    assert d.body("steel_bar").xpos[2] > 0.035  # lifted: held by friction alone


def test_finger_contacts_point_along_the_grip_and_sit_at_the_grasp_position(grasped_bar):
    m, d, _ = grasped_bar
    c = ContactStream(m, ["aluminium_bar"]).read(d)["aluminium_bar"]
    act, mic = c.merged("actuator"), c.merged("mic")
    # Outward normals of opposite side faces (object y), contact points at x = 30 mm.
    assert abs(act[1][1]) == pytest.approx(1.0, abs=1e-6) and act[1][1] == pytest.approx(-mic[1][1])
    assert act[0][0] == pytest.approx(0.03, abs=1e-3) and mic[0][0] == pytest.approx(0.03, abs=1e-3)
    assert abs(act[0][1]) == pytest.approx(0.0125, abs=5e-4)
    # The actuator finger is on the side its site is on.
    r = d.xmat[m.body("aluminium_bar").id].reshape(3, 3)
    site_obj = r.T @ (d.site("aas_actuator").xpos - d.xpos[m.body("aluminium_bar").id])
    assert np.sign(site_obj[1]) == np.sign(act[1][1])
    # Finger forces push the object inwards: along -normal.
    sel = c.select("actuator")
    assert np.all(np.einsum("ij,ij->i", sel.forces_n, sel.normals) < 0)


def test_no_slip_while_holding(grasped_bar):
    m, d, _ = grasped_bar
    hand = Hand(m)
    b = m.body("aluminium_bar").id
    site = m.site("aas_actuator").id

    def rel():
        r = d.xmat[b].reshape(3, 3)
        return r.T @ (d.site_xpos[site] - d.xpos[b])

    before = rel()
    mujoco.mj_step(m, d, nstep=500)  # 1 s of holding = the sensing window
    assert np.linalg.norm(rel() - before) < 1e-5
    assert hand.opening_m(d) == pytest.approx(0.025, abs=5e-4)


def test_contact_stream_rejects_unknown_bodies():
    m = build_scene(["wood_bar"])
    with pytest.raises(ValueError, match="no body named"):
        ContactStream(m, ["granite_bar"])


@pytest.mark.parametrize("cone", ["elliptic", "pyramidal"])
def test_stream_forces_equal_mj_contact_force(cone):
    m = build_scene(["steel_bar", "wood_bar"])
    if cone == "pyramidal":
        m.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    d = mujoco.MjData(m)
    planar_grasp(m, d, "steel_bar", 0.02, 40.0)
    stream = ContactStream(m, ["steel_bar", "wood_bar"])
    got = stream.read(d)
    f6 = np.zeros(6)
    for body in ("steel_bar", "wood_bar"):
        bid = m.body(body).id
        expected_total = np.zeros(3)
        for i in range(d.ncon):
            g = d.contact.geom[i]
            side = [m.geom_bodyid[g[0]] == bid, m.geom_bodyid[g[1]] == bid]
            if not any(side):
                continue
            mujoco.mj_contactForce(m, d, i, f6)
            world = d.contact.frame[i].reshape(3, 3).T @ f6[:3]
            expected_total += world if side[1] else -world  # force acts on geom[1]
        rot = d.xmat[bid].reshape(3, 3)
        np.testing.assert_allclose(rot @ got[body].forces_n.sum(axis=0), expected_total, atol=1e-9)
    assert got["steel_bar"].total_normal_force_n("actuator") == pytest.approx(40.0, rel=0.05)
    assert len(got["wood_bar"]) == 4 and set(got["wood_bar"].kinds) == {"environment"}
