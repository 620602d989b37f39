"""Every stored plan's rows in one file: gzip-compressed JSON lines (results/diagnosis_accuracy_rows.jsonl.gz).

Each line is one JSON object with ``"plan"`` (the plan's id, ``plan_id``) and either ``"meta"`` (one line per
plan, before its rows: how it was run) or ``"row"`` (one diagnosed case, in the plan's order; its fields are
those ``accuracy.run_case`` returns, listed in benchmarks/diagnosis_accuracy/README.md). Storing a plan replaces
every line of that plan and keeps the others as they are. The file is written whole (a temporary file renamed
over it), strict JSON (a non-finite number as null), byte for byte the same for the same plans (no time stamp
in the gzip header).
"""

from __future__ import annotations

import gzip
import io
import json
import os
from pathlib import Path

from hysbench.data.files import ensure_dir, jsonable, write_atomic
from hysbench.models.errors import HysbenchError

ROWS_FILE = Path("results") / "diagnosis_accuracy_rows.jsonl.gz"
META_KEYS = ("design", "seed", "cases", "wall_s", "code", "machine", "missing_bases", "note", "on")


def plan_id(design: str, seed: int, on: dict | None = None) -> str:
    """A plan's id: ``DESIGN-SEED`` on the fixed bases (``balanced-45``, ``within-limits-63``); on a user's
    dataset ``on-NAME-SEED`` with its options (``-MODEL`` if not mrpim, ``-segmentsK``, ``-thorough``)."""
    if not on:
        return f"{design}-{seed}"
    return (f"on-{on['name']}-{seed}" + (f"-{on['model']}" if on.get("model", "mrpim") != "mrpim" else "")
            + (f"-segments{on['segments']}" if on.get("segments") else "") + ("-thorough" if on.get("thorough") else ""))


def expand(ids: list[str]) -> list[str]:
    """Plan ids, ``NAME-A..B`` standing for ``NAME-A`` to ``NAME-B`` (``balanced-35..44``)."""
    out = []
    for text in ids:
        head, sep, last = text.partition("..")
        name, _, first = head.rpartition("-")
        if not sep:
            out.append(text)
            continue
        if not (name and first.isdigit() and last.isdigit() and int(first) <= int(last)):
            raise HysbenchError(f"plan range {text!r} is not NAME-A..B with integers A <= B")
        out += [f"{name}-{s}" for s in range(int(first), int(last) + 1)]
    return out


def read_plans(path: str | os.PathLike = ROWS_FILE) -> dict[str, dict]:
    """{plan id: {"meta": {...}, "rows": [...]}} in the file's order ({} if there is no file)."""
    path = Path(path)
    if not path.exists():
        return {}
    plans: dict[str, dict] = {}
    try:
        with gzip.open(path, "rt", encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                entry = json.loads(line)
                plan = plans.setdefault(entry["plan"], {"meta": {}, "rows": []})
                if "meta" in entry:
                    plan["meta"] = entry["meta"]
                else:
                    plan["rows"].append(entry["row"])
    except (OSError, EOFError, ValueError, KeyError, TypeError) as e:
        raise HysbenchError(f"{path} is not an accuracy row file (line {locals().get('n', 0)}: {e})") from None
    return plans


CASE_KEYS = ("kinds", "base", "drive", "seed", "strength_pct", "right")  # the fields every use of a row reads
PLAN_META_KEYS = ("design", "seed", "cases")  # the meta fields a plan's report, limits and rerun read


def checked_rows(plan: dict, keys: tuple[str, ...] = CASE_KEYS) -> list[dict]:
    """A plan's rows ({"id", "rows"}), each checked for the fields ``keys`` (default: those the reports, pooling
    and the limits all read); HysbenchError naming the plan and the first case that lacks one."""
    rows = plan["rows"]
    if not rows:
        raise HysbenchError(f"plan {plan['id']} has no rows")
    for i, r in enumerate(rows):
        bad = [k for k in keys if k not in r] if isinstance(r, dict) else ["fields"]
        if not bad and not (isinstance(r["seed"], int) and isinstance(r["kinds"], list)
                            and isinstance(r["strength_pct"], (int, float))):
            bad = ["seed, kinds or strength_pct of the right type"]
        if bad:
            raise HysbenchError(f"plan {plan['id']}: case {i} has no {', '.join(bad)}")
    return rows


def plan_rows(plans: dict[str, dict], ids: list[str], path: str | os.PathLike = ROWS_FILE) -> list[dict]:
    """The stored plans ``ids`` ({"id", "meta", "rows"} each); a missing one, one without rows or one whose meta
    or rows lack a field (``checked_rows``) raises HysbenchError naming it, before anything is computed from them."""
    missing = [i for i in ids if i not in plans]
    if missing:
        raise HysbenchError(f"no plan {', '.join(missing)} in {path} ({len(plans)} stored: hysbench accuracy list)")
    chosen = [{"id": i, **plans[i]} for i in ids]
    for plan in chosen:
        meta = plan["meta"]
        lacking = [k for k in PLAN_META_KEYS if k not in meta] if isinstance(meta, dict) else ["meta"]
        if lacking:
            raise HysbenchError(f"plan {plan['id']} in {path}: its meta line has no {', '.join(lacking)}")
        checked_rows(plan)
    return chosen


def write_plans(path: str | os.PathLike, plans: dict[str, dict]) -> None:
    """Write every plan (its meta line, then its rows) whole: to a temporary file, then renamed over ``path``."""
    path = Path(path)
    ensure_dir(path.parent)
    buffer = io.BytesIO()
    with gzip.GzipFile(fileobj=buffer, mode="wb", mtime=0, compresslevel=9) as gz:
        for pid, plan in plans.items():
            lines = [{"plan": pid, "meta": plan["meta"]}] + [{"plan": pid, "row": r} for r in plan["rows"]]
            for entry in lines:
                gz.write((json.dumps(jsonable(entry), separators=(",", ":"), allow_nan=False) + "\n").encode())
    write_atomic(path, buffer.getvalue())


def store_plan(path: str | os.PathLike, pid: str, meta: dict, rows: list[dict]) -> None:
    """Store one plan: its lines replaced (or appended at the end if it is new), every other plan kept."""
    plans = read_plans(path)
    plans[pid] = {"meta": meta, "rows": rows}
    write_plans(path, plans)

