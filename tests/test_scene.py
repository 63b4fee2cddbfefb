"""Scene assets: hand figures, objects of every material, generated MJCF files, bad names."""

import math

import mujoco
import numpy as np
import pytest

from aas_gym.assets import HAND_XML, OBJECTS_DIR, SCENES_DIR
from aas_gym.fingertips import FingertipSpec
from aas_gym.object_bodies import object_specs_from_model
from aas_gym.object_names import DEFAULT_OBJECT_NAMES
from aas_gym.scene import build_scene, build_scene_spec
from sensors.objects import ObjectSpec, get_object, known_material_names


def test_hand_figures_match_the_real_franka_hand():
    m = mujoco.MjModel.from_xml_path(str(HAND_XML))
    assert m.body("hand").mass[0] == pytest.approx(0.73)
    for side in ("left", "right"):
        assert m.body(f"{side}_finger").mass[0] + m.body(f"{side}_fingertip").mass[0] == pytest.approx(0.015)
        assert tuple(m.joint(f"finger_{side}").range) == pytest.approx((0.0, 0.04))
    assert m.actuator("gripper").ctrlrange[1] == pytest.approx(0.08)  # max opening
    for site in ("aas_actuator", "aas_mic", "tcp"):
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, site) >= 0
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and m.opt.impratio == pytest.approx(10)


def test_sensor_sites_sit_on_the_fingertip_faces_at_the_opening():
    m = build_scene(["aluminium_bar"])
    d = mujoco.MjData(m)
    d.qpos[m.jnt_qposadr[m.joint("finger_left").id]] = 0.015
    d.qpos[m.jnt_qposadr[m.joint("finger_right").id]] = 0.015
    mujoco.mj_forward(m, d)
    gap = np.linalg.norm(d.site("aas_actuator").xpos - d.site("aas_mic").xpos)
    assert gap == pytest.approx(0.03, abs=1e-9)  # joint values are the face offsets
    np.testing.assert_allclose((d.site("aas_actuator").xpos + d.site("aas_mic").xpos) / 2, d.site("tcp").xpos,
                               atol=1e-9)


@pytest.mark.parametrize("name", DEFAULT_OBJECT_NAMES)
def test_default_objects_have_paper_dimensions_and_mass(name):
    obj = get_object(name)
    assert obj.length_m == 0.2
    if obj.shape == "bar":
        assert (obj.width_m, obj.height_m) == (0.025, 0.025)
        expected = obj.density_kg_m3 * 0.2 * 0.025**2
    else:
        assert (obj.outer_radius_m, obj.inner_radius_m) == (0.0125, 0.0095)
        expected = obj.density_kg_m3 * 0.2 * math.pi * (0.0125**2 - 0.0095**2)
    assert obj.mass_kg == pytest.approx(expected)
    assert ObjectSpec.from_text(obj.to_text()) == obj


def test_every_material_builds_bar_tube_and_rod_in_one_scene():
    objects = [f"{mat}_{shape}" for mat in known_material_names() for shape in ("bar", "tube", "rod")]
    m = build_scene(objects)
    specs = object_specs_from_model(m)
    assert len(specs) == len(objects)
    for body, spec in specs.items():
        assert m.body(body).mass[0] == pytest.approx(spec.mass_kg)


def test_generated_asset_files_load_and_describe_their_objects():
    names = [f"{mat}_{shape}" for mat in known_material_names() for shape in ("bar", "tube")]
    assert set(DEFAULT_OBJECT_NAMES) <= set(names)
    for name in names:
        m = mujoco.MjModel.from_xml_path(str(OBJECTS_DIR / f"{name}.xml"))
        assert object_specs_from_model(m) == {name: get_object(name)}
    single = mujoco.MjModel.from_xml_path(str(SCENES_DIR / "single_object.xml"))
    multi = mujoco.MjModel.from_xml_path(str(SCENES_DIR / "multi_object.xml"))
    assert list(object_specs_from_model(single)) == ["aluminium_bar"]
    assert len(object_specs_from_model(multi)) == 3


def test_tube_collides_as_a_prism_with_facets_at_the_outer_radius():
    m = build_scene(["aluminium_tube"])
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    mujoco.mj_step(m, d, nstep=200)
    # Resting on a facet: centre one outer radius above the table (within contact softness).
    assert d.body("aluminium_tube").xpos[2] == pytest.approx(0.0125, abs=2e-4)


def test_fingertips_are_replaceable():
    spec = build_scene_spec(["wood_bar"], fingertip=FingertipSpec(half_width_m=0.015, friction=(0.6, 0.01, 0.001)))
    m = spec.compile()
    assert m.geom("left_fingertip").size[0] == pytest.approx(0.015)
    assert m.geom("right_fingertip").friction[0] == pytest.approx(0.6)


@pytest.mark.parametrize("bad", ["unobtainium_bar", "steel_sphere", "steel", "", 42])
def test_unknown_object_names_raise_clear_errors(bad):
    with pytest.raises(ValueError, match="unknown|must look like"):
        get_object(bad)


def test_unknown_material_in_spec_lists_known_materials():
    with pytest.raises(ValueError, match="known materials"):
        ObjectSpec.bar("kryptonite")
    with pytest.raises(ValueError, match="inner_radius_m"):
        ObjectSpec.tube("steel", outer_radius_m=0.01, inner_radius_m=0.02)
