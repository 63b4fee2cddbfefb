"""The glue cuts of a randomized episode's sensing (issue 27): FAST_POINT_CHECKS
(``sensors.modal.basis``), LEAN_FEATURE_STREAM (``sensors.synthesis.feature_recording``), FEW_EXTRA_POINTS
(``sensors.modal.spring_modes``) and KIND_EQUALITY (``aas_gym.contacts``) give the reference's
bytes; so do the env-side cuts of a probe episode: GATHER_FORCES, LEAN_FINGERTIPS, PYTHON_SUMS and
WHOLE_SELECTION (``aas_gym.contacts``),
LAZY_GRASP_TESTS, CACHED_EXTENTS and LEAN_TELEPORT (``aas_gym.grasp``), LAZY_PLACEMENT_FORWARD (``aas_gym.envs.base``),
WIDTH_ARRAY and REST_ROTATION_CACHE (``aas_gym.object_grasps``), LEAN_PAD (``aas_gym.envs.info``):
per cut on its own inputs (odd ones included), and for whole envs (observations, rewards, infos and the
MuJoCo state over randomized episodes of GraspPosition-v0, ObjectRecognition-v0 and FillLevel-v0, caches
emptied between)."""

from __future__ import annotations

import gc
import importlib

import numpy as np
import pytest

from sensors._infra.lru import clear_all
from sensors.modal import basis
from sensors.modal.basis import MAX_POINT_COORDINATE_M, check_points_m
from sensors.synthesis import feature_recording

from aas_gym import contacts, grasp, object_grasps
from aas_gym.envs import base
from aas_gym.envs import info as env_info

# the module (``sensors.modal`` exports a function of the same name)
spring_modes = importlib.import_module("sensors.modal.spring_modes")

FLAGS = ((basis, "FAST_POINT_CHECKS"), (feature_recording, "LEAN_FEATURE_STREAM"),
         (spring_modes, "FEW_EXTRA_POINTS"), (contacts, "KIND_EQUALITY"), (contacts, "GATHER_FORCES"), (contacts, "PYTHON_SUMS"), (contacts, "WHOLE_SELECTION"),
         (contacts, "LEAN_FINGERTIPS"), (grasp, "LAZY_GRASP_TESTS"), (grasp, "CACHED_EXTENTS"), (grasp, "LEAN_TELEPORT"),
         (base, "LAZY_PLACEMENT_FORWARD"), (object_grasps, "WIDTH_ARRAY"), (object_grasps, "REST_ROTATION_CACHE"), (env_info, "LEAN_PAD"))


@pytest.fixture
def restore_flags():
    saved = [(m, n, getattr(m, n)) for m, n in FLAGS]
    yield
    for m, n, v in saved:
        setattr(m, n, v)


def _set_all(value: bool) -> None:
    for m, n in FLAGS:
        setattr(m, n, value)


def _outcome(f, x):
    try:
        out = f(x)
    except Exception as e:  # noqa: BLE001  (the errors must agree too)
        return type(e), str(e)
    return out.dtype.str, out.shape, out.tobytes(), out.flags.c_contiguous


POINTS = [
    np.random.default_rng(0).normal(0, 0.05, (7, 3)),
    np.zeros((0, 3)),
    np.array([[0.0, -0.0, 1e-300]]),
    np.array([[np.nan, 0.0, 0.0]]),
    np.array([[0.0, np.inf, 0.0]]),
    np.array([[0.0, 0.0, -np.inf]]),
    np.array([[MAX_POINT_COORDINATE_M, 0.0, 0.0]]),
    np.array([[np.nextafter(MAX_POINT_COORDINATE_M, np.inf), 0.0, 0.0]]),
    np.array([[-2e6, 0.0, 0.0]]),
    np.asfortranarray(np.random.default_rng(1).normal(0, 0.05, (5, 3))),
    np.random.default_rng(2).normal(0, 0.05, (3, 5)).T,          # a strided view
    np.random.default_rng(3).normal(0, 0.05, (4, 3)).astype(np.float32),
    np.array([0.01, 0.02, 0.03]),
    np.zeros((2, 4)),
    np.array([[1, 2, 3]]),
    np.array([[True, False, True]]),
    [[0.0, 0.1, 0.2]],
    [[False, 0.0, 0.0]],
    np.array([["a", "b", "c"]]),
]


@pytest.mark.parametrize("i", range(len(POINTS)))
def test_point_checks_agree_with_the_general_checks(i, restore_flags):
    x = POINTS[i]
    basis.FAST_POINT_CHECKS = False
    want = _outcome(check_points_m, x)
    basis.FAST_POINT_CHECKS = True
    assert _outcome(check_points_m, x) == want


def test_point_checks_return_a_copy(restore_flags):
    basis.FAST_POINT_CHECKS = True
    p = np.random.default_rng(4).normal(0, 0.05, (6, 3))
    out = check_points_m(p)
    assert out is not p and not np.shares_memory(out, p)


def test_kind_masks_are_isin(restore_flags):
    rng = np.random.default_rng(6)
    names = np.array(contacts.KINDS)
    for n in (0, 1, 5, 40):
        kinds = names[rng.integers(0, len(names), n)]
        for sel in (("actuator", "mic"), ("environment",), ("mic", "mic"), ("object", "hand", "other"), ()):
            contacts.KIND_EQUALITY = False
            want = contacts.kind_mask(kinds, sel)
            contacts.KIND_EQUALITY = True
            got = contacts.kind_mask(kinds, sel)
            assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want)
    empty = contacts.ContactStream.__new__(contacts.ContactStream)._empty("b")
    assert contacts.kind_mask(empty.kinds, ("actuator",)).shape == (0,)


@pytest.mark.parametrize("rows", [np.zeros((0, 3)), np.array([[0.01, -0.0, 0.02]]),
                                  np.array([[np.nan, 0.0, -1e-300]])])
def test_fewer_than_two_extra_points_are_their_unique_rows(rows):
    assert np.unique(rows, axis=0).tobytes() == rows.copy().tobytes()
    assert np.unique(rows, axis=0).shape == rows.shape


VELOCITIES = [[0.0, 0.0], [2e-4, -0.0], [-2e-4, 0.0], [1e-4, -1e-4], [np.nan, 1.0], [1.0, np.nan],
              [np.inf, 0.0], [-np.inf, np.nan], [0.0, 0.0, 0.0, 5e-3], [1e-3, -1e-3, 0.0, 0.0]]


@pytest.mark.parametrize("v", VELOCITIES)
def test_motion_test_is_numpys(v):
    for tol in (1e-4, 1e-3):
        assert grasp.exceeds(list(v), tol) == bool(np.max(np.abs(np.array(v))) > tol)


OPENINGS = [-0.0, 0.0, 0.08, float(np.nextafter(0.08, 1)), float(np.nextafter(0.08, 0)), -1e-300, 5e-324, -5e-324,
            float("nan"), float("inf"), float("-inf"), -0.5, 0.04, 1.0, 0, 1, np.float64(-0.0), np.float32(0.5),
            np.array(0.09)]


@pytest.mark.parametrize("i", range(len(OPENINGS)))
def test_opening_clip_is_numpys(i, restore_flags):
    x = OPENINGS[i]
    got = []
    for flag in (False, True):
        grasp.LEAN_TELEPORT = flag
        out = grasp.clip_opening_m(x)
        got.append((type(out), np.float64(out).tobytes()))
    assert got[0] == got[1] and got[0][0] is float


def test_half_extents_cache_follows_the_model(restore_flags):
    import mujoco

    xml = """<mujoco><worldbody><body name="b" pos="0 0 1"><freejoint/>
      <geom type="box" size="0.1 0.02 0.01" pos="0.01 0 0" euler="0 0 20"/>
      <geom type="sphere" size="0.03" pos="-0.1 0 0"/><geom type="box" size="1 1 1" contype="0" conaffinity="0"/>
      </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    bid = 1
    for edit in (None, ("geom_pos", 0, 0.05), ("geom_quat", 0, 0.3), ("geom_contype", 2, 1)):
        if edit is not None:
            name, g, value = edit
            arr = getattr(model, name)
            arr[(g,) if arr.ndim == 1 else (g, 0)] = value
        grasp.CACHED_EXTENTS = False
        want = grasp.body_half_extents(model, bid)
        grasp.CACHED_EXTENTS = True
        first, again = grasp.body_half_extents(model, bid), grasp.body_half_extents(model, bid)
        assert first.tobytes() == want.tobytes() == again.tobytes()
        first[:] = 9.0                                  # a caller's edit does not reach the cache
        assert grasp.body_half_extents(model, bid).tobytes() == want.tobytes()


def test_nearest_grasp_with_the_width_array(restore_flags):
    from sensors.objects.catalog import get_object

    grasps = object_grasps.grasp_set(get_object("mug"))
    widths = np.array([g.width_m for g in grasps.grasps])
    lo, hi = grasps.span_m
    rng = np.random.default_rng(8)
    cases = [(p, w, avoid) for p in rng.uniform(lo - 0.01, hi + 0.01, 6)
             for w in (0.0, float(np.median(widths)), float(widths.max()), float(widths.max()) + 1e-3, np.nan)
             for avoid in ((), (grasps.grasps[3].centre_m + 0.004,))]
    for p, w, avoid in cases:
        outcome = []
        for flag in (False, True):
            object_grasps.WIDTH_ARRAY = flag
            try:
                g = grasps.nearest(float(p), avoid, 0.01, min_width_m=w)
                outcome.append((g.centre_m.tobytes(), g.axis.tobytes(), g.width_m, g.position_m))
            except ValueError as e:
                outcome.append(str(e))
        assert outcome[0] == outcome[1]
    assert grasps.widths_m.tobytes() == widths.astype(np.float64).tobytes()


@pytest.mark.parametrize("n", [0, 1, 13, 64, 70])
def test_padded_contacts_lean(n, restore_flags):
    rng = np.random.default_rng(n)
    f = rng.uniform(0, 5, n)
    f[: min(n, 2)] = (-0.0, np.nan)[: min(n, 2)]
    names = np.array(contacts.KINDS)[rng.integers(0, len(contacts.KINDS), n)]
    c = contacts.ObjectContacts("b", rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), f, rng.normal(size=(n, 3)),
                                rng.uniform(size=n), rng.uniform(size=n), names, names.astype(object),
                                names.astype(object))
    out = []
    for flag in (False, True):
        env_info.LEAN_PAD = flag
        out.append(_flat(env_info.padded_contacts(c)))
    assert out[0] == out[1]


def test_row_sums_in_python_are_numpys(restore_flags):
    rng = np.random.default_rng(9)
    efc = np.concatenate([[1.0, 1e-16, 1e-16, 1e-16, -0.0, 0.0, -3.0, np.nan, 1e16, -1e16, 5e-324],
                          rng.normal(0, 30, 40), rng.uniform(0, 1, 40) * 10.0 ** rng.integers(-20, 20, 40)])
    cases = [np.zeros(0, int), np.array([0, 1, 2]), np.array([1, 2, 0]), np.array([-1, -1]), np.array([4]),
             np.array([5, 4]), np.array([7, 0]), np.array([8, 9, 0, 1, 2]), np.array([-1, 0, 1, 2, 3, 8, 9]),
             np.arange(8), np.arange(12)]
    cases += [rng.integers(-1, len(efc), size) for size in (2, 3, 5, 6, 7, 7, 7, 8, 9) for _ in range(30)]
    for adr in cases:
        adr = adr.astype(np.int32)
        contacts.PYTHON_SUMS = False
        want = contacts.row_force_sum_n(efc, adr)
        contacts.PYTHON_SUMS = True
        got = contacts.row_force_sum_n(efc, adr)
        assert type(got) is float and np.float64(got).tobytes() == np.float64(want).tobytes(), adr


def test_rest_rotations_cached(restore_flags):
    import dataclasses

    from sensors.objects.catalog import get_object

    mug = get_object("mug").solid()
    solids = [mug, dataclasses.replace(mug, up_axis=(0.0, 0.0, 1.0)), dataclasses.replace(mug, up_axis=(0.0, 1.0, 1.0)),
              dataclasses.replace(mug, up_axis=(1.0, 0.0, 0.001), main_axis=(1.0, 0.0, 0.0)),
              dataclasses.replace(mug, up_axis=(0.0, 0.0, 1.0), main_axis=(0.0, 0.0, 1.0)),
              dataclasses.replace(mug, up_axis=(0.0, 0.0, 1.0), main_axis=(0.0, 1.0, 0.0)),
              dataclasses.replace(mug, up_axis=(0.0, 0.3, 0.2), main_axis=(0.1, 0.0, 0.9))]
    for solid in solids + solids:                   # the second round from the cache
        object_grasps.REST_ROTATION_CACHE = False
        want = object_grasps.rest_rotation(solid)
        object_grasps.REST_ROTATION_CACHE = True
        got = object_grasps.rest_rotation(solid)
        assert got.tobytes() == want.tobytes() and got.shape == want.shape
        got[:] = 0.0                                # a caller's edit does not reach the cache
        assert object_grasps.rest_rotation(solid).tobytes() == want.tobytes()


def _read_bytes(stream, d) -> list:
    return [(name, [(f, getattr(c, f).dtype.str, getattr(c, f).tobytes()) for f in
                    ("positions_m", "normals", "normal_forces_n", "forces_n", "friction", "penetration_m")]
             + [c.kinds.tolist(), c.other_bodies.tolist(), c.other_geoms.tolist()]) for name, c in stream.read(d).items()]


@pytest.mark.parametrize("scene", ["single", "multi"])
def test_contact_reads_and_fingertip_sums_through_a_squeeze(scene, restore_flags):
    """``read`` (GATHER_FORCES, WHOLE_SELECTION: one sensed body in the single scene),
    ``fingertip_forces_n`` (LEAN_FINGERTIPS) and ``fingertip_rows``' sums (PYTHON_SUMS) against the references step by step, before the pads touch and through the squeeze."""
    import gymnasium as gym
    import mujoco

    import aas_gym  # noqa: F401

    u = gym.make("aas_gym/GraspPosition-v0", scene=scene, disable_env_checker=True,
                 acoustic={"enabled": False}).unwrapped
    u.reset(seed=5)
    sc, m, d = u._scene, u.model, u.data
    stream, body = sc.stream, sc.bodies[0]
    assert (len(sc.bodies) == 1) == (scene == "single")     # WHOLE_SELECTION's path, and the other
    tcp, width = grasp.grasp_pose(m, d, body, 0.03)
    sc.hand.teleport(d, tcp + np.array([0.004, 0.0, 0.0, 0.0]), width + 0.03)
    sc.hand.command(d, opening_m=0.0)
    seen = set()
    for _ in range(60):
        mujoco.mj_step(m, d)
        contacts.GATHER_FORCES = contacts.LEAN_FINGERTIPS = contacts.PYTHON_SUMS = contacts.WHOLE_SELECTION = False
        want_read, want = _read_bytes(stream, d), stream.fingertip_forces_n(d, body)
        contacts.GATHER_FORCES = contacts.LEAN_FINGERTIPS = contacts.PYTHON_SUMS = contacts.WHOLE_SELECTION = True
        assert _read_bytes(stream, d) == want_read
        got = stream.fingertip_forces_n(d, body)
        efc, actuator, mic = stream.fingertip_rows(d, body)
        rows = (contacts.row_force_sum_n(efc, actuator), contacts.row_force_sum_n(efc, mic))
        assert np.float64(got).tobytes() == np.float64(want).tobytes() == np.float64(rows).tobytes()
        seen.add((want[0] > 0, want[1] > 0))
    u.close()
    assert (True, True) in seen and (False, False) in seen


def _flat(x, path="", out=None):
    """(path, bytes) of every leaf of an observation or info (arrays by dtype, shape, bytes)."""
    out = [] if out is None else out
    if isinstance(x, dict):
        for k in sorted(x, key=str):
            _flat(x[k], f"{path}/{k}", out)
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            _flat(v, f"{path}[{i}]", out)
    elif isinstance(x, np.ndarray) and x.dtype != object:
        out.append((path, (x.dtype.str, x.shape, x.tobytes())))
    elif isinstance(x, np.ndarray):
        _flat(x.tolist(), path, out)
    elif isinstance(x, (float, np.floating)):
        out.append((path, np.float64(x).tobytes()))
    else:
        out.append((path, repr(x)))
    return out


def _physics(env) -> tuple:
    """The MuJoCo state an env step leaves: integration state, poses, contacts, solver forces."""
    import mujoco

    d, m = env.unwrapped.data, env.unwrapped.model
    state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    n = d.ncon
    return (state.tobytes(), d.xpos.tobytes(), d.xquat.tobytes(), d.qacc.tobytes(), d.efc_force[:d.nefc].tobytes(),
            d.contact.pos[:n].tobytes(), d.contact.geom[:n].tobytes())


def _run(env_id: str, steps: int, seed: int, **kwargs):
    import gymnasium as gym

    import aas_gym  # noqa: F401

    clear_all()
    gc.collect()
    env = gym.make(env_id, **kwargs)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    trace = [_flat(obs), _flat(info), _physics(env)]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace += [_flat(obs), _flat(info), np.float64(reward).tobytes(), (terminated, truncated), _physics(env)]
        if terminated or truncated:
            obs, info = env.reset()
            trace += [_flat(obs), _flat(info), _physics(env)]
    env.close()
    del env
    clear_all()
    gc.collect()
    return trace


# three of the paper's objects keep the process below ~2.5 GB (each model holds its unit-load
# store); their episodes randomize as the default env's do
ENVS = [("aas_gym/GraspPosition-v0", 200, {}), ("aas_gym/GraspPosition-v0", 300, {"acoustic": {"enabled": False}}),
        ("aas_gym/ObjectRecognition-v0", 200, {"objects": ("aluminium_bar", "pla_tube", "wood_bar")}),
        ("aas_gym/FillLevel-v0", 200, {})]


@pytest.mark.parametrize("env_id,steps,kwargs", ENVS)
def test_envs_give_the_same_bytes_with_the_cuts(env_id, steps, kwargs, restore_flags):
    _set_all(False)
    want = _run(env_id, steps, seed=7, **kwargs)
    _set_all(True)
    unused = feature_recording.UNUSED_RNG.bit_generator.state
    got = _run(env_id, steps, seed=7, **kwargs)
    # the lean stream's shared generator is never drawn from (a draw would tie features to history)
    assert feature_recording.UNUSED_RNG.bit_generator.state == unused
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want)):
        assert g == w, f"{env_id}: step record {i} differs"
