"""The detection limits the diagnosis states, per cause and base: measured data, stated from stored plans.

A detection limit (``shares.detection_limit``) is the smallest strength of a planted effect (rms over the
identification records, % of the output's peak-to-peak) above which the verdict is right in >= 95 % of the
single-cause cases, with at least ``MIN_CASES`` cases at or above it. ``state`` computes the table from stored
plans' rows (``hysbench accuracy limits``, by default from the balanced plans 35-62) and ``write_limits`` writes it
to ``LIMITS_FILE`` (stated_limits.json beside this module, installed with the package), together with the plans it
was stated from. A cause and base with no such strength in the drawn range has no limit (null): the diagnosis
cannot be trusted to find that cause on such a plant, at any strength drawn.

The ``within-limits`` plan (``accuracy.plan``) draws each vocabulary effect at or above its stated limit and
plants a cause only on a base where it has one; its accuracy is measured on plans whose seeds are above those the
limits were stated from.
"""

from __future__ import annotations

import json
from pathlib import Path

from hysbench.data.files import write_json
from hysbench.models.errors import HysbenchError

from .planted import BASES, VOCABULARY
from .shares import PLAN_STRIDE, RIGHT_SHARE, detection_limit

LIMITS_FILE = Path(__file__).with_name("stated_limits.json")
MIN_CASES = 20  # single-cause cases at or above a stated limit, at least
STATING_PLANS = ["balanced-35..62"]  # the plans ``hysbench accuracy limits`` states them from by default


def state(plans: list[dict], min_cases: int = MIN_CASES) -> dict:
    """The limits stated from ``plans`` (``rows.plan_rows``: {"id", "meta", "rows"} each), per vocabulary cause
    and fixed base: {"plans", "seeds", "min_cases", "right_share", "limits": [{cause, base, limit_pct (None: not
    reached), cases, cases_above, right_above}]}."""
    rows = [r for p in plans for r in p["rows"]]
    limits = []
    for cause in VOCABULARY:
        for base in BASES:
            q = detection_limit([r for r in rows if r["base"] == base], cause, min_cases=min_cases)
            limits.append({"cause": cause, "base": base, "limit_pct": q["strength_pct"], "cases": q["cases"],
                           "cases_above": q["cases_above"], "right_above": q["right_above"]})
    return {"plans": [p["id"] for p in plans], "seeds": sorted({r["seed"] // PLAN_STRIDE for r in rows}),
            "min_cases": min_cases, "right_share": RIGHT_SHARE, "limits": limits}


def write_limits(data: dict, path: str | Path | None = None) -> None:
    """Write the table (``state``'s) as JSON to ``path`` (default LIMITS_FILE: the limits read from then on)."""
    write_json(path or LIMITS_FILE, data)
    _loaded.clear()


def load(path: str | Path | None = None) -> dict:
    """The stated limits as written by ``write_limits``; HysbenchError if the file is missing or not one."""
    path = path or LIMITS_FILE
    try:
        data = json.loads(Path(path).read_text())
        table = {(q["cause"], q["base"]): q["limit_pct"] for q in data["limits"]}
        missing = [k for k in ("plans", "seeds", "min_cases") if k not in data]
        if missing:
            raise KeyError(", ".join(missing))
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise HysbenchError(f"cannot read the stated limits from {path} ({e})") from None
    return {**data, "table": table}


_loaded: dict = {}


def _stated() -> dict:
    """LIMITS_FILE, read once (a command that cannot find it fails where a limit is needed, not at import)."""
    if "data" not in _loaded:
        _loaded["data"] = load()
    return _loaded["data"]


def __getattr__(name: str):
    if name == "LIMITS_PCT":  # {(cause, base): limit in % of p2p, or None}, as LIMITS_FILE states them
        return _stated()["table"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def stated_from() -> dict:
    """What the limits were stated from: {"plans", "seeds", "min_cases"}."""
    return {k: _stated()[k] for k in ("plans", "seeds", "min_cases")}


def stated_limit(cause: str, base: str) -> float | None:
    """The stated limit of a vocabulary cause on a base (None: none stated)."""
    return _stated()["table"].get((cause, base))


def in_scope(kinds, base: str) -> bool:
    """Whether every vocabulary effect of ``kinds`` has a stated limit on ``base`` (nulls and
    out-of-vocabulary effects always are)."""
    return all(stated_limit(k, base) is not None for k in kinds if k in VOCABULARY)


def minimum_strengths(kinds, base: str) -> dict[str, float]:
    """Per vocabulary effect of ``kinds``, the strength it is drawn at or above (its stated limit on ``base``)."""
    return {k: stated_limit(k, base) for k in kinds if k in VOCABULARY}


def out_of_scope() -> list[tuple[str, str]]:
    """(cause, base) pairs without a stated limit: not planted by the within-limits plan."""
    return [key for key, v in _stated()["table"].items() if v is None]
