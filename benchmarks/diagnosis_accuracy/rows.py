"""Every stored plan's rows in one file: gzip-compressed JSON lines (results/diagnosis_accuracy_rows.jsonl.gz).

Each line is one JSON object with ``"plan"`` (the plan's id, ``plan_id``) and either ``"meta"`` (one line per
plan, before its rows: how it was run) or ``"row"`` (one diagnosed case, in the plan's order; its fields are
those ``accuracy.run_case`` returns, listed in benchmarks/diagnosis_accuracy/README.md). Storing a plan replaces
every line of that plan and keeps the others as they are. The file is written whole (a temporary file renamed
over it), strict JSON (a non-finite number as null), byte for byte the same for the same plans (no time stamp
in the gzip header). Every line carries ``"format"`` (``ROWS_FORMAT``); a line without it is read as that
format (hysbench 0.2.0 wrote the same layout unlabelled), a line of another format is refused.

Reading is strict (``read_plans``): a file that is not gzip or is truncated, a line that is not a JSON object,
of another format, or whose meta or row lacks a field every reader needs or holds a field of the wrong type is
refused with ``RowFileError``, one line naming the file, the line and the field.
"""

from __future__ import annotations

import gzip
import io
import json
import os
import zlib
from pathlib import Path

from hysbench.data.files import ensure_dir, jsonable, write_atomic
from hysbench.models.errors import HysbenchError

ROWS_FILE = Path("results") / "diagnosis_accuracy_rows.jsonl.gz"
ROWS_FORMAT = "hysbench-accuracy-rows/1"  # the layout of every line; the only one this code writes and reads
META_KEYS = ("design", "seed", "cases", "wall_s", "code", "machine", "missing_bases", "note", "on")
PLAN_DESIGNS = ("balanced", "within-limits")


class RowFileError(HysbenchError):
    """A row file that cannot be read: not gzip, truncated, a line that is not JSON or of another format, a field
    missing or of the wrong type."""


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


# --- what a line must hold: field -> (kind, required); a kind is (test, what it must be) or a nested spec -------
def _kind(test, what: str):
    return test, what


def _optional(kind):
    return (lambda v: v is None or kind[0](v)), f"{kind[1]} or null"


def _list_of(kind, nonempty: bool = False):
    return ((lambda v: isinstance(v, list) and (bool(v) or not nonempty) and all(kind[0](x) for x in v)),
            f"a{' non-empty' if nonempty else ''} list of {kind[1].removeprefix('a ').removeprefix('an ')}s")


TEXT = _kind(lambda v: isinstance(v, str), "a string")
INTEGER = _kind(lambda v: isinstance(v, int) and not isinstance(v, bool), "an integer")
COUNT = _kind(lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0, "an integer >= 0")
NUMBER = _kind(lambda v: isinstance(v, (int, float)) and not isinstance(v, bool), "a number")
FLAG = _kind(lambda v: isinstance(v, bool), "true or false")
OBJECT = _kind(lambda v: isinstance(v, dict), "an object")
TEXTS = _list_of(TEXT)
ERRORS = _kind(lambda v: isinstance(v, dict) and all(NUMBER[0](x) or x is None for x in v.values()),
               "an object of numbers (null: not computed)")
DESIGN = _kind(lambda v: v in PLAN_DESIGNS, " or ".join(repr(d) for d in PLAN_DESIGNS))

MACHINE = {"cpu_count": (_optional(INTEGER), True), "load_start": (NUMBER, True), "load_end": (NUMBER, True),
           "jobs": (COUNT, False)}
OWN = {"verdict": (TEXT, True), "also": (TEXTS, True), "reason": (TEXT, True), "confirmed": (_optional(FLAG), False)}
ON = {"dataset": (TEXT, True), "name": (TEXT, True), "model": (TEXT, True), "own": (OWN, True),
      "segments": (_optional(COUNT), False), "thorough": (FLAG, False)}
META_FIELDS = {"design": (DESIGN, True), "seed": (COUNT, True), "cases": (COUNT, True),
               "wall_s": (_optional(NUMBER), False), "code": (TEXT, False), "machine": (MACHINE, False),
               "missing_bases": (_kind(lambda v: isinstance(v, dict) and all(isinstance(x, str) for x in v.values()),
                                       "an object of strings"), False),
               "note": (TEXT, False), "on": (ON, False)}
# a row: the fields every reader needs (``CASE_KEYS``) required; every other known field checked when present
ROW_FIELDS = {"kinds": (_list_of(TEXT, nonempty=True), True), "base": (TEXT, True), "drive": (TEXT, True),
              "seed": (COUNT, True), "strength_pct": (NUMBER, True), "right": (FLAG, True),
              "strength_by_effect_pct": (OBJECT, False), "min_strength_pct": (OBJECT, False),
              "attempts": (COUNT, False), "effects": (OBJECT, False), "verdict": (TEXT, False),
              "trace": (_list_of(_kind(lambda v: isinstance(v, list) and len(v) == 2
                                       and all(isinstance(x, str) for x in v), "a [rule, outcome] pair")), False),
              "confirmed": (_optional(FLAG), False), "validation": (OBJECT, False), "also": (TEXTS, False),
              "ambiguous_with": (TEXTS, False), "remainder": (_optional(NUMBER), False),
              "dropped": (_optional(TEXT), False), "unexplained_check": (_optional(OBJECT), False),
              "also_on_validation": (_list_of(OBJECT), False), "parameters": (OBJECT, False),
              "parameter_errors": (ERRORS, False), "parameters_within": (FLAG, False),
              "also_parameter_errors": (_kind(lambda v: isinstance(v, dict) and all(ERRORS[0](x) for x in v.values()),
                                              "an object of parameter errors"), False),
              "own_lead_s": (NUMBER, False), "parameter_errors_planted_alone": (ERRORS, False),
              "also_parameter_errors_planted_alone": (OBJECT, False), "effect_evidence": (OBJECT, False),
              "effect_shows_evidence": (FLAG, False), "extension_could_show": (FLAG, False),
              "shows_on_kept": (FLAG, False), "own": (TEXT, False), "seconds": (NUMBER, False)}


def _shown(value) -> str:
    """A JSON value for a message, cut short."""
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_fields(obj, spec: dict, where: str, what: str, prefix: str = "") -> None:
    """``obj`` holds every required field of ``spec``, each known field of its kind (a nested spec: an object, or
    null when optional); RowFileError naming the first that does not (``where``: file and line; ``what``: "meta"
    or "row")."""
    for name, (kind, required) in spec.items():
        field = prefix + name
        if name not in obj:
            if required:
                raise RowFileError(f"{where}: {what} has no field {field!r}")
            continue
        value = obj[name]
        if isinstance(kind, dict):  # an optional object may be null (not recorded)
            if value is None and not required:
                continue
            if not isinstance(value, dict):
                raise RowFileError(f"{where}: {what} field {field!r} must be an object, got {_shown(value)}")
            _check_fields(value, kind, where, what, field + ".")
        elif not kind[0](value):
            raise RowFileError(f"{where}: {what} field {field!r} must be {kind[1]}, got {_shown(value)}")


def _count_lines(data: bytes) -> int:
    return data.count(b"\n")


def _text(path: Path) -> str:
    """The file's text, the whole gzip stream checked first (every member, its CRC and length)."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise RowFileError(f"{path}: cannot be read ({e.strerror or e})") from None
    if not raw:
        raise RowFileError(f"{path}: empty, not a gzip-compressed accuracy row file")
    if raw[:2] != b"\x1f\x8b":
        raise RowFileError(f"{path}: not a gzip-compressed accuracy row file")
    out, rest, chunk = [], raw, 1 << 16
    while rest:
        d, end = zlib.decompressobj(16 + zlib.MAX_WBITS), len(rest)
        try:
            for i in range(0, len(rest), chunk):
                out.append(d.decompress(rest[i:i + chunk]))
                if d.eof:
                    end = i + chunk
                    break
        except zlib.error as e:
            raise RowFileError(f"{path}: damaged: the gzip stream cannot be read past line "
                               f"{_count_lines(b''.join(out)) + 1} ({e})") from None
        if not d.eof:
            raise RowFileError(f"{path}: truncated: the gzip stream ends inside line "
                               f"{_count_lines(b''.join(out) + d.flush()) + 1}")
        rest = (d.unused_data + rest[end:]).lstrip(b"\0")  # a following gzip member (or padding)
    data = b"".join(out)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise RowFileError(f"{path}, line {_count_lines(data[:e.start]) + 1}: not UTF-8 text") from None


def read_plans(path: str | os.PathLike = ROWS_FILE) -> dict[str, dict]:
    """{plan id: {"meta": {...}, "rows": [...], "lines": {"file", "meta", "rows"}}} in the file's order ({} if
    there is no file); ``lines``: the file and the line numbers of the plan's meta line and rows, for messages.
    Every line is checked (module docstring); RowFileError names the file, the line and the field."""
    path = Path(path)
    if not path.exists():
        return {}
    plans: dict[str, dict] = {}
    text = _text(path)
    lines = text.split("\n")
    if lines[-1] == "":
        lines.pop()
    elif text:
        raise RowFileError(f"{path}, line {len(lines)}: the last line is cut short (no line end)")
    for n, line in enumerate(lines, 1):
        where = f"{path}, line {n}"
        try:
            entry = json.loads(line)
        except (ValueError, RecursionError) as e:
            raise RowFileError(f"{where}: not JSON ({str(e).split(':')[0] if isinstance(e, ValueError) else e})") from None
        if not isinstance(entry, dict):
            raise RowFileError(f"{where}: not a JSON object")
        fmt = entry.get("format", ROWS_FORMAT)
        if fmt != ROWS_FORMAT:
            raise RowFileError(f"{where}: field 'format' is {_shown(fmt)}; this hysbench reads {ROWS_FORMAT!r} only")
        pid = entry.get("plan")
        if not isinstance(pid, str) or not pid:
            raise RowFileError(f"{where}: field 'plan' must be a plan id (a non-empty string), got "
                               f"{'nothing' if 'plan' not in entry else _shown(pid)}")
        if ("meta" in entry) == ("row" in entry):
            raise RowFileError(f"{where}: needs exactly one of the fields 'meta' and 'row'")
        kind = "meta" if "meta" in entry else "row"
        body = entry[kind]
        if not isinstance(body, dict):
            raise RowFileError(f"{where}: field {kind!r} must be an object, got {_shown(body)}")
        _check_fields(body, META_FIELDS if kind == "meta" else ROW_FIELDS, where, kind)
        plan = plans.get(pid)
        if kind == "meta":
            if plan is not None:
                raise RowFileError(f"{where}: a second meta line for plan {pid} (the first is line "
                                   f"{plan['lines']['meta']})")
            plans[pid] = {"meta": body, "rows": [], "lines": {"file": str(path), "meta": n, "rows": []}}
        else:
            if plan is None:
                raise RowFileError(f"{where}: a row of plan {pid} before its meta line")
            plan["rows"].append(body)
            plan["lines"]["rows"].append(n)
    return plans


CASE_KEYS = ("kinds", "base", "drive", "seed", "strength_pct", "right")  # the fields every use of a row reads
# the fields a plan's report, pooling and diagnosing again read besides (``read_plans`` checks their kinds)
REPORT_KEYS = (*CASE_KEYS, "verdict", "also", "ambiguous_with", "confirmed", "parameter_errors", "parameters_within",
               "seconds")
PLAN_META_KEYS = ("design", "seed", "cases")  # the meta fields a plan's report, limits and rerun read


def checked_rows(plan: dict, keys: tuple[str, ...] = CASE_KEYS) -> list[dict]:
    """A plan's rows ({"id", "rows"}, and "lines" as ``read_plans`` gives them), each checked for the fields
    ``keys`` (default: those the reports, pooling and the limits all read); HysbenchError naming the plan and the
    first case that lacks one (read from a file: the file and its line)."""
    rows = plan["rows"]
    if not rows:
        raise HysbenchError(f"plan {plan['id']} has no rows")
    lines = plan.get("lines")
    for i, r in enumerate(rows):
        bad = [k for k in keys if k not in r] if isinstance(r, dict) else ["fields"]
        if not bad and not (isinstance(r["seed"], int) and isinstance(r["kinds"], list)
                            and isinstance(r["strength_pct"], (int, float))):
            bad = ["seed, kinds or strength_pct of the right type"]
        if bad and lines:
            raise HysbenchError(f"{lines['file']}, line {lines['rows'][i]}: row has no field {bad[0]!r} (plan "
                                f"{plan['id']}, case {i})")
        if bad:
            raise HysbenchError(f"plan {plan['id']}: case {i} has no {', '.join(bad)}")
    return rows


def plan_rows(plans: dict[str, dict], ids: list[str], path: str | os.PathLike = ROWS_FILE,
              keys: tuple[str, ...] = CASE_KEYS) -> list[dict]:
    """The stored plans ``ids`` ({"id", "meta", "rows"} each); a missing one, one without rows or one whose meta
    or rows lack a field (``checked_rows`` with ``keys``) raises HysbenchError naming it, before anything is
    computed from them."""
    missing = [i for i in ids if i not in plans]
    if missing:
        raise HysbenchError(f"no plan {', '.join(missing)} in {path} ({len(plans)} stored: hysbench accuracy list)")
    chosen = [{"id": i, **plans[i]} for i in ids]
    for plan in chosen:
        meta = plan["meta"]
        lacking = [k for k in PLAN_META_KEYS if k not in meta] if isinstance(meta, dict) else ["meta"]
        if lacking:
            raise HysbenchError(f"plan {plan['id']} in {path}: its meta line has no {', '.join(lacking)}")
        checked_rows(plan, keys)
    return chosen


def write_plans(path: str | os.PathLike, plans: dict[str, dict]) -> None:
    """Write every plan (its meta line, then its rows) whole: to a temporary file, then renamed over ``path``."""
    path = Path(path)
    ensure_dir(path.parent)
    buffer = io.BytesIO()
    with gzip.GzipFile(fileobj=buffer, mode="wb", mtime=0, compresslevel=9) as gz:
        for pid, plan in plans.items():
            lines = ([{"format": ROWS_FORMAT, "plan": pid, "meta": plan["meta"]}]
                     + [{"format": ROWS_FORMAT, "plan": pid, "row": r} for r in plan["rows"]])
            for entry in lines:
                gz.write((json.dumps(jsonable(entry), separators=(",", ":"), allow_nan=False) + "\n").encode())
    write_atomic(path, buffer.getvalue())


def store_plan(path: str | os.PathLike, pid: str, meta: dict, rows: list[dict]) -> None:
    """Store one plan: its lines replaced (or appended at the end if it is new), every other plan kept."""
    plans = read_plans(path)
    plans[pid] = {"meta": meta, "rows": rows}
    write_plans(path, plans)

