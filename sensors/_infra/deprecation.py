"""Deprecated spellings: one warning, pointed at the user's line.

An old spelling keeps working for one release and says once per call site (Python's default
filter) what to write instead. The warning is attributed to the first frame outside the
project and Gymnasium, so ``gym.make(..., old=...)`` in a user's script names that line, and
Python's default filters show it for code run as ``__main__``.
"""

from __future__ import annotations

import functools
import sys
import warnings
from typing import Callable, TypeVar

__all__ = ["renamed_keywords", "warn_deprecated"]

F = TypeVar("F", bound=Callable)

# Frames of these packages are skipped when attributing a warning to its caller.
_INTERNAL = frozenset({"sensors", "aas_gym", "real", "gymnasium"})


def _user_stacklevel() -> int:
    """``stacklevel`` for ``warnings.warn`` called in :func:`warn_deprecated` that names the
    first frame outside ``_INTERNAL``."""
    level, frame = 2, sys._getframe(2)
    while frame is not None and frame.f_globals.get("__name__", "").partition(".")[0] in _INTERNAL:
        frame, level = frame.f_back, level + 1
    return level if frame is not None else 2


def warn_deprecated(old: str, new: str) -> None:
    """A ``DeprecationWarning``: ``old`` is deprecated, write ``new`` (removed next release)."""
    warnings.warn(f"{old} is deprecated and will be removed in the next release; use {new}",
                  DeprecationWarning, stacklevel=_user_stacklevel())


def renamed_keywords(renames: dict[str, str]) -> Callable[[F], F]:
    """Decorator: each keyword ``old`` of ``renames`` is accepted as the keyword ``new`` with a
    deprecation warning; both at once is a ``TypeError``. The signature stays the new one."""

    def wrap(func: F) -> F:
        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            for old, new in renames.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{func.__qualname__}() got both {old}= and {new}=; {old} is the "
                                        f"deprecated spelling of {new}")
                    warn_deprecated(f"{func.__qualname__}({old}=...)", f"{new}=")
                    kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return wrap
