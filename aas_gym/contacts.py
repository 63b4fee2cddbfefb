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
from typing import Any, NamedTuple

import mujoco
import numpy as np

#: Contact kinds, from the sensed object's point of view.
KINDS = ("actuator", "mic", "hand", "object", "environment", "other")
_ACTUATOR, _MIC = KINDS.index("actuator"), KINDS.index("mic")
# as a plain int: comparing the option's int with the enum member costs ~10 us per test
_ELLIPTIC = int(mujoco.mjtCone.mjCONE_ELLIPTIC)
#: The contacts of some kinds as an OR of ``kinds == name`` (one comparison per name) instead of
#: ``np.isin`` (which sorts both sides: ~30 us a call, three calls per grasp): the same booleans
#: (string equality either way).  False: ``np.isin`` (the reference; ``tests/test_episode_glue.py``).
#: Read at each call.
KIND_EQUALITY = True
#: Elliptic cones: :meth:`ContactStream.read` gathers every contact's three force rows with one
#: index when every read contact has them (rows present, ``dim`` >= 3), instead of three masked
#: assignments (~25 us a read); the same ``efc_force`` values land in the same places.  False:
#: the masked assignments (the reference; ``tests/test_episode_glue.py``).  Read at each call.
GATHER_FORCES = True
#: :meth:`ContactStream.fingertip_rows` (the actuator and mic fingertips' normal rows of a body,
#: summed when asked: ``aas_gym.grasp.planar_grasp`` sums the mic's only when it tests for
#: rest) and :meth:`ContactStream.fingertip_forces_n` without the two ``any`` tests (empty sums
#: are 0.0 either way).  False: the reference.  Read at each call.
LEAN_FINGERTIPS = True
#: Whether :func:`row_force_sum_n` sums fewer than 8 rows in Python (~2 us instead of ~10): numpy
#: adds fewer than 8 values one by one from 0.0 (its pairwise sum starts at 8), so the clipped
#: forces added in the same order give the same float.  False: numpy (the reference;
#: ``tests/test_episode_glue.py``).  Read at each call.
PYTHON_SUMS = True
#: Whether :meth:`ContactStream.read` takes the read arrays as they are for a body that has every
#: read contact (one sensed body: always), instead of indexing them with all their rows (six
#: copies of fresh arrays that nothing else holds).  False: the indexing (the reference;
#: ``tests/test_episode_glue.py``).  Read at each call.
WHOLE_SELECTION = True


def kind_mask(kinds: np.ndarray, names) -> np.ndarray:
    """Whether each entry of the string array ``kinds`` is one of ``names`` (bool, ``kinds``' shape)."""
    if not KIND_EQUALITY:
        return np.isin(kinds, names)
    out = np.zeros(np.shape(kinds), dtype=bool)
    for name in names:
        out |= kinds == name
    return out


class SensorGrasp(NamedTuple):
    """An object's contacts as the acoustic sensor takes them (``sensors.Contact``, object
    frame): one merged contact per sensor fingertip (``None`` where that fingertip does not
    press the object, or presses it on opposite sides), and the other contacts."""

    actuator: Any
    mic: Any
    others: list


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
        mask = self._mask(mask)
        return ObjectContacts(self.body, self.positions_m[mask], self.normals[mask], self.normal_forces_n[mask],
                              self.forces_n[mask], self.friction[mask], self.penetration_m[mask],
                              self.kinds[mask], self.other_bodies[mask], self.other_geoms[mask])

    def _mask(self, mask) -> np.ndarray:
        """A boolean mask, or the contacts of the kind name(s) given as one."""
        if isinstance(mask, str) or (isinstance(mask, (tuple, list)) and mask and isinstance(mask[0], str)):
            kinds = (mask,) if isinstance(mask, str) else tuple(mask)
            unknown = set(kinds) - set(KINDS)
            if unknown:
                raise ValueError(f"unknown contact kind(s) {sorted(unknown)}; known: {list(KINDS)}")
            return kind_mask(self.kinds, kinds)
        return np.asarray(mask, dtype=bool)

    def total_normal_force_n(self, kind: str | None = None) -> float:
        """Sum of normal forces, optionally of one kind only."""
        if kind is None:
            return float(np.sum(self.normal_forces_n))
        if not isinstance(kind, str) or kind not in KINDS:
            return float(np.sum(self.select(kind).normal_forces_n))   # several kinds, or the ValueError
        # the same elements select(kind) keeps, summed in the same order (no subset built)
        return float(np.sum(self.normal_forces_n[self.kinds == kind]))

    def to_sensor_contacts(self, min_force_n: float = 0.0, materials=None) -> list:
        """Each contact as a ``sensors.Contact`` (object frame, outward normal); ``materials``
        maps a touching body's name to its material name, the other body of the contact's
        Hertz stiffness (others: the ``Contact`` default, a wooden table)."""
        from sensors.modal.contact import Contact
        from sensors.modal.contact_stiffness import DEFAULT_COUNTER_MATERIAL

        materials = materials or {}
        return [Contact(position_m=p, normal=n, force_n=float(f), friction=float(mu),
                        counter_material=materials.get(str(b), DEFAULT_COUNTER_MATERIAL))
                for p, n, f, mu, b in zip(self.positions_m, self.normals, self.normal_forces_n, self.friction,
                                          self.other_bodies)
                if f > min_force_n]

    def sensor_grasp(self, min_force_n: float = 0.0, materials=None, others: bool = True) -> SensorGrasp:
        """The contacts the acoustic sensor synthesizes from: each fingertip's contacts
        :meth:`merged` into one, and every other contact carrying more than ``min_force_n``
        (hand links, table, other objects; ``materials``: see :meth:`to_sensor_contacts`).
        The one place MuJoCo contacts become ``sensors.Contact`` for the simulated sensor
        and its stream.  ``others=False``: the fingertips only (``others`` None), for a caller
        that takes the other contacts from :meth:`other_sensor_contacts` when it needs them."""
        from sensors.modal.contact import Contact

        tips = []
        for kind in ("actuator", "mic"):
            patch = self.merged(kind)
            tips.append(None if patch is None else Contact(position_m=patch[0], normal=patch[1], force_n=patch[2],
                                                           friction=patch[3]))
        return SensorGrasp(tips[0], tips[1], self.other_sensor_contacts(min_force_n, materials) if others else None)

    def other_sensor_contacts(self, min_force_n: float = 0.0, materials=None) -> list:
        """:meth:`sensor_grasp`'s other contacts: all but the fingertips', as ``sensors.Contact``."""
        return self.select(~kind_mask(self.kinds, ("actuator", "mic"))).to_sensor_contacts(min_force_n, materials)

    def sensor_loads(self, min_force_n: float = 0.0, pressing_before=None):
        """The forces every touching body exerts on the object (normal plus friction, object
        frame) at its contacts carrying more than ``min_force_n``, as the acoustic stream's
        passive sound takes them (``sensors.synthesis.passive.ContactLoads``). A contact
        slides when its friction force reaches ``SLIDING_CONE_RATIO`` of mu times its normal
        force (MuJoCo's contact force frame: the tangential rows of the solver); it is an
        impact when its partner body is not in ``pressing_before`` (the bodies that pressed at
        the previous read; ``None``: no impacts). Each load names the body exerting it (a
        touching partner's loads act on it too)."""
        from sensors.synthesis.passive import SLIDING_CONE_RATIO, ContactLoads

        keep = self.normal_forces_n > min_force_n
        f, n, fn = self.forces_n[keep], self.normals[keep], self.normal_forces_n[keep]
        tangential = np.linalg.norm(f - np.einsum("ij,ij->i", f, n)[:, None] * n, axis=1)
        sliding = (self.friction[keep] > 0) & (tangential >= SLIDING_CONE_RATIO * self.friction[keep] * fn)
        impact = (np.zeros(int(keep.sum()), bool) if pressing_before is None
                  else ~np.isin(self.other_bodies[keep], list(pressing_before)))
        return ContactLoads(self.positions_m[keep], n, f, sliding, impact, bodies=self.other_bodies[keep])

    def pressing_bodies(self, min_force_n: float = 0.0) -> set:
        """Names of the bodies pressing on the object with more than ``min_force_n``."""
        return set(self.other_bodies[self.normal_forces_n > min_force_n].tolist())

    def merged(self, kind: str) -> tuple[np.ndarray, np.ndarray, float, float] | None:
        """One equivalent contact for all contacts of ``kind`` (a fingertip pad touches a face
        at several points): force-weighted mean point and normal, summed force, mean friction.
        ``None`` if there is no such contact carrying force."""
        mask = self._mask(kind)                        # what select(kind) keeps, without its copies
        fn = self.normal_forces_n[mask]
        total = float(np.sum(fn))
        if len(fn) == 0 or total <= 0.0:
            return None
        w = fn / total
        point = w @ self.positions_m[mask]
        normal = w @ self.normals[mask]
        norm = np.linalg.norm(normal)
        if norm < 1e-9:  # opposite normals cancel: not one contact patch
            return None
        return point, normal / norm, total, float(w @ self.friction[mask])

    def to_dict(self) -> dict:
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
        self._kind_of_geom = kind[self._geom_body]
        self._geom_of_body = [self._body_index[self._geom_body] == i for i in range(len(self.body_ids))]
        self._body_names = np.array([mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or f"body{i}"
                                     for i in range(model.nbody)], dtype=object)
        self._geom_names = np.array([mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) or f"geom{i}"
                                     for i in range(model.ngeom)], dtype=object)
        self._f6 = np.zeros(6)
        self._kind_names = np.array(KINDS)
        # Per sensed body, per geom pair (flat index ngeom * geom0 + geom1): 1 + the kind of the
        # other geom where one geom is the body's, else 0 (two geoms of one body never touch):
        # one lookup per contact gives whether it is the body's and what touches it there
        # (normal_force_totals_n, fingertip_forces_n). ngeom^2 bytes per sensed body.
        other_code = (self._kind_of_geom + 1).astype(np.int8)
        self._kind_code = []
        for mine in self._geom_of_body:
            code = np.zeros((model.ngeom, model.ngeom), np.int8)
            code[mine] = other_code
            code[:, mine] = other_code[:, None]
            code[np.ix_(mine, mine)] = 0
            self._kind_code.append(code.ravel())
        self._pair_index = np.array([model.ngeom, 1])

    def read(self, data: mujoco.MjData) -> dict[str, ObjectContacts]:
        """Body name -> ``ObjectContacts`` for the current state of ``data`` (vectorized over
        the contact list; forces straight from the solver's rows for elliptic cones)."""
        n = data.ncon
        rows = sides = np.zeros(0, dtype=int)
        if n:
            con = data.contact
            geom = con.geom[:n]
            sensed = self._body_index[self._geom_body[geom]]  # (n, 2): sensed-body index or -1
            rows, sides = np.nonzero(sensed >= 0)
        k = rows.size
        if k == 0:
            return {name: self._empty(name) for name in self.bodies}
        frame = con.frame[:n][rows].reshape(k, 3, 3)
        pos_w = con.pos[:n][rows]
        mu = con.friction[:n][rows, 0].copy()
        pen = -con.dist[:n][rows]
        f_contact = self._contact_forces(data, con, n, rows)  # (k, 3): on geom[1], contact frame
        sign = np.where(sides == 0, 1.0, -1.0)[:, None]  # object is geom[0]: normal points out of it
        normal_w = sign * frame[:, 0, :]
        force_w = -sign * np.einsum("kij,ki->kj", frame, f_contact)  # frame^T f, then onto the object
        obj = sensed[rows, sides]
        other_geom = geom[rows, 1 - sides]
        other_body = self._geom_body[other_geom]
        kinds = self._kind_names[self._kind_of_body[other_body]]
        fn = np.maximum(f_contact[:, 0], 0.0)
        out = {}
        if WHOLE_SELECTION and len(self.bodies) == 1:     # every read contact is the body's, in order
            b = self.body_ids[0]
            rot = data.xmat[b].reshape(3, 3)
            name = self.bodies[0]
            out[name] = ObjectContacts(
                name, (pos_w - data.xpos[b]) @ rot, normal_w @ rot, fn, force_w @ rot, mu, pen, kinds,
                self._body_names[other_body], self._geom_names[other_geom])
            return out
        for i, name in enumerate(self.bodies):
            sel = np.flatnonzero(obj == i)
            if sel.size == 0:
                out[name] = self._empty(name)
                continue
            b = self.body_ids[i]
            rot = data.xmat[b].reshape(3, 3)
            # Row vectors: v @ R is R^T v for each row (world -> object frame).
            out[name] = ObjectContacts(
                name, (pos_w[sel] - data.xpos[b]) @ rot, normal_w[sel] @ rot, fn[sel], force_w[sel] @ rot,
                mu[sel], pen[sel], kinds[sel], self._body_names[other_body[sel]], self._geom_names[other_geom[sel]])
        return out

    def normal_force_totals_n(self, data: mujoco.MjData, body: str) -> np.ndarray:
        """Summed normal force [N] on ``body`` per contact kind (indexed as :data:`KINDS`):
        ``read(data)[body].total_normal_force_n(kind)`` for every kind at once without
        building the contact list (a per-step ground truth needs only these sums; elliptic
        cones: the solver's normal rows).  The same forces added in the same order: equal bit
        for bit up to 7 contacts of a kind (numpy sums 8 and more pairwise), to rounding beyond."""
        if self.model.opt.cone != _ELLIPTIC:
            c = self.read(data)[body]
            return np.array([c.total_normal_force_n(k) for k in KINDS])
        n = data.ncon
        if not n or not data.nefc:
            return np.zeros(len(KINDS))
        con = data.contact
        # the body's contacts in contact order, each with 1 + the kind of what touches it there
        code = self._kind_code[self.bodies.index(body)][con.geom[:n].dot(self._pair_index)]
        mine = code.nonzero()[0]
        fn = _normal_row_forces(data.efc_force, con.efc_address[:n][mine])
        return np.bincount(code[mine] - 1, weights=fn, minlength=len(KINDS))

    def fingertip_forces_n(self, data: mujoco.MjData, body: str) -> tuple[float, float]:
        """Summed normal force [N] of the actuator and the mic fingertip on ``body``: equal bit
        for bit to ``read(data)[body].total_normal_force_n("actuator")`` and ``("mic")`` (the
        same forces summed by the same ``np.sum`` in the same order) without building the
        contact list: the test a grasp makes after every chunk of steps (``planar_grasp``)."""
        if self.model.opt.cone != _ELLIPTIC:
            c = self.read(data)[body]
            return c.total_normal_force_n("actuator"), c.total_normal_force_n("mic")
        if LEAN_FINGERTIPS:
            efc, actuator, mic = self._fingertip_rows(data, body)
            return row_force_sum_n(efc, actuator), row_force_sum_n(efc, mic)
        n = data.ncon
        if not n or not data.nefc:
            return 0.0, 0.0
        con = data.contact
        # the fingertips' contacts with the body in contact order (one lookup per contact)
        code = self._kind_code[self.bodies.index(body)][con.geom[:n].dot(self._pair_index)]
        actuator, mic = code == _ACTUATOR + 1, code == _MIC + 1
        if not (actuator.any() or mic.any()):          # no fingertip touches it: empty sums
            return 0.0, 0.0
        adr = con.efc_address[:n]
        efc = data.efc_force
        # summed as np.sum does (np.add.reduce without its Python wrapper)
        return (float(np.add.reduce(_normal_row_forces(efc, adr[actuator]), axis=None)),
                float(np.add.reduce(_normal_row_forces(efc, adr[mic]), axis=None)))

    @property
    def elliptic(self) -> bool:
        """Whether the model's friction cones are elliptic (:meth:`fingertip_rows` has rows)."""
        return self.model.opt.cone == _ELLIPTIC

    def fingertip_rows(self, data: mujoco.MjData, body: str):
        """``(efc_force, actuator rows, mic rows)``: the fingertips' contacts with ``body`` as the
        ``efc_address`` of their normal rows, in contact order, for :func:`row_force_sum_n`
        (``fingertip_forces_n`` is the two sums); None where the cone is not elliptic (no rows
        to sum: use ``fingertip_forces_n``)."""
        if self.model.opt.cone != _ELLIPTIC:
            return None
        return self._fingertip_rows(data, body)

    def _fingertip_rows(self, data: mujoco.MjData, body: str):
        n = data.ncon
        if not n or not data.nefc:
            return _NO_ROWS
        con = data.contact
        code = self._kind_code[self.bodies.index(body)][con.geom[:n].dot(self._pair_index)]
        adr = con.efc_address[:n]
        return data.efc_force, adr[code == _ACTUATOR + 1], adr[code == _MIC + 1]

    def _contact_forces(self, data, con, n: int, rows: np.ndarray) -> np.ndarray:
        """Normal and two tangential force components (contact frame, acting on geom[1])."""
        elliptic = self.model.opt.cone == _ELLIPTIC
        if elliptic and GATHER_FORCES:
            adr = con.efc_address[:n][rows]
            if adr.size and adr.min() >= 0 and con.dim[:n][rows].min() >= 3:
                return data.efc_force[adr[:, None] + _THREE_ROWS]
        out = np.zeros((rows.size, 3))
        if elliptic:
            # Elliptic cones: the solver's rows of a contact are its force components
            # (what mj_contactForce copies); contacts without rows carry no force.
            adr = con.efc_address[:n][rows]
            dim = con.dim[:n][rows]
            efc = data.efc_force
            ok = adr >= 0
            out[ok, 0] = efc[adr[ok]]
            tang = ok & (dim >= 3)
            out[tang, 1] = efc[adr[tang] + 1]
            out[tang, 2] = efc[adr[tang] + 2]
            return out
        f6 = self._f6
        for k, r in enumerate(rows):
            mujoco.mj_contactForce(self.model, data, int(r), f6)
            out[k] = f6[:3]
        return out

    def _empty(self, name: str) -> ObjectContacts:
        z3, z = np.zeros((0, 3)), np.zeros(0)
        e = np.zeros(0, dtype=object)
        return ObjectContacts(name, z3, z3.copy(), z, z3.copy(), z.copy(), z.copy(), np.zeros(0, dtype="<U11"), e, e)


_THREE_ROWS = np.arange(3)
_NO_ROWS = (np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int))


def row_force_sum_n(efc_force: np.ndarray, adr: np.ndarray) -> float:
    """Summed normal force [N] of the normal rows ``adr`` (a :meth:`ContactStream.fingertip_rows`
    entry): as ``fingertip_forces_n`` sums them (0.0 for none)."""
    if PYTHON_SUMS and adr.size < 8:
        total = 0.0
        for r in adr.tolist():
            if r >= 0:                                  # a row: its force clipped at 0 (NaN kept)
                f = float(efc_force[r])
                if f > 0.0 or f != f:
                    total += f
        return total
    return float(np.add.reduce(_normal_row_forces(efc_force, adr), axis=None))


def _normal_row_forces(efc_force: np.ndarray, adr: np.ndarray) -> np.ndarray:
    """Elliptic cones: the normal rows' forces [N] at the contacts' ``efc_address`` values
    ``adr``, clipped at 0 (-1: a contact without rows carries no force)."""
    fn = efc_force[adr]
    fn[adr < 0] = 0.0
    np.maximum(fn, 0.0, out=fn)
    return fn


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
