"""numba compilation on first use.

``import numba`` costs 0.2-0.5 s of CPU (python -X importtime: llvmlite and numba.core), more
than the rest of ``import sensors``; only two paths need it (the one-sided fingertip model and
the low-rank complex modes). Their kernels are written as plain module-level functions and
compiled here, once, on the first call: the public API and the on-disk numba cache
(``cache=True``) are the same as with a decorator.
"""
from __future__ import annotations

import threading
from typing import Callable

_LOCK = threading.Lock()


def jitted(namespace: dict, name: str, callees: tuple[str, ...] = (), **options) -> Callable:
    """The ``numba.njit(**options)`` dispatcher of the module-level function
    ``namespace[name]`` (pass the module's ``globals()``), compiled on the first call.

    ``callees``: module-level functions that ``name`` calls; they are compiled first and
    rebound in the namespace, because numba resolves a kernel's globals when it compiles it.
    """
    dispatchers = namespace.get("_NUMBA_DISPATCHERS")
    if dispatchers is not None and name in dispatchers:
        return dispatchers[name]
    with _LOCK:
        dispatchers = namespace.setdefault("_NUMBA_DISPATCHERS", {})
        if name not in dispatchers:
            import numba  # the deferred import this module exists for

            for fn in (*callees, name):
                if fn not in dispatchers:
                    dispatchers[fn] = numba.njit(**options)(namespace[fn])
                    if fn != name:
                        namespace[fn] = dispatchers[fn]
        return dispatchers[name]
