"""Small hand-made modal models for the synthesis tests (duck-typed like sensors.ModalModel).

A box-shaped "object" [-L/2, L/2] x [-a/2, a/2]^2 whose r modes have smooth, made-up 3-D
shapes: enough structure to couple modes through contact damping, and cheap.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

# Paper Table I damping (alpha [1/s], beta [s], gamma [s/m])
TABLE = {
    "abs": (4.0, 3e-7, 4e-2),
    "aluminium": (0.0, 5e-7, 2e-1),
    "steel": (5.0, 3e-8, 3e-1),
    "wood": (60.0, 4e-6, 5e-2),
}


class BoxModel:
    def __init__(self, freqs_hz, material="steel", length_m=0.2, width_m=0.02, mass_kg=0.6, seed=0):
        self.frequencies_hz = np.asarray(freqs_hz, dtype=float)
        self.angular_frequencies_rad_s = 2 * np.pi * self.frequencies_hz
        a, b, g = TABLE[material] if isinstance(material, str) else material
        self.material = SimpleNamespace(name=str(material), alpha=a, beta=b, gamma=g)
        self.L, self.a = length_m, width_m
        r = len(self.frequencies_hz)
        rng = np.random.default_rng(seed)
        self._k = np.arange(1, r + 1)
        self._dir = rng.normal(size=(r, 3))
        self._dir /= np.linalg.norm(self._dir, axis=1, keepdims=True)
        self._ph = rng.uniform(0, 2 * np.pi, size=(r, 3))
        self._amp = 1.0 / np.sqrt(mass_kg)  # mass-normalised shapes are ~ 1/sqrt(mass)

    def mode_shapes_at(self, points_m):
        p = np.atleast_2d(np.asarray(points_m, dtype=float))
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        k = self._k[None, :]
        s = (np.cos(np.pi * k * x[:, None] / self.L + self._ph[None, :, 0])
             * (1 + 0.5 * np.sin(k * y[:, None] / self.a + self._ph[None, :, 1]))
             * (1 + 0.5 * np.cos(k * z[:, None] / self.a + self._ph[None, :, 2])))
        return self._amp * s[:, None, :] * self._dir.T[None, :, :]  # (n, 3, r)

    def surface_distance_m(self, points_m):
        p = np.atleast_2d(np.asarray(points_m, dtype=float))
        half = np.array([self.L, self.a, self.a]) / 2
        q = np.abs(p) - half
        outside = np.linalg.norm(np.maximum(q, 0), axis=1)
        inside = np.minimum(q.max(axis=1), 0)
        return outside + inside


def box_points(model, n, rng):
    """n random points on the box surface with outward normals."""
    half = np.array([model.L, model.a, model.a]) / 2
    pts, nrm = [], []
    for _ in range(n):
        axis = rng.integers(3)
        sign = rng.choice([-1.0, 1.0])
        p = rng.uniform(-half, half)
        p[axis] = sign * half[axis]
        nv = np.zeros(3)
        nv[axis] = sign
        pts.append(p)
        nrm.append(nv)
    return np.array(pts), np.array(nrm)


def grasp(model):
    """Drive on the +y face, mic on the -y face, near x = L/4 (an antipodal grasp)."""
    h = model.a / 2
    return (np.array([0.05, h, 0.001]), np.array([0.0, 1.0, 0.0]),
            np.array([0.05, -h, 0.001]), np.array([0.0, -1.0, 0.0]))


def lsim_reference(model, C, u, sample_rate_hz, dp, dn, mp, mn, output="displacement", x0=None, interp=True):
    """Independent reference: scipy.signal.lsim (matrix exponential, linear input
    interpolation, or the input held per sample with ``interp=False``) of
    q'' + C q' + w^2 q = U_d^T (-n_d) u in plain [q; q'] coordinates.
    Returns (y, state trajectory in [q; q'])."""
    import scipy.signal as ss

    w = np.asarray(model.angular_frequencies_rad_s, dtype=float)
    r = len(w)
    U = model.mode_shapes_at(np.array([dp, mp]))
    b = -np.asarray(dn) @ U[0]
    o = np.asarray(mn) @ U[1]
    A = np.block([[np.zeros((r, r)), np.eye(r)], [-np.diag(w**2), -C]])
    B = np.concatenate([np.zeros(r), b])[:, None]
    if output == "displacement":
        Cm, D = np.concatenate([o, np.zeros(r)]), 0.0
    elif output == "velocity":
        Cm, D = np.concatenate([np.zeros(r), o]), 0.0
    else:
        Cm, D = o @ A[r:], o @ b
    t = np.arange(len(u)) / sample_rate_hz
    _, y, x = ss.lsim((A, B, Cm[None], np.array([[D]])), u, t, X0=x0, interp=interp)
    return y, x
