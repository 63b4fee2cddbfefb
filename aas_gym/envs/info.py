"""The ``info`` entries of the aas_gym envs in forms that stack across the envs of a vector env.

``gym.make_vec`` (``"sync"`` and ``"async"``) stacks every ``info`` entry of its envs into one
array per key, shaped after the first env's value: an entry whose shape changes from env to
env (the contacts of an object, one row per contact) cannot stack. Here the contacts of each
sensed object are padded to :data:`MAX_INFO_CONTACTS` rows with a count (the strongest kept
when there are more, in their original order).
"""

from __future__ import annotations

import numpy as np

from aas_gym.contacts import ObjectContacts

__all__ = ["MAX_INFO_CONTACTS", "contacts_info", "padded_contacts"]

#: Rows of every contact array in ``info["contacts"][body]`` (a grasped bar on the table has
#: 8-16 contacts; a convex-decomposed everyday object more). Beyond it the weakest (smallest
#: normal force) are left out and counted in ``n_dropped``.
MAX_INFO_CONTACTS = 64
#: Whether :func:`padded_contacts` copies the rows straight in when none is left out (no index
#: array): the same arrays.  False: the index (the reference; ``tests/test_episode_glue.py``).
#: Read at each call.
LEAN_PAD = True


def padded_contacts(contacts: ObjectContacts, max_contacts: int = MAX_INFO_CONTACTS) -> dict:
    """The contacts of one object as fixed-shape arrays of ``max_contacts`` rows.

    Keys: ``n_contacts`` (int, the valid rows, first), ``n_dropped`` (int, weakest contacts
    left out above ``max_contacts``), ``positions_m`` (rows x 3, object frame [m]), ``normals``
    (rows x 3, outward unit normals), ``normal_forces_n`` (rows [N]), ``forces_n`` (rows x 3,
    force on the object [N]), ``friction`` (rows), ``kinds`` (rows, one of
    ``aas_gym.contacts.KINDS``), ``other_bodies`` (rows, body names). The names are object
    arrays of ``str`` (Gymnasium's ``check_env`` compares a fixed-width string array as
    numbers and fails). Padding rows hold zeros and empty strings.
    """
    n = len(contacts)
    keep = np.arange(n)
    if n > max_contacts:
        keep = np.sort(np.argsort(-np.asarray(contacts.normal_forces_n), kind="stable")[:max_contacts])
    k = len(keep)
    lean = LEAN_PAD and k == n

    def pad(values, width: int | None = None, dtype=np.float64, fill=0.0) -> np.ndarray:
        shape = (max_contacts,) if width is None else (max_contacts, width)
        out = np.full(shape, fill, dtype=dtype)
        out[:k] = values if lean else np.asarray(values)[keep]
        return out

    return {"n_contacts": int(k), "n_dropped": int(n - k),
            "positions_m": pad(contacts.positions_m, 3), "normals": pad(contacts.normals, 3),
            "normal_forces_n": pad(contacts.normal_forces_n), "forces_n": pad(contacts.forces_n, 3),
            "friction": pad(contacts.friction),
            "kinds": pad(contacts.kinds, dtype=object, fill=""),
            "other_bodies": pad(contacts.other_bodies, dtype=object, fill="")}


def contacts_info(contacts: dict[str, ObjectContacts]) -> dict[str, dict]:
    """``info["contacts"]``: body name -> :func:`padded_contacts`."""
    return {body: padded_contacts(c) for body, c in contacts.items()}
