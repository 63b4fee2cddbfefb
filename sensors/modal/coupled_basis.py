"""Where a coupled group's Ritz bases put their attachment modes (:mod:`sensors.modal.coupled_bodies`).

The reference puts each body's attachment modes at its link points: a point on a face of the
quadratic tets loads the face's six nodes, and every node not yet in the model's unit-load
store costs a sparse solve (:class:`sensors.modal.static_correction.UnitLoadStore`) and its
products with the other nodes of the set.  A bar rocking and sliding on a plinth touches new
faces at every contact change: in ``benchmarks/streaming_env.py``'s moving scenes those solves
and products are half of a streamed step.

With :data:`SNAP_TO_NODES` the attachment modes of the links between bodies (and of a
partner's contacts with the table) are those of unit forces at the mesh node nearest each link
point (one node instead of six, and nearby points share it); the links themselves still act at
their own points (their springs' rows are the basis evaluated there).  The basis is a span: the
static response to a force at a node 1.5 mm (at most 2.7 mm on the project's bars, whose nodes
lie 3.1 mm apart) from the point still carries the local flexibility the spring needs, within
the tolerance measured and tested in ``tests/test_coupled_basis.py`` (not bit for bit: with it
on, env observations of scenes with touching objects move, see :data:`SNAP_TO_NODES`).  The grasped object's own
contacts (fingertip pads, table) keep their exact points: the drive and the microphone sit
there.  Deterministic (the mesh decides, not the history of contacts), so two envs on the same
models hear the same.
"""

from __future__ import annotations

import numpy as np

from .._infra.lru import CACHE_SIZES, LRU, IdentityKey

__all__ = ["SNAP_TO_NODES", "basis_points"]

#: Attachment modes of inter-body links at the nearest mesh node (True, the fast path) or at
#: the link points (False, the reference).  Read at each build.  Measured on the moving ABS
#: bar (``benchmarks/group_memo_probe.py --snap``, 253 contact reads x 140 features): the
#: pad-to-pad transfer within median 0.011, p95 0.089, max 1.74 dB of the reference; unit-load
#: solves 374 -> 106 nodes.  To the nearest corner node of the quadratic tets (6 mm apart)
#: instead: p95 0.28, max 4.3 dB (not taken).  Off by default: the streamed moving scene is
#: 1.2-1.3x faster with it, but its sound while the bar chatters is mostly the transients of
#: contact switches, and those move more than the transfer does (``benchmarks/stream_tolerance.py
#: --scene moving --flag sensors.modal.coupled_basis:SNAP_TO_NODES``, ABS bar, 43 steps:
#: rms 12.7 %, features p95 3.6 dB with passive sound; 6.9 %, 3.6 dB without; the stream's own
#: position tolerance at 0.1 instead of 0.2 mm: 16.2 %, 3.0 dB and 3.6 %, 5.5 dB).
SNAP_TO_NODES = False

_TREES: LRU = LRU(CACHE_SIZES["modal.node_trees"])


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
