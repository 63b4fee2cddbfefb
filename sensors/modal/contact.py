"""A contact point on an object, in the object (modal model) frame."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._infra.checks import holds_bool, real_number
from ..materials.solids import get_material
from .contact_stiffness import DEFAULT_CONTACT_RADIUS_M, DEFAULT_COUNTER_MATERIAL

# Normals coming from MuJoCo are float32 and renormalised upstream; 1e-4 accepts rounding
# but rejects a vector that was never normalised (or a force vector passed by mistake).
NORMAL_TOLERANCE = 1e-4

#: Whether a contact whose fields are already float64 3-arrays and floats (what the MuJoCo side
#: and ``dataclasses.replace`` of a contact pass) is checked with plain-Python tests (True, fast:
#: about 6 against 20 us a contact, which a FillLevel-v0 probe pays for some 40 contacts) or
#: by the general checks (False, the reference).  The fast path stores the same values, bit
#: for bit (the same copies, ``np.linalg.norm``'s own ``sqrt(n . n)`` and the same division),
#: and hands every input it does not accept, invalid ones included, to the general checks
#: (``tests/test_contact_checks.py``).  Read at each call.
FAST_CONTACT_CHECKS = True
_FLOAT_TYPES = (float, np.float64)


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
    force_n : normal force magnitude [N], >= 0 (it scales the contact damping and sets the
        Hertz stiffness); 0: the contact does not touch.
    friction : Coulomb friction coefficient mu >= 0.
    normal_stiffness_n_per_m, tangential_stiffness_n_per_m : the contact's spring [N/m] along
        the normal and across it (both tangential directions).  ``None`` (default): derived
        from the force, ``radius_m`` and both bodies' elastic constants, Hertz normal and, for
        a contact with friction (it sticks), Mindlin tangential
        (:mod:`sensors.modal.contact_stiffness`); ``0``: no spring.  The fingertip pads get
        theirs from ``sensors.FingertipModel``.  Used with ``contact_model="spring_damper"``
        (the default of the synthesis); ``"damping"`` ignores them (the paper's model).
    radius_m : effective radius of curvature [m] of the contact for Hertz (default
        ``DEFAULT_CONTACT_RADIUS_M`` = 5 mm, a rounded edge on a flat).
    counter_material : the material name of the other body (default ``"wood"``, a table).

    Raises ``ValueError`` for non-finite values, a normal whose length differs from 1 by more
    than ``NORMAL_TOLERANCE``, a negative force or a negative friction coefficient.  The
    normal is stored renormalised; arrays are stored read-only.
    """

    position_m: np.ndarray
    normal: np.ndarray
    force_n: float
    friction: float
    normal_stiffness_n_per_m: float | None = None
    tangential_stiffness_n_per_m: float | None = None
    radius_m: float = DEFAULT_CONTACT_RADIUS_M
    counter_material: str = DEFAULT_COUNTER_MATERIAL

    def __post_init__(self) -> None:
        if FAST_CONTACT_CHECKS and self._plain_fields():
            return
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
        for name in ("normal_stiffness_n_per_m", "tangential_stiffness_n_per_m"):
            k = getattr(self, name)
            if k is not None:
                k = real_number(k, f"Contact {name} [N/m]")
                if k < 0.0:
                    raise ValueError(f"Contact {name} must be >= 0 N/m or None, got {k!r}")
                object.__setattr__(self, name, k)
        radius = real_number(self.radius_m, "Contact radius_m [m]", above=0.0)
        if not isinstance(self.counter_material, str):
            raise TypeError(f"Contact counter_material must be a material name, got {self.counter_material!r}")
        get_material(self.counter_material)  # KeyError listing the names for an unknown one
        self._store(p, n / length, f, mu, radius)

    def _store(self, p: np.ndarray, n: np.ndarray, f: float, mu: float, radius: float) -> None:
        """Keep the checked values, the vectors read-only (both check paths end here)."""
        p.setflags(write=False)
        n.setflags(write=False)
        object.__setattr__(self, "position_m", p)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "force_n", f)
        object.__setattr__(self, "friction", mu)
        object.__setattr__(self, "radius_m", radius)

    def _plain_fields(self) -> bool:
        """Check and store fields that are float64 3-arrays and floats, valid ones only, as the
        general checks store them (:data:`FAST_CONTACT_CHECKS`); False leaves everything to them."""
        p, n = self.position_m, self.normal
        if type(p) is not np.ndarray or type(n) is not np.ndarray or p.dtype != np.float64 \
                or n.dtype != np.float64 or p.shape != (3,) or n.shape != (3,):
            return False
        f, mu, radius = self.force_n, self.friction, self.radius_m
        kn, kt = self.normal_stiffness_n_per_m, self.tangential_stiffness_n_per_m
        if type(f) not in _FLOAT_TYPES or type(mu) not in _FLOAT_TYPES or type(radius) not in _FLOAT_TYPES \
                or (kn is not None and type(kn) not in _FLOAT_TYPES) \
                or (kt is not None and type(kt) not in _FLOAT_TYPES) or type(self.counter_material) is not str:
            return False
        values = p.tolist() + n.tolist()
        if not all(map(math.isfinite, values)):
            return False
        f, mu, radius = float(f), float(mu), float(radius)
        if not (math.isfinite(f) and f >= 0.0 and math.isfinite(mu) and mu >= 0.0
                and math.isfinite(radius) and radius > 0.0):
            return False
        ks = [None if k is None else float(k) for k in (kn, kt)]
        if any(k is not None and not (math.isfinite(k) and k >= 0.0) for k in ks):
            return False
        length = float(np.sqrt(n.dot(n)))       # np.linalg.norm of a 1-D real array, bit for bit
        if abs(length - 1.0) > NORMAL_TOLERANCE:
            return False
        try:
            get_material(self.counter_material)
        except (KeyError, TypeError):
            return False
        object.__setattr__(self, "normal_stiffness_n_per_m", ks[0])
        object.__setattr__(self, "tangential_stiffness_n_per_m", ks[1])
        self._store(p.copy(), n / length, f, mu, radius)
        return True

    def _key(self) -> tuple:
        return (*self.position_m.tolist(), *self.normal.tolist(), self.force_n, self.friction,
                self.normal_stiffness_n_per_m, self.tangential_stiffness_n_per_m, self.radius_m,
                self.counter_material)

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
            "normal_stiffness_n_per_m": self.normal_stiffness_n_per_m,
            "tangential_stiffness_n_per_m": self.tangential_stiffness_n_per_m,
            "radius_m": self.radius_m,
            "counter_material": self.counter_material,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Contact":
        """The contact of :meth:`to_dict` (a dict written before the stiffness fields existed
        reads with their defaults)."""
        return cls(d["position_m"], d["normal"], d["force_n"], d["friction"],
                   d.get("normal_stiffness_n_per_m"), d.get("tangential_stiffness_n_per_m"),
                   d.get("radius_m", DEFAULT_CONTACT_RADIUS_M), d.get("counter_material", DEFAULT_COUNTER_MATERIAL))

    def __repr__(self) -> str:
        p = ", ".join(f"{v:.4g}" for v in self.position_m)
        n = ", ".join(f"{v:.3g}" for v in self.normal)
        extra = "".join(f", {k}={getattr(self, k):.4g}" for k in ("normal_stiffness_n_per_m", "tangential_stiffness_n_per_m")
                        if getattr(self, k) is not None)
        return (f"Contact(position_m=[{p}], normal=[{n}], force_n={self.force_n:.4g}, friction={self.friction:.3g}"
                f"{extra})")
