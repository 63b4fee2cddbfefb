"""The held-out-geometry protocol: each shape is tested by a classifier that never saw it.

Features are made here so the answer is known: a material's own signature plus a shape's
own signature. When the material signature is there, a classifier trained on other shapes
names the material of an unseen shape; when only the shape signature is there, it cannot
(a leak of test shapes into training would make it succeed).
"""

from __future__ import annotations

import numpy as np
import pytest

from aas_gym.experiments.protocols import held_out_geometry

MATERIALS = ["steel", "steel", "wood", "wood", "glass", "glass", "abs"]
SHAPES = ["steel_bar", "steel_can", "wood_bar", "wood_spoon", "glass_bar", "glass_bottle", "abs_box"]


def _data(material_weight: float, n: int = 12, seed: int = 0):
    rng = np.random.default_rng(seed)
    mat_sig = {m: rng.normal(size=40) for m in set(MATERIALS)}
    shape_sig = {s: rng.normal(size=40) for s in SHAPES}
    X, mats, shapes = [], [], []
    for m, s in zip(MATERIALS, SHAPES):
        for _ in range(n):
            X.append(np.exp(material_weight * mat_sig[m] + shape_sig[s] + 0.05 * rng.normal(size=40)))
            mats.append(m)
            shapes.append(s)
    return np.array(X), np.array(mats), np.array(shapes)


def test_a_material_signature_carries_over_to_unseen_shapes():
    X, m, s = _data(material_weight=3.0)
    results = held_out_geometry(X, m, s, excitation="linear")
    assert {r.protocol for r in results} == {"geometry"}
    best = max(r.accuracy for r in results)
    assert best > 90.0
    # Only shapes whose material comes in another shape are tested: abs_box (alone) is not.
    assert all(r.confusion.sum() == 6 * 12 for r in results)


def test_without_a_material_signature_unseen_shapes_are_not_recognized():
    # Each held-out shape is named as one material for all its samples: per draw the accuracy
    # moves in steps of 1/6; averaged over draws it sits near chance (about 1/3 here).
    accuracies = [np.mean([r.accuracy for r in held_out_geometry(*_data(0.0, seed=seed), excitation="linear")])
                  for seed in range(4)]
    assert np.mean(accuracies) < 50.0


def test_needs_a_material_in_two_shapes():
    X, m, s = _data(material_weight=1.0)
    one_shape_each = np.isin(s, ["steel_bar", "wood_bar", "abs_box"])
    with pytest.raises(ValueError, match="two shapes"):
        held_out_geometry(X[one_shape_each], m[one_shape_each], s[one_shape_each], excitation="linear")
