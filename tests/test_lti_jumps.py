"""State jumps inside one response (``DiscreteSystem.response(..., jumps=...)``) and free
propagation (``DiscreteSystem.free_state``), against the split evaluation and matrix powers."""

import numpy as np
import pytest

from sensors.synthesis.lti import lti_system


def _system(method):
    """A damped 4-state system (two coupled oscillators), in complex modes or dense form."""
    A = np.array([[0.0, 0.0, 900.0, 0.0], [0.0, 0.0, 0.0, 2300.0],
                  [-900.0, 0.0, -30.0, 12.0], [0.0, -2300.0, 12.0, -55.0]])
    return lti_system(A, [0.0, 0.0, 1.0, -0.4], [0.7, 0.2, 0.0, 0.1], 0.0, 8000.0, method=method)


@pytest.mark.parametrize("method", ["auto", "dense"])
def test_a_jump_equals_restarting_from_the_end_state_plus_the_jump(method):
    sysm = _system(method)
    rng = np.random.default_rng(3)
    u = rng.standard_normal(301)
    x0 = rng.standard_normal(4)
    jumps = [(9, rng.standard_normal(4)), (170, rng.standard_normal(4))]
    y = sysm.response(u[:300], x0, jumps)
    # reference: three pieces, each from the previous one's end state plus the jump
    ref, x, at = [], x0, 0
    for k, dx in jumps + [(300, None)]:
        ref.append(sysm.response(u[at:k], x))
        if dx is not None:
            x = sysm.final_state(u[at:k + 1], x) + dx
        at = k
    ref = np.concatenate(ref)
    assert np.abs(y - ref).max() <= 1e-12 * np.abs(ref).max()
    assert not np.allclose(y, sysm.response(u[:300], x0), atol=1e-3 * np.abs(ref).max())   # the jumps are heard


@pytest.mark.parametrize("method", ["auto", "dense"])
def test_free_state_is_the_transition_matrix_power(method):
    sysm = _system(method)
    x = np.random.default_rng(4).standard_normal(4)
    ref = np.linalg.matrix_power(sysm.transition_matrix(), 57) @ x
    assert np.allclose(sysm.free_state(x, 57), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert np.allclose(sysm.free_state(x, 57), sysm.final_state(np.zeros(58), x), rtol=0, atol=1e-12 * np.abs(ref).max())
