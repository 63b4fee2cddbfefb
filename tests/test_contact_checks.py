"""sensors.Contact's fast checks (FAST_CONTACT_CHECKS) store what the general checks store, bit
for bit, and leave every input they do not accept (invalid ones included) to the general checks."""

from dataclasses import replace

import numpy as np
import pytest

from sensors import Contact
from sensors.modal import contact as contact_module

FIELDS = ("position_m", "normal", "force_n", "friction", "normal_stiffness_n_per_m",
          "tangential_stiffness_n_per_m", "radius_m", "counter_material")


def _build(fast: bool, *args, **kwargs):
    saved = contact_module.FAST_CONTACT_CHECKS
    contact_module.FAST_CONTACT_CHECKS = fast
    try:
        return Contact(*args, **kwargs)
    finally:
        contact_module.FAST_CONTACT_CHECKS = saved


def _same_bits(a: Contact, b: Contact) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert type(y) is np.ndarray and x.dtype == y.dtype == np.float64 and x.shape == y.shape == (3,)
            assert x.tobytes() == y.tobytes(), name
            assert not x.flags.writeable and not y.flags.writeable
        else:
            assert type(x) is type(y) and (x == y or (x is None and y is None)), name


def _random_inputs(rng, n):
    for _ in range(n):
        p = rng.normal(size=3) * 0.05
        nrm = rng.normal(size=3)
        nrm = (nrm / np.linalg.norm(nrm)).astype(np.float32).astype(float)   # float32 rounding, as MuJoCo's
        nrm *= 1.0 + rng.uniform(-5e-5, 5e-5)                                 # within NORMAL_TOLERANCE
        kw = dict(force_n=float(rng.uniform(0, 40)), friction=float(rng.uniform(0, 1)))
        if rng.random() < 0.5:
            kw["normal_stiffness_n_per_m"] = float(rng.uniform(0, 1e7))
            kw["tangential_stiffness_n_per_m"] = np.float64(rng.uniform(0, 1e7))
        if rng.random() < 0.3:
            kw["radius_m"], kw["counter_material"] = float(rng.uniform(1e-3, 1e-2)), "steel"
        yield p, nrm, kw


def test_fast_checks_store_the_reference_bits():
    rng = np.random.default_rng(7)
    taken = 0
    for p, nrm, kw in _random_inputs(rng, 300):
        fast, ref = _build(True, p, nrm, **kw), _build(False, p, nrm, **kw)
        _same_bits(fast, ref)
        # the fast path did run (it would fail here if it declined these plain inputs)
        taken += _accepts(p, nrm, kw)
        # replace() of a checked contact (the fingertip pads) goes through the checks again
        _same_bits(replace(fast, normal_stiffness_n_per_m=2e6), _build(False, ref.position_m, ref.normal,
                                                                       **dict(kw, normal_stiffness_n_per_m=2e6)))
    assert taken == 300


def _accepts(p, nrm, kw) -> bool:
    c = Contact.__new__(Contact)
    defaults = dict(normal_stiffness_n_per_m=None, tangential_stiffness_n_per_m=None, radius_m=5e-3,
                    counter_material="wood")
    for k, v in {**defaults, "position_m": p, "normal": nrm, **kw}.items():
        object.__setattr__(c, k, v)
    return c._plain_fields()


BAD = [
    dict(position_m=np.array([0.0, np.nan, 0.0])),
    dict(position_m=np.array([0.0, 0.0, np.inf])),
    dict(normal=np.array([0.0, 0.0, 2.0])),
    dict(normal=np.array([0.0, 0.0, 0.0])),
    dict(force_n=-1.0),
    dict(force_n=float("nan")),
    dict(friction=-0.1),
    dict(friction=float("inf")),
    dict(normal_stiffness_n_per_m=-1.0),
    dict(tangential_stiffness_n_per_m=float("nan")),
    dict(radius_m=0.0),
    dict(radius_m=-1e-3),
    dict(counter_material="unobtainium"),
    dict(counter_material=3.0),
    dict(force_n=True),
    dict(position_m=np.array([0.0, 0.0])),
    dict(position_m=np.array([1, 2, 3])),
]


@pytest.mark.parametrize("bad", BAD)
def test_fast_checks_leave_bad_input_to_the_general_checks(bad):
    base = dict(position_m=np.array([0.01, 0.0, 0.02]), normal=np.array([0.0, 0.0, 1.0]), force_n=5.0, friction=0.5)
    args = {**base, **bad}
    errors = []
    for fast in (True, False):
        try:
            c = _build(fast, **args)
            errors.append(("ok", c))
        except (TypeError, ValueError, KeyError) as e:
            errors.append((type(e), str(e)))
    if errors[1][0] == "ok":
        _same_bits(errors[0][1], errors[1][1])     # accepted by both (e.g. integer positions): the same bits
    else:
        assert errors[0] == errors[1]


def test_other_input_types_take_the_general_checks():
    # lists, float32 arrays and integer forces are not the fast path's inputs: the same result
    for args in [([0.01, 0.0, 0.02], [0.0, 0.0, 1.0], 5, 0.5),
                 (np.array([0.01, 0.0, 0.02], np.float32), np.array([0.0, 0.6, 0.8], np.float32), 5.0, 0.5)]:
        _same_bits(_build(True, *args), _build(False, *args))
