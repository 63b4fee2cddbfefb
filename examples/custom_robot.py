"""The acoustic sensor on your own robot: any MJCF that declares the two sensor sites.

A gripper written here from scratch in MJCF (two fingers on slide joints, each pushed by a
40 N motor; nothing from aas_gym's hand) holds a wooden bar on a table. What makes it sense:

* a site ``aas_actuator`` on the fingertip body carrying the exciter and a site ``aas_mic`` on
  the one carrying the piezo microphone (contacts of those two bodies are the sensor's);
* for each object it may sense, a custom text ``aas_object:<body>`` describing it
  (``ObjectSpec.to_text()``: shape, material, sizes), the body's frame at the object's centre
  with its main axis along x (or pass ``objects={body: "wood_bar"}`` to the sensor instead).

    python examples/custom_robot.py
"""

from __future__ import annotations

import mujoco
import numpy as np

from aas_gym.sim_sensor import SimAcousticSensor
from sensors import Excitation
from sensors.objects.catalog import get_object

BAR = get_object("wood_bar")  # 200 x 25 x 25 mm
HALF = BAR.half_extents_m
GRIP_FORCE_N = 40.0

MJCF = f"""
<mujoco model="my_gripper">
  <option timestep="0.002" cone="elliptic" impratio="10" integrator="implicitfast"/>
  <custom>
    <text name="aas_object:bar" data="{BAR.to_text()}"/>
  </custom>
  <worldbody>
    <geom name="table" type="plane" size="0.5 0.5 0.01"/>
    <body name="bar" pos="0 0 {HALF[2]}">
      <freejoint/>
      <inertial pos="0 0 0" mass="{BAR.mass_kg}" diaginertia="{' '.join(map(str, BAR.diag_inertia_kg_m2))}"/>
      <geom type="box" size="{' '.join(map(str, HALF))}" friction="0.5 0.005 0.0001" mass="0"/>
    </body>
    <!-- A gripper mount fixed above the bar; fingers close along y at the bar's mid-height. The
         armature (reflected motor inertia) keeps 40 N from pushing light fingers through contacts. -->
    <body name="mount" pos="0.03 0 {HALF[2]}">
      <body name="exciter_finger" pos="0 0.03 0">
        <joint name="left" type="slide" axis="0 -1 0" range="0 0.03" damping="20" armature="0.1"/>
        <geom type="box" size="0.01 0.004 0.01" pos="0 0.004 0" friction="1 0.01 0.0005"/>
        <site name="aas_actuator" pos="0 0 0" size="0.003"/>
      </body>
      <body name="mic_finger" pos="0 -0.03 0">
        <joint name="right" type="slide" axis="0 1 0" range="0 0.03" damping="20" armature="0.1"/>
        <geom type="box" size="0.01 0.004 0.01" pos="0 -0.004 0" friction="1 0.01 0.0005"/>
        <site name="aas_mic" pos="0 0 0" size="0.003"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="left" gear="1" ctrlrange="0 {GRIP_FORCE_N}"/>
    <motor joint="right" gear="1" ctrlrange="0 {GRIP_FORCE_N}"/>
  </actuator>
</mujoco>
"""


def main() -> dict:
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    data.ctrl[:] = GRIP_FORCE_N  # squeeze
    mujoco.mj_step(model, data, nstep=300)  # 0.6 s: the fingers close and come to rest
    sensor = SimAcousticSensor(model, data)  # finds the sites and reads the bar from the MJCF
    contacts = sensor.stream.read(data)["bar"]
    observation = sensor.sense(Excitation.by_name("linear"), duration_s=1.0)
    features = observation.features()
    out = {"actuator_force_n": contacts.total_normal_force_n("actuator"),
           "mic_force_n": contacts.total_normal_force_n("mic"),
           "grasped": bool(observation.metadata["grasped"]), "features": features}
    print(f"fingertip forces {out['actuator_force_n']:.1f} / {out['mic_force_n']:.1f} N, grasped: {out['grasped']}, "
          f"{features.size} features, peak {np.max(features):.3g}")
    return out


if __name__ == "__main__":
    main()
