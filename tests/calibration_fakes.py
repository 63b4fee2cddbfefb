"""An analytic free-free bar (Euler-Bernoulli bending in two planes, axial modes) duck-typed
like ``sensors.ModalModel``: an independent reference for the calibration tests, whose
frequencies scale with sqrt(E) by construction and whose mass-normalised shapes are known
in closed form (for a free-free beam, the mean of psi^2 over the length is exactly 1)."""

from __future__ import annotations

import numpy as np

from sensors import Contact
from sensors.materials.solids import Material

BETA_L = np.array([4.730041, 7.853205, 10.995608, 14.137165, 17.278760])


def _beta_l(n: int) -> float:
    return float(BETA_L[n]) if n < BETA_L.size else (2 * n + 3) * np.pi / 2


class AnalyticBar:
    """Bar along x, centred at 0, width along y, height along z; modes up to ``f_max_hz``."""

    def __init__(self, length_m, width_m, height_m, material: Material, f_max_hz=12000.0):
        self.L, self.w, self.h = length_m, width_m, height_m
        self.material = material
        E, rho = material.youngs_modulus_pa, material.density_kg_m3
        self.mass_kg = rho * length_m * width_m * height_m
        area = width_m * height_m
        modes = []  # (frequency, kind, index)
        for axis, inertia in (("y", height_m * width_m**3 / 12), ("z", width_m * height_m**3 / 12)):
            n = 0
            while True:
                bl = _beta_l(n)
                f = bl**2 / (2 * np.pi * length_m**2) * np.sqrt(E * inertia / (rho * area))
                if f > f_max_hz:
                    break
                modes.append((f, axis, bl))
                n += 1
        n = 1
        while n / (2 * length_m) * np.sqrt(E / rho) <= f_max_hz:
            modes.append((n / (2 * length_m) * np.sqrt(E / rho), "x", n))
            n += 1
        modes.sort(key=lambda m: m[0])
        self._modes = modes
        self.frequencies_hz = np.array([m[0] for m in modes])
        self.angular_frequencies_rad_s = 2 * np.pi * self.frequencies_hz

    def mode_shapes_at(self, points_m):
        p = np.atleast_2d(np.asarray(points_m, float))
        xi = p[:, 0] + self.L / 2
        out = np.zeros((p.shape[0], 3, len(self._modes)))
        norm = 1 / np.sqrt(self.mass_kg)
        for j, (_, kind, k) in enumerate(self._modes):
            if kind == "x":
                out[:, 0, j] = np.sqrt(2) * norm * np.cos(k * np.pi * xi / self.L)
                continue
            bl = k
            b = bl / self.L
            kk = (np.cosh(bl) - np.cos(bl)) / (np.sinh(bl) - np.sin(bl))
            x = b * xi
            # cosh x - kk sinh x, written without the cancellation of two huge terms
            hyper = 0.5 * ((1 - kk) * np.exp(x) + (1 + kk) * np.exp(-x))
            psi = hyper + np.cos(x) - kk * np.sin(x)
            out[:, 1 if kind == "y" else 2, j] = norm * psi
        return out

    def surface_distance_m(self, points_m):
        p = np.atleast_2d(np.asarray(points_m, float))
        q = np.abs(p) - np.array([self.L, self.w, self.h]) / 2
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)

    def grasp(self, x_m: float, force_n: float, friction: float = 0.5):
        """Antipodal grasp on the +-z faces at x (actuator on +z, mic on -z)."""
        h = self.h / 2
        return (Contact([x_m, 0.002, h], [0, 0, 1], force_n, friction),
                Contact([x_m, 0.002, -h], [0, 0, -1], force_n, friction))
