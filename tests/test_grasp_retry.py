"""Dataset tasks on surface objects retry a grasp whose pad rests off the modal surface
(a collision piece over-covering the solid) instead of failing the whole run."""

import pytest

from aas_gym.experiments import simulate
from aas_gym.experiments.config import DatasetConfig
from aas_gym.sim_sensor import SimAcousticSensor
from sensors.modal.damping import OffSurfaceError


def _task(config):
    return next(t for t in config.tasks() if t.object_name == "glass")


def test_an_off_surface_grasp_is_retried_and_a_persistent_one_names_the_task(monkeypatch):
    config = DatasetConfig(objects=("glass", "wood_bar"), scenes=("single",), single_grasps=1,
                           excitations=("linear",))
    real_sense = SimAcousticSensor.sense
    calls = {"n": 0}

    def off_once(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 1:
            raise OffSurfaceError("drive/mic point at [0, 0, 0] m is 6.76 mm from the object surface")
        return real_sense(self, *args, **kwargs)

    monkeypatch.setattr(SimAcousticSensor, "sense", off_once)
    rows = simulate.run_task(_task(config), config)
    assert calls["n"] == 2 and len(rows) == 1 and rows[0]["features"].shape == (140,)

    def always_off(self, *args, **kwargs):
        raise OffSurfaceError("drive/mic point is 6.76 mm from the object surface")

    monkeypatch.setattr(SimAcousticSensor, "sense", always_off)
    with pytest.raises(OffSurfaceError, match="task single/glass/g000"):
        simulate.run_task(_task(config), config)
