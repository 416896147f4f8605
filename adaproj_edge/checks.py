"""Checks for values read from files: type, finiteness and range, with the key named.

Every field of a board file, a calibration and a saved-state file goes through one of
these, so a wrong value is refused with the key, the allowed range and what was found
(the caller's :func:`~adaproj_edge.geometry.calibration.field_errors` adds the file):

>>> integer(99999999999999999, "[imu] bus", 0, 1023)
Traceback (most recent call last):
...
adaproj_edge.errors.InputError: [imu] bus must be an integer in [0, 1023], got 99999999999999999
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection
from typing import Any

from adaproj_edge.errors import InputError


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def integer(value: Any, key: str, lo: int, hi: int) -> int:
    """``value`` if it is an integer (not a bool; a float only when whole) in
    ``[lo, hi]``, else :class:`InputError`."""
    whole = isinstance(value, float) and math.isfinite(value) and value.is_integer()
    if isinstance(value, bool) or not (isinstance(value, numbers.Integral) or whole):
        raise InputError(f"{key} must be an integer in [{lo}, {hi}], got {_shown(value)}")
    if not lo <= value <= hi:
        raise InputError(f"{key} must be an integer in [{lo}, {hi}], got {_shown(value)}")
    return int(value)


def number(value: Any, key: str, lo: float, hi: float, *, above: bool = False) -> float:
    """``value`` as a float if it is a finite number in ``[lo, hi]`` (``(lo, hi]`` with
    ``above``), else :class:`InputError`."""
    span = f"{'(' if above else '['}{lo:g}, {hi:g}]"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{key} must be a number in {span}, got {_shown(value)}")
    x = float(value)
    if not math.isfinite(x) or not (lo < x if above else lo <= x) or x > hi:
        raise InputError(f"{key} must be a finite number in {span}, got {_shown(value)}")
    return x


def text(value: Any, key: str, choices: Collection[str] | None = None) -> str:
    """``value`` if it is a string (one of ``choices`` when given), else :class:`InputError`."""
    if not isinstance(value, str):
        raise InputError(f"{key} must be a string, got {_shown(value)}")
    if choices is not None and value not in choices:
        raise InputError(f"{key} must be one of {', '.join(sorted(choices))}, got {value!r}")
    return value


def flag(value: Any, key: str) -> bool:
    """``value`` if it is a bool (``true`` / ``false``), else :class:`InputError`."""
    if not isinstance(value, bool):
        raise InputError(f"{key} must be true or false, got {_shown(value)}")
    return value


def number_list(value: Any, key: str, lo: float, hi: float, most: int) -> tuple[float, ...]:
    """``value`` as a tuple of floats if it is a list of at most ``most`` finite numbers
    in ``[lo, hi]``, else :class:`InputError`."""
    if not isinstance(value, list | tuple) or len(value) > most:
        raise InputError(f"{key} must be a list of at most {most} numbers, got {_shown(value)}")
    return tuple(number(x, f"{key}[{i}]", lo, hi) for i, x in enumerate(value))
