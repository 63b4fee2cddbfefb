"""A lone surface target is placed without its rim (nothing leans on it) and with its rest height
computed once per solid (``aas_gym.scenario._place_on_surface_target``): the same pose and the
same random stream as the full placement computes."""

import mujoco
import numpy as np

import aas_gym  # noqa: F401
from aas_gym import scenario
from aas_gym.object_bodies import yaw_rest_quat
from aas_gym.object_grasps import rest_height_m
from aas_gym.scene import build_scene
from sensors.objects.catalog import get_object


def test_a_lone_surface_target_is_placed_as_before_and_draws_the_same_stream():
    for name in ("mug", "glass"):
        target = get_object(name)
        model = build_scene([target])
        data = mujoco.MjData(model)
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, model.body(model.nbody - 1).name)
        joint = (int(model.jnt_qposadr[model.body_jntadr[bid]]), int(model.jnt_dofadr[model.body_jntadr[bid]]))
        r = scenario.DomainRandomization()
        for seed in range(3):
            for _ in range(2):                                  # the second time from the cached height
                rng = np.random.default_rng(seed)
                layout = scenario.place_objects(model, data, (target,), [joint], rng, r)
                ref = np.random.default_rng(seed)
                xy = ref.uniform(-r.placement_m, r.placement_m, 2)
                yaw = float(ref.uniform(-r.yaw_rad, r.yaw_rad))
                ref.uniform(0, 2 * np.pi)                       # the side others would lean from
                assert rng.random() == ref.random()             # the stream goes on as before
                a = joint[0]
                solid = target.solid()
                assert np.array_equal(data.qpos[a:a + 3], [xy[0], xy[1], rest_height_m(solid)])
                assert np.array_equal(data.qpos[a + 3:a + 7], yaw_rest_quat(solid, yaw))
                assert layout == scenario.Layout((float(xy[0]), float(xy[1])), yaw, (), ())
