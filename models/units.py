"""Parameter units: each ``Parameter`` declares its unit as a product of powers of symbols.

``u`` and ``y`` stand for the dataset's input and output units (kV and mm on the paper's DEA), ``s`` for the
second, ``Hz`` for 1/s and ``kPa`` for itself; ``1`` is dimensionless. Examples: ``"y/u"`` (a play weight),
``"y/u^2"``, ``"u*s^2/y"`` (a mass on force input and displacement output). ``render`` writes one with a
dataset's unit names, ``dimension`` gives the powers of (u, y, s) the parameter scales with.
"""

from __future__ import annotations

import re

from .errors import ModelError

# symbol -> (powers of u, y, s); None: a fixed physical unit that does not follow the data's scale
SYMBOLS = {"u": (1, 0, 0), "y": (0, 1, 0), "s": (0, 0, 1), "Hz": (0, 0, -1), "kPa": None}
_FACTOR = re.compile(r"([A-Za-z]+)(?:\^(-?\d+))?$")


def factors(unit: str) -> list[tuple[str, int]]:
    """``"y*s^2/u"`` -> [("y", 1), ("s", 2), ("u", -1)]; ``"1"`` -> []."""
    unit = unit.strip()
    if unit == "1":
        return []
    out = []
    for k, part in enumerate(re.split(r"(?=[*/])", unit)):
        sign = -1 if part.startswith("/") else 1
        token = part.lstrip("*/") if k else part
        m = _FACTOR.match(token.strip())
        if not m or m.group(1) not in SYMBOLS or (k == 0 and part[:1] in "*/"):
            raise ModelError(f"unit {unit!r}: {token!r} is not one of {', '.join(SYMBOLS)} with an optional ^power")
        out.append((m.group(1), sign * int(m.group(2) or 1)))
    return out


def dimension(unit: str) -> tuple[int, int, int] | None:
    """Powers of (u, y, s) of a unit; None if it holds a fixed physical unit (kPa)."""
    total = [0, 0, 0]
    for symbol, power in factors(unit):
        dims = SYMBOLS[symbol]
        if dims is None:
            return None
        total = [t + power * d for t, d in zip(total, dims)]
    return tuple(total)


def render(unit: str, input_unit: str = "", output_unit: str = "") -> str:
    """The unit in the dataset's terms: ``"y/u^2"`` -> ``"mm/kV^2"``; "" for a dimensionless one. Without the
    dataset's unit names, ``in`` and ``out`` stand for them."""
    names = {"u": input_unit.strip() or "in", "y": output_unit.strip() or "out"}
    up, down = [], []
    for symbol, power in factors(unit):
        name = names.get(symbol, symbol)
        if not re.fullmatch(r"[^\W\d_]+", name):  # "m/s" as a factor: bracketed
            name = f"({name})"
        text = name if abs(power) == 1 else f"{name}^{abs(power)}"
        (up if power > 0 else down).append(text)
    if not up and not down:
        return ""
    top = "*".join(up) or "1"
    return top + "".join(f"/{d}" for d in down)
