"""The Franka Panda (robot="panda"): its model, inverse kinematics, the 40 N grasp, every env.

Kinematics are checked against Franka's published Denavit-Hartenberg parameters evaluated here
in numpy, independent of the MJCF; limits against Franka's published values."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import aas_gym  # noqa: F401  (registers the envs)
from aas_gym.contacts import ContactStream
from aas_gym.grasp import planar_grasp
from aas_gym.panda import PANDA_JOINTS, PandaAssetsError, franka_mesh_dir
from aas_gym.panda_control import PANDA_TCP_HIGH, PANDA_TCP_LOW, PandaArm, UnreachableError
from aas_gym.robots import robot_controller
from aas_gym.scene import build_scene
from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation

try:
    franka_mesh_dir()
except PandaAssetsError as exc:  # a dependency of the project (pyproject): missing only in a partial install
    pytest.skip(str(exc), allow_module_level=True)

# Franka "Robot and interface specifications" (Panda): joint limits [rad], torque limits [N m].
FRANKA_Q_MIN = [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
FRANKA_Q_MAX = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
FRANKA_TAU_MAX = [87, 87, 87, 87, 12, 12, 12]
# Franka's modified DH table: (a [m], d [m], alpha [rad]) per joint, then the flange.
FRANKA_DH = [(0, 0.333, 0), (0, 0, -math.pi / 2), (0, 0.316, math.pi / 2), (0.0825, 0, math.pi / 2),
             (-0.0825, 0.384, -math.pi / 2), (0, 0, math.pi / 2), (0.088, 0, math.pi / 2)]
FLANGE_D_M, TCP_FROM_FLANGE_M = 0.107, 0.1034
# franka_description: the hand sits on the flange turned by -45 deg about its z axis.
HAND_MOUNT_YAW_RAD = -math.pi / 4


def dh_tcp(q, base):
    """TCP position, hand approach axis (its z) and hand x axis (normal to the fingers' travel,
    whose heading is the TCP yaw) from Franka's DH parameters and hand mount (numpy only)."""
    def tf(a, d, alpha, theta):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -d * sa], [st * sa, ct * sa, ca, d * ca],
                         [0, 0, 0, 1]])
    t = np.eye(4)
    t[:3, 3] = base
    for (a, d, alpha), qi in zip(FRANKA_DH, q):
        t = t @ tf(a, d, alpha, qi)
    t = t @ tf(0, FLANGE_D_M + TCP_FROM_FLANGE_M, 0, HAND_MOUNT_YAW_RAD)
    return t[:3, 3], t[:3, 2], t[:3, 0]


@pytest.fixture(scope="module")
def scene():
    model = build_scene(["aluminium_bar"], robot="panda")
    return model, mujoco.MjData(model), robot_controller(model)


def test_model_has_franka_limits_masses_and_the_sensor_sites(scene):
    model, _, arm = scene
    assert isinstance(arm, PandaArm)
    ids = [model.joint(n).id for n in PANDA_JOINTS]
    np.testing.assert_allclose(model.jnt_range[ids, 0], FRANKA_Q_MIN)
    np.testing.assert_allclose(model.jnt_range[ids, 1], FRANKA_Q_MAX)
    np.testing.assert_allclose(model.actuator_forcerange[[model.actuator(n).id for n in PANDA_JOINTS], 1],
                               FRANKA_TAU_MAX)
    # Arm links 0-7: 16.69 kg in franka_description (Gaz et al. 2019); the hand 0.73 kg (Franka datasheet).
    arm_mass = sum(model.body(f"panda_link{i}").mass[0] for i in range(8))
    assert arm_mass == pytest.approx(16.692, abs=0.001)
    assert model.body("hand").mass[0] == pytest.approx(0.73)
    lo = model.jnt_range[[model.joint("finger_left").id, model.joint("finger_right").id]]
    assert np.sum(lo[:, 1]) == pytest.approx(0.08) and np.all(lo[:, 0] == 0)
    for site in ("aas_actuator", "aas_mic", "tcp"):
        assert model.site(site).id >= 0
    assert franka_mesh_dir().parts[-5:] == ("envs", "assets", "kitchen_franka", "franka_assets", "meshes")
    assert model.nmesh >= 10


def test_ik_matches_franka_dh_over_the_command_box(scene):
    model, data, arm = scene
    base = model.body("panda_link0").pos
    rng = np.random.default_rng(3)
    corners = [np.where([(k >> i) & 1 for i in range(4)], PANDA_TCP_HIGH, PANDA_TCP_LOW) for k in range(16)]
    for tcp in corners + [rng.uniform(PANDA_TCP_LOW, PANDA_TCP_HIGH) for _ in range(12)]:
        q = arm.solve_ik(data, tcp)
        assert np.all(q >= np.array(FRANKA_Q_MIN)) and np.all(q <= np.array(FRANKA_Q_MAX))
        assert not arm.self_collides(q)
        pos, approach, hand_x = dh_tcp(q, base)
        np.testing.assert_allclose(pos, tcp[:3], atol=1e-3)
        np.testing.assert_allclose(approach, [0, 0, -1], atol=1e-2)  # hand pointing down
        # the commanded yaw is the heading of Franka's hand x axis (fingers travel along its y)
        np.testing.assert_allclose(hand_x, [math.cos(tcp[3]), math.sin(tcp[3]), 0], atol=1e-2)


def test_the_fingers_close_along_the_franka_hand_y_axis(scene):
    model, data, arm = scene
    q = arm.solve_ik(data, (0.05, -0.1, 0.1, 0.7))
    data.qpos[arm.arm_qpos] = q
    mujoco.mj_forward(model, data)
    _, _, hand_x = dh_tcp(q, model.body("panda_link0").pos)
    hand_y = np.cross([0, 0, -1], hand_x)  # z_hand x x_hand, with z_hand pointing down
    left, right = (data.site_xpos[model.site(s).id] for s in ("aas_actuator", "aas_mic"))
    gap = (right - left) / np.linalg.norm(right - left)
    assert abs(gap @ hand_y) == pytest.approx(1.0, abs=1e-3)


def test_unreachable_grasps_raise_instead_of_clipping(scene):
    _, data, arm = scene
    with pytest.raises(UnreachableError, match="command box"):
        arm.teleport(data, (0.6, 0.0, 0.1, 0.0), 0.08)
    with pytest.raises(UnreachableError, match="cannot reach"):
        arm.tcp_low, arm.tcp_high = np.full(4, -9.0), np.full(4, 9.0)  # past the box: the arm's own reach
        try:
            arm.solve_ik(data, (1.5, 0.0, 0.1, 0.0))
        finally:
            arm.tcp_low, arm.tcp_high = np.array(PANDA_TCP_LOW), np.array(PANDA_TCP_HIGH)


def test_self_collision_is_detected(scene):
    _, _, arm = scene
    folded = np.array([0.0, 0.0, 0.0, -3.0, 0.0, 0.0, 0.0])  # forearm folded onto the upper arm
    assert arm.self_collides(folded)
    assert not arm.self_collides(np.array([0.0, -0.2, 0.0, -2.2, 0.0, 2.0, math.pi / 4]))


def test_joint_space_control_stays_within_limits(scene):
    model, data, arm = scene
    with pytest.raises(ValueError, match="limits"):
        arm.command_joints(data, [0, 0, 0, 0.5, 0, 1, 0])  # joint 4 must stay below -0.0698
    arm.command_joints(data, [0.1, -0.2, 0, -2.2, 0, 2.0, 0.8])
    np.testing.assert_allclose(data.ctrl[arm.arm_actuators], [0.1, -0.2, 0, -2.2, 0, 2.0, 0.8])


def test_panda_grasps_at_40_n_and_senses(scene):
    model, data, arm = scene
    mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    stream = ContactStream(model, ["aluminium_bar"])
    result = planar_grasp(model, data, "aluminium_bar", 0.02, 40.0, hand=arm, stream=stream)
    assert result.success
    assert result.actuator_force_n == pytest.approx(40.0, rel=0.05)
    assert result.mic_force_n == pytest.approx(40.0, rel=0.05)
    panda = SimAcousticSensor(model, data).sense(Excitation("impulse", duration_s=0.5), 0.5)
    assert panda.metadata["grasped"]
    # The same grasp by the floating hand sounds the same: the sensor hears contacts, not arms.
    hand_model = build_scene(["aluminium_bar"])
    hand_data = mujoco.MjData(hand_model)
    mujoco.mj_forward(hand_model, hand_data)
    planar_grasp(hand_model, hand_data, "aluminium_bar", 0.02, 40.0)
    hand = SimAcousticSensor(hand_model, hand_data).sense(Excitation("impulse", duration_s=0.5), 0.5)
    assert np.max(np.abs(panda.waveform)) > 0
    # Compared in the sensed band (the 140 features): below it, the grasped bar's suspension
    # modes on the pad and table springs (tens to hundreds of Hz) ring for long and shift with
    # sub-millimetre differences of the contact points, which is physics, not the arm.
    a, b = panda.features(), hand.features()
    assert np.linalg.norm(a - b) < 0.05 * np.linalg.norm(b)


ENVS = {"aas_gym/AcousticGrasp-v0": {}, "aas_gym/GraspPosition-v0": {},
        "aas_gym/ObjectRecognition-v0": {"objects": ["aluminium_bar", "wood_bar"]},
        "aas_gym/ContactFormation-v0": {}, "aas_gym/FillLevel-v0": {}}


@pytest.mark.parametrize("robot", ["floating_hand", "panda"])
@pytest.mark.parametrize("env_id", list(ENVS))
def test_every_env_passes_gymnasium_and_sb3_check_env_with_both_robots(env_id, robot):
    import warnings

    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, robot=robot, acoustic={"duration_s": 0.5, "feature_scale": "db"}, **ENVS[env_id]).unwrapped
    assert env.robot == robot
    check_env(env, skip_render_check=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env, warn=True)
    env.close()


def test_unknown_robot_is_refused():
    with pytest.raises(ValueError, match="robot must be one of"):
        gym.make("aas_gym/AcousticGrasp-v0", robot="ur5")


def test_a_panda_dataset_records_its_robot(tmp_path):
    import json

    from aas_gym.experiments.config import DatasetConfig
    from aas_gym.experiments.generate import generate_dataset, load_dataset

    config = DatasetConfig(objects=("aluminium_bar",), excitations=("impulse",), scenes=("single",), single_grasps=1,
                           multi_grasps=0, positions=0, position_repeats=0, duration_s=0.5, robot="panda")
    out = generate_dataset(config, tmp_path / "ds", workers=1, progress=False)
    manifest = json.loads((out / ".dataset.json").read_text())
    assert manifest["robot"] == "panda" and manifest["config"]["robot"] == "panda"
    assert len(load_dataset(out)) == 1
    with pytest.raises(ValueError, match="robot must be one of"):
        DatasetConfig(robot="ur5")


def test_a_user_written_mjcf_with_the_two_sites_senses():
    """examples/custom_robot.py: a gripper owing nothing to aas_gym's hand gets the sensor."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "custom_robot.py"
    spec = importlib.util.spec_from_file_location("custom_robot", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = example.main()
    assert out["grasped"]
    assert out["actuator_force_n"] == pytest.approx(40.0, rel=0.05)
    assert out["mic_force_n"] == pytest.approx(40.0, rel=0.05)
    assert out["features"].shape == (140,) and np.all(np.isfinite(out["features"])) and np.any(out["features"] != 0)


def test_joint_space_control_option_of_acoustic_grasp():
    env = gym.make("aas_gym/AcousticGrasp-v0", robot="panda", control="joint", acoustic={"cadence": "never"}).unwrapped
    assert env.action_space.shape == (9,)
    check_env(env, skip_render_check=True)
    env.reset(seed=0)
    q0 = env.hand.joint_positions(env.data)
    action = np.zeros(9, np.float32)
    action[0] = 1.0  # joint 1 by +0.05 rad per step
    for _ in range(4):
        env.step(action)
    assert env.hand.target_q[0] - q0[0] == pytest.approx(0.2, abs=1e-9)
    for _ in range(6):  # the servo catches up
        env.step(np.zeros(9, np.float32))
    assert env.hand.joint_positions(env.data)[0] - q0[0] == pytest.approx(0.2, abs=0.01)
    obs = env.reset(seed=0)[0]
    # the joints are observed (the TCP pose leaves the arm's redundancy open)
    np.testing.assert_allclose(obs["joint_positions"], env.hand.joint_positions(env.data), atol=1e-6)
    assert obs["joint_velocities"].shape == (7,)
    assert "joint_positions" not in gym.make("aas_gym/AcousticGrasp-v0", robot="panda",
                                             acoustic={"cadence": "never"}).observation_space.spaces
    with pytest.raises(ValueError, match="robot='panda'"):
        gym.make("aas_gym/AcousticGrasp-v0", control="joint")
    with pytest.raises(ValueError, match="robot must be one of"):  # the misspelt robot is named
        gym.make("aas_gym/AcousticGrasp-v0", robot="Panda", control="joint")
