"""Contact datastream: every contact of each sensed object, in the object's frame.

MuJoCo conventions (checked in tests/test_scene_contacts.py): ``data.contact.frame[i][:3]`` is
the contact normal pointing from ``geom[0]`` to ``geom[1]``; ``mj_contactForce`` returns the
force in the contact frame (normal, then two tangential components) that acts on ``geom[1]``,
its normal component >= 0 (repulsive). So for a sensed object that is ``geom[0]`` the outward
surface normal is ``+n`` and the force on the object is ``-F``; as ``geom[1]`` they are ``-n``
and ``+F``. Read the stream after ``mj_step`` (forces are those of the last step's solve).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np

#: Contact kinds, from the sensed object's point of view.
KINDS = ("actuator", "mic", "hand", "object", "environment", "other")


@dataclass(frozen=True)
class ObjectContacts:
    """All contacts of one sensed object after a step, as arrays in the object's frame.

    Attributes:
        body: name of the sensed object's body.
        positions_m: (n, 3) contact points (MuJoCo's mid-penetration point).
        normals: (n, 3) unit OUTWARD normals of the object surface.
        normal_forces_n: (n,) normal force magnitudes [N] (>= 0).
        forces_n: (n, 3) total contact force acting ON the object (normal + friction) [N].
        friction: (n,) sliding friction coefficients of the contact pairs.
        penetration_m: (n,) penetration depths (>= 0 when overlapping).
        kinds: (n,) one of ``KINDS`` per contact.
        other_bodies: (n,) names of the touching bodies.
        other_geoms: (n,) names (or ``geom<id>``) of the touching geoms.
    """

    body: str
    positions_m: np.ndarray
    normals: np.ndarray
    normal_forces_n: np.ndarray
    forces_n: np.ndarray
    friction: np.ndarray
    penetration_m: np.ndarray
    kinds: np.ndarray
    other_bodies: np.ndarray
    other_geoms: np.ndarray = field(repr=False)

    def __len__(self) -> int:
        return len(self.normal_forces_n)

    def select(self, mask) -> "ObjectContacts":
        """Subset by boolean mask or kind name(s)."""
        if isinstance(mask, str) or (isinstance(mask, (tuple, list)) and mask and isinstance(mask[0], str)):
            kinds = (mask,) if isinstance(mask, str) else tuple(mask)
            unknown = set(kinds) - set(KINDS)
            if unknown:
                raise ValueError(f"unknown contact kind(s) {sorted(unknown)}; known: {list(KINDS)}")
            mask = np.isin(self.kinds, kinds)
        mask = np.asarray(mask, dtype=bool)
        return ObjectContacts(self.body, self.positions_m[mask], self.normals[mask], self.normal_forces_n[mask],
                              self.forces_n[mask], self.friction[mask], self.penetration_m[mask],
                              self.kinds[mask], self.other_bodies[mask], self.other_geoms[mask])

    def total_normal_force_n(self, kind: str | None = None) -> float:
        """Sum of normal forces, optionally of one kind only."""
        sel = self if kind is None else self.select(kind)
        return float(np.sum(sel.normal_forces_n))

    def to_sensor_contacts(self, min_force_n: float = 0.0) -> list:
        """Each contact as a ``sensors.Contact`` (object frame, outward normal)."""
        from sensors.contact import Contact

        return [Contact(position_m=p, normal=n, force_n=float(f), friction=float(mu))
                for p, n, f, mu in zip(self.positions_m, self.normals, self.normal_forces_n, self.friction)
                if f > min_force_n]

    def merged(self, kind: str) -> tuple[np.ndarray, np.ndarray, float, float] | None:
        """One equivalent contact for all contacts of ``kind`` (a fingertip pad touches a face
        at several points): force-weighted mean point and normal, summed force, mean friction.
        ``None`` if there is no such contact carrying force."""
        sel = self.select(kind)
        total = float(np.sum(sel.normal_forces_n))
        if len(sel) == 0 or total <= 0.0:
            return None
        w = sel.normal_forces_n / total
        point = w @ sel.positions_m
        normal = w @ sel.normals
        norm = np.linalg.norm(normal)
        if norm < 1e-9:  # opposite normals cancel: not one contact patch
            return None
        return point, normal / norm, total, float(w @ sel.friction)

    def as_dict(self) -> dict:
        """Plain arrays (for ``info`` and datasets)."""
        return {"positions_m": self.positions_m.copy(), "normals": self.normals.copy(),
                "normal_forces_n": self.normal_forces_n.copy(), "forces_n": self.forces_n.copy(),
                "friction": self.friction.copy(), "kinds": self.kinds.tolist(),
                "other_bodies": self.other_bodies.tolist()}


class ContactStream:
    """Reads the contacts of the sensed bodies of a model after each step.

    Args:
        model: the MuJoCo model.
        bodies: names of the sensed object bodies.
        actuator_site, mic_site: names of the sensor sites; contacts with geoms of the bodies
            holding them are of kind ``actuator`` / ``mic``. Models without them are allowed
            (no contact is then of those kinds).
    """

    def __init__(self, model: mujoco.MjModel, bodies: Iterable[str],
                 actuator_site: str = "aas_actuator", mic_site: str = "aas_mic") -> None:
        self.model = model
        self.bodies = list(bodies)
        self.body_ids = np.array([_body_id(model, b) for b in self.bodies], dtype=int)
        self._body_index = np.full(model.nbody, -1, dtype=int)
        self._body_index[self.body_ids] = np.arange(len(self.body_ids))
        self._geom_body = np.asarray(model.geom_bodyid)
        # Kind of contact with each body (from the sensed object's view).
        kind = np.full(model.nbody, KINDS.index("other"), dtype=int)
        static = np.asarray(model.body_weldid) == 0
        kind[static] = KINDS.index("environment")
        roots = np.asarray(model.body_rootid)
        site_bodies = {}
        for key, site in (("actuator", actuator_site), ("mic", mic_site)):
            sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
            if sid >= 0:
                site_bodies[key] = int(model.site_bodyid[sid])
        for b in site_bodies.values():
            kind[(roots == roots[b]) & ~static] = KINDS.index("hand")
        for key, b in site_bodies.items():
            # Only the body carrying the site (our replaceable fingertip) is the sensor contact;
            # the finger link or housing touching the object is a plain hand contact.
            kind[b] = KINDS.index(key)
        kind[self.body_ids] = KINDS.index("object")
        self._kind_of_body = kind
        self._body_names = np.array([mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or f"body{i}"
                                     for i in range(model.nbody)], dtype=object)
        self._geom_names = np.array([mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) or f"geom{i}"
                                     for i in range(model.ngeom)], dtype=object)
        self._f6 = np.zeros(6)

    def read(self, data: mujoco.MjData) -> dict[str, ObjectContacts]:
        """Body name -> ``ObjectContacts`` for the current state of ``data``."""
        out = {}
        ncon = data.ncon
        if ncon:
            geoms = np.asarray(data.contact.geom)[:ncon]
            gbody = self._geom_body[geoms]
            sensed = self._body_index[gbody]  # (ncon, 2) index into self.bodies or -1
            rows, sides = np.nonzero(sensed >= 0)
        else:
            rows = sides = np.zeros(0, dtype=int)
        per_body: dict[int, list] = {i: [] for i in range(len(self.bodies))}
        for r, s in zip(rows, sides):
            per_body[int(sensed[r, s])].append((int(r), int(s)))
        for i, name in enumerate(self.bodies):
            out[name] = self._object_contacts(data, i, per_body[i], geoms if ncon else None)
        return out

    def _object_contacts(self, data, index: int, items, geoms) -> ObjectContacts:
        n = len(items)
        pos = np.zeros((n, 3))
        nrm = np.zeros((n, 3))
        fn = np.zeros(n)
        fvec = np.zeros((n, 3))
        mu = np.zeros(n)
        pen = np.zeros(n)
        kinds = np.empty(n, dtype=object)
        others = np.empty(n, dtype=object)
        other_geoms = np.empty(n, dtype=object)
        b = self.body_ids[index]
        xpos = data.xpos[b]
        rot = data.xmat[b].reshape(3, 3)
        for k, (r, side) in enumerate(items):
            con = data.contact[r]
            frame = con.frame.reshape(3, 3)
            sign = 1.0 if side == 0 else -1.0  # object is geom[0]: normal points out of it
            mujoco.mj_contactForce(self.model, data, r, self._f6)
            f_world = frame.T @ self._f6[:3]  # force on geom[1]
            pos[k] = rot.T @ (con.pos - xpos)
            nrm[k] = rot.T @ (sign * frame[0])
            fn[k] = max(self._f6[0], 0.0)
            fvec[k] = rot.T @ (-sign * f_world)
            mu[k] = con.friction[0]
            pen[k] = -con.dist
            other_geom = geoms[r, 1 - side]
            other_body = self._geom_body[other_geom]
            kinds[k] = KINDS[self._kind_of_body[other_body]]
            others[k] = self._body_names[other_body]
            other_geoms[k] = self._geom_names[other_geom]
        return ObjectContacts(self.bodies[index], pos, nrm, fn, fvec, mu, pen, kinds.astype(str) if n else
                              np.zeros(0, dtype=str), others, other_geoms)


def _body_id(model: mujoco.MjModel, name: str) -> int:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        raise ValueError(f"model has no body named {name!r}")
    if bid == 0:
        raise ValueError("the world body cannot be a sensed object")
    return bid


def object_contacts(model: mujoco.MjModel, data: mujoco.MjData,
                    bodies: Iterable[str] | Mapping[str, object]) -> dict[str, ObjectContacts]:
    """One-shot convenience: ``ContactStream(model, bodies).read(data)``."""
    return ContactStream(model, list(bodies)).read(data)
