"""Checks of configuration values, shared by the envs, their acoustic config and the dataset
config: each returns the value in its plain Python type or raises a ``TypeError`` (wrong
kind: a bool where a number goes, a string where a bool goes) or ``ValueError`` (right kind,
out of range, NaN or infinite) that names the argument and what it accepts.

Python's own conversions are too lenient here: ``True`` is the number 1, ``"no"`` is a
true value, ``int(2.7)`` is 2.
"""

from __future__ import annotations

import numbers
from typing import Any

from .._infra.checks import real_number

__all__ = ["check_choice", "check_flag", "check_integer", "check_number"]


def check_flag(name: str, value: Any) -> bool:
    """A bool (``numpy.bool_`` too); anything else, a string above all, is a ``TypeError``."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return bool(value)
    raise TypeError(f"{name} must be True or False, got {value!r} ({type(value).__name__})")


def check_integer(name: str, value: Any, low: int | None = None, high: int | None = None) -> int:
    """An integer (not a bool, not a float, even a whole one) in ``[low, high]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {value!r} ({type(value).__name__})")
    value = int(value)
    if (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"{name} must be an integer in [{_bound(low, '-')}, {_bound(high)}], got {value}")
    return value


def check_number(name: str, value: Any, low: float | None = None, high: float | None = None, *,
                 low_open: bool = False, unit: str = "") -> float:
    """A finite real number (not a bool, not a string) in ``[low, high]`` (``(low, high]``
    with ``low_open``)."""
    value = real_number(value, name)  # the type and finiteness checks (and their messages)
    unit = f" {unit}" if unit else ""
    if (low is not None and (value < low or (low_open and value == low))) or (high is not None and value > high):
        left = "(" if low_open else "["
        raise ValueError(f"{name} must be in {left}{_bound(low, '-')}, {_bound(high)}]{unit}, got {value!r}")
    return value


def check_choice(name: str, value: Any, choices: tuple) -> Any:
    """One of ``choices`` (compared by equality after a type check against the choices' types)."""
    if not any(type(value) is type(c) and value == c for c in choices):
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def _bound(x, sign: str = "") -> str:
    return f"{sign}inf" if x is None else f"{x:g}" if isinstance(x, float) else str(x)
