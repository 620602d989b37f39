"""Checks of model hyperparameters: the one home of these rules.

Every model validates its constructor arguments with these helpers and raises
``ModelError`` naming the model, the hyperparameter and the value it got (the
command line prints that as one line with exit status 2). Nothing is coerced:

* a boolean hyperparameter takes only True or False (``--hyper offset=false``;
  the CLI reads true/false as booleans) -- never "no", "off", 2 or None;
* an integer hyperparameter takes only an integer (not True/False, not 13.0)
  within its bounds; size hyperparameters have an upper bound so that a typo
  (n_operators=100000000) is refused instead of exhausting memory;
* a number takes an int or float (not a bool, not a string), finite.

Each helper returns the value as a plain Python bool, int or float.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .errors import ModelError

MAX_OPERATORS = 1000  # play operators of a P-I model (classical-pi, mrpim, rate-dependent-pi)


def _is_bool(value) -> bool:
    return isinstance(value, (bool, np.bool_))


def check_bool(owner: str, name: str, value) -> bool:
    """``value`` if it is True or False; anything else is refused."""
    if _is_bool(value):
        return bool(value)
    raise ModelError(f"{owner}: {name} must be true or false, got {value!r}")


def _span(lo, hi) -> str:
    if lo is not None and hi is not None:
        return f"in {lo}..{hi}"
    if lo is not None:
        return f">= {lo}"
    return f"<= {hi}" if hi is not None else ""


def _int_in(value, lo: int | None, hi: int | None) -> bool:
    return (isinstance(value, (int, np.integer)) and not _is_bool(value)
            and (lo is None or value >= lo) and (hi is None or value <= hi))


def check_int(owner: str, name: str, value, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` if it is an integer (not a bool) in lo..hi (inclusive; None: unbounded)."""
    if _int_in(value, lo, hi):
        return int(value)
    span = _span(lo, hi)
    raise ModelError(f"{owner}: {name} must be an integer{' ' + span if span else ''}, got {value!r}")


def check_int_list(owner: str, name: str, values, lo: int | None = None, hi: int | None = None) -> tuple[int, ...]:
    """A non-empty list or tuple of integers, each in lo..hi."""
    span = _span(lo, hi)
    what = f"{owner}: {name} must be a non-empty list of integers{' ' + span if span else ''}, got {values!r}"
    if not isinstance(values, (list, tuple, np.ndarray)) or len(values) == 0:
        raise ModelError(what)
    if not all(_int_in(v, lo, hi) for v in values):
        raise ModelError(what)
    return tuple(int(v) for v in values)


def check_number(owner: str, name: str, value, lo: float | None = None, hi: float | None = None,
                 positive: bool = False) -> float:
    """``value`` as a float if it is a finite real number (not a bool), > 0 if ``positive``,
    in [lo, hi] where given."""
    ok = (isinstance(value, (int, float, np.integer, np.floating)) and not _is_bool(value)
          and math.isfinite(float(value)))
    if ok:
        v = float(value)
        ok = (not positive or v > 0) and (lo is None or v >= lo) and (hi is None or v <= hi)
    if ok:
        return v
    if lo is not None and hi is not None:
        what = f"a number in [{lo}, {hi}]"
    elif lo is not None:
        what = f"a number >= {lo}"
    elif hi is not None:
        what = f"a number <= {hi}"
    else:
        what = "a positive number" if positive else "a finite number"
    raise ModelError(f"{owner}: {name} must be {what}, got {value!r}")


def check_choice(owner: str, name: str, value, choices: Sequence[str]) -> str:
    """``value`` if it is one of the strings ``choices``."""
    if isinstance(value, str) and value in choices:
        return value
    raise ModelError(f"{owner}: {name} must be one of {', '.join(choices)}, got {value!r}")
