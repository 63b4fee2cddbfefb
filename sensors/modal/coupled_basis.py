"""Where a coupled group's Ritz bases put their attachment modes (:mod:`sensors.modal.coupled_bodies`).

The reference puts each body's attachment modes at its link points: a point on a face of the
quadratic tets loads the face's six nodes, and every node not yet in the model's unit-load
store costs a sparse solve (:class:`sensors.modal.static_correction.UnitLoadStore`) and its
products with the other nodes of the set.  A bar rocking and sliding on a plinth touches new
faces at every contact change: in ``benchmarks/streaming_env.py``'s moving scenes those solves
and products are half of a streamed step.

With :data:`SNAP_TO_NODES` a partner's attachment modes (its links with the grasped object and
its contacts with the table) are those of unit forces at the mesh node nearest each point (one
node instead of six, and nearby points share it); the links themselves still act at their own
points (their springs' rows are the basis evaluated there).  The basis is a span: the static
response to a force at a node 1.5 mm (at most 2.7 mm on the project's bars, whose nodes lie
3.1 mm apart) from the point still carries the local flexibility the spring needs.  The grasped
object's own points stay exact: its coordinates are the state the stream carries across contact
switches, and in a chattering grasp the sound is mostly those switches' transients, which move
with its basis (:data:`SNAP_GRASPED`).  Deterministic (the mesh decides, not the history of
contacts), so two envs on the same models hear the same.  Tolerances: ``tests/test_coupled_basis.py``.
"""

from __future__ import annotations

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey

__all__ = ["SNAP_GRASPED", "SNAP_TO_NODES", "basis_points", "flags"]

#: The partners' attachment modes at the nearest mesh nodes (True, the fast path) or at their
#: points (False, the reference).  Read at each build.  Streamed moving scene, ABS bar on the
#: steel plinth, 43 steps (``benchmarks/stream_tolerance.py --scene moving --flag
#: sensors.modal.coupled_basis:SNAP_TO_NODES``): rms of the difference 0.15 % (passive sound
#: on) / 0.06 % (off), features p95 0.06 / 0.03 dB, max 0.13 / 0.27 dB; unit-load solves of
#: the plinth 197 -> about 40 nodes; 1.08-1.19x per streamed step (stream_profile.py, two
#: processes).  The stream's own position tolerance at 0.1 instead of 0.2 mm moves the same
#: sound by 16 % / 3.6 %, features p95 3.0 / 5.5 dB.  Off: safe only where the partner is much
#: stiffer than the grasped object.  The ABS bar's pad-to-pad transfer with the plinth snapped:
#: steel plinth p95 0.001, max 0.005 dB; aluminium 0.003, 0.015; wood 0.69, 3.2 dB; an ABS
#: plinth 0.24, 8.6 dB (its local flexibility is heard as much as the bar's): a Young's modulus
#: ratio of 25 or more, not checked here.
SNAP_TO_NODES = False

#: With :data:`SNAP_TO_NODES`, the grasped object's ends of its links with the partners too
#: (its fingertip pads and table contacts never).  1.2-1.4x per streamed step, and each
#: system's pad-to-pad transfer stays within median 0.011, p95 0.089, max 1.74 dB of the
#: reference (``benchmarks/group_memo_probe.py --snap``, 253 contact reads x 140 features),
#: but the stream's sound moves by rms 12.7 % / 6.9 %, features p95 3.6 dB (the switch
#: transients; basis points moved 0.1 mm: 0.07 %, 1 mm: 6.6 %).  Off.
SNAP_GRASPED = False

_TREES: LRU = LRU(CACHE_SIZES["modal.node_trees"])


def flags() -> tuple[bool, bool]:
    """The flags a coupled build reads (a cache key part)."""
    return bool(SNAP_TO_NODES), bool(SNAP_GRASPED)


def _tree(base):
    from scipy.spatial import cKDTree  # deferred: `import sensors` loads no SciPy spatial

    return _TREES.get_or_build(IdentityKey(base), lambda: cKDTree(np.asarray(base.nodes_m, float)))


def basis_points(base, points_m: np.ndarray) -> np.ndarray:
    """The points (P, 3) [m, the mesh's frame] where ``base``'s attachment modes go for link
    points ``points_m``: the nearest mesh nodes (:data:`SNAP_TO_NODES`), else the points."""
    p = np.asarray(points_m, float).reshape(-1, 3)
    if not SNAP_TO_NODES or not len(p):
        return p
    _, idx = _tree(base).query(p)
    return np.asarray(base.nodes_m, float)[idx]
