"""Checks of the numbers a user passes: a clear TypeError or ValueError naming the argument,
before any work starts (a boolean is no number here: ``float(True)`` is 1.0, so a typo would
pass silently; ``int(0.7)`` is 0, so a fraction would truncate silently)."""

from __future__ import annotations

import math
import numbers

__all__ = ["real_number", "whole_number", "holds_bool"]


def real_number(value, name: str, *, minimum: float | None = None, maximum: float | None = None,
                above: float | None = None) -> float:
    """``value`` as a finite float in [``minimum``, ``maximum``] (and > ``above``).

    Raises:
        TypeError: not a real number (a string, a boolean, an array, None).
        ValueError: NaN, infinite, or out of range.
    """
    if isinstance(value, bool) or type(value).__name__ == "bool_" or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {value!r} ({type(value).__name__})")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond float's range
        x = math.inf
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if above is not None and not x > above:
        raise ValueError(f"{name} must be above {above:g}, got {value!r}")
    if (minimum is not None and x < minimum) or (maximum is not None and x > maximum):
        lo = "-inf" if minimum is None else f"{minimum:g}"
        hi = "inf" if maximum is None else f"{maximum:g}"
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value!r}")
    return x


def whole_number(value, name: str, *, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as an int in [``minimum``, ``maximum``]; a float must be integral (2.0, not 0.7).

    Raises:
        TypeError: not a number, or a boolean.
        ValueError: not integral, or out of range.
    """
    x = real_number(value, name)
    if x != int(x):
        raise ValueError(f"{name} must be a whole number, got {value!r}")
    n = int(x)
    if (minimum is not None and n < minimum) or (maximum is not None and n > maximum):
        raise ValueError(f"{name} must be in [{minimum}, {maximum if maximum is not None else 'inf'}], got {value!r}")
    return n


def holds_bool(value) -> bool:
    """Whether ``value`` is or (in nested lists and tuples, or a boolean array) holds a boolean:
    ``np.asarray([False, 0.0, 0.0])`` is a float array, so the dtype alone does not tell."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return True
    if isinstance(value, (list, tuple)):
        return any(holds_bool(v) for v in value)
    return getattr(getattr(value, "dtype", None), "kind", "") == "b"
