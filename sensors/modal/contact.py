"""A contact point on an object, in the object (modal model) frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._infra.checks import holds_bool, real_number

# Normals coming from MuJoCo are float32 and renormalised upstream; 1e-4 accepts rounding
# but rejects a vector that was never normalised (or a force vector passed by mistake).
NORMAL_TOLERANCE = 1e-4


def _vector3(value, name: str) -> np.ndarray:
    """A copy of ``value`` as a float 3-vector; TypeError for booleans, strings or objects."""
    v = np.array(value)
    if v.dtype.kind not in "iuf" or holds_bool(value):
        raise TypeError(f"Contact {name} must be 3 numbers, got {value!r}")
    v = v.astype(float).reshape(-1)
    if v.shape != (3,):
        raise ValueError(f"Contact position_m and normal must be 3-vectors, got {name} of shape {v.shape}")
    return v


@dataclass(frozen=True, eq=False)
class Contact:
    """One contact point on the object.

    Parameters
    ----------
    position_m : (3,) contact point in the object frame [m].
    normal : (3,) unit OUTWARD surface normal of the object at the point (object frame).
        A finger pushing on the object pushes along ``-normal``.
    force_n : normal force magnitude [N], >= 0 (it scales the contact damping).
    friction : Coulomb friction coefficient mu >= 0.

    Raises ``ValueError`` for non-finite values, a normal whose length differs from 1 by more
    than ``NORMAL_TOLERANCE``, a negative force or a negative friction coefficient.  The
    normal is stored renormalised; arrays are stored read-only.
    """

    position_m: np.ndarray
    normal: np.ndarray
    force_n: float
    friction: float

    def __post_init__(self) -> None:
        p, n = _vector3(self.position_m, "position_m"), _vector3(self.normal, "normal")
        if p.shape != (3,) or n.shape != (3,):
            raise ValueError(f"Contact position_m and normal must be 3-vectors, got {p.shape} and {n.shape}")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
            raise ValueError(f"Contact position_m/normal must be finite, got {p} / {n}")
        length = float(np.linalg.norm(n))
        if abs(length - 1.0) > NORMAL_TOLERANCE:
            raise ValueError(f"Contact normal must be a unit vector (|n| = {length:.6g})")
        f = real_number(self.force_n, "Contact force_n [N]")
        mu = real_number(self.friction, "Contact friction")
        if not np.isfinite(f) or f < 0.0:
            raise ValueError(f"Contact force_n must be finite and >= 0 N, got {self.force_n!r}")
        if not np.isfinite(mu) or mu < 0.0:
            raise ValueError(f"Contact friction must be finite and >= 0, got {self.friction!r}")
        n = n / length
        p.setflags(write=False)
        n.setflags(write=False)
        object.__setattr__(self, "position_m", p)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "force_n", f)
        object.__setattr__(self, "friction", mu)

    def _key(self) -> tuple:
        return (*self.position_m.tolist(), *self.normal.tolist(), self.force_n, self.friction)

    def __eq__(self, other) -> bool:
        return isinstance(other, Contact) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def to_dict(self) -> dict:
        """Plain-Python form (JSON-serialisable)."""
        return {
            "position_m": self.position_m.tolist(),
            "normal": self.normal.tolist(),
            "force_n": self.force_n,
            "friction": self.friction,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Contact":
        return cls(d["position_m"], d["normal"], d["force_n"], d["friction"])

    def __repr__(self) -> str:
        p = ", ".join(f"{v:.4g}" for v in self.position_m)
        n = ", ".join(f"{v:.3g}" for v in self.normal)
        return f"Contact(position_m=[{p}], normal=[{n}], force_n={self.force_n:.4g}, friction={self.friction:.3g})"
