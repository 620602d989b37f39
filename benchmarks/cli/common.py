"""Argument types and the parser class shared by every command."""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path
from typing import Callable

from hysbench.data.files import check_output_dir, check_output_file
from hysbench.data.virtual_dea import default_dataset_path
from hysbench.models.errors import HysbenchError


class CommandError(HysbenchError):
    """A bad command-line value (printed as one line, exit status 2)."""


def integer_at_least(minimum: int):
    """An argparse type: an integer >= ``minimum``, refused in one line otherwise."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


positive_int = integer_at_least(1)
nonnegative_int = integer_at_least(0)


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2, and reads "-1e3" as a number."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # a minus sign before a digit is a number, never an option (Python 3.11's argparse took "-1e3" for one)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def error(self, message: str):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


# --- shared arguments ----------------------------------------------------------------------
def add_dataset_argument(parser: argparse.ArgumentParser, many: bool = False) -> None:
    """DATASET: a folder holding dataset.toml (or the file itself); default: the shipped virtual DEA.
    ``many``: any number of them (the matrix)."""
    parser.add_argument("dataset", metavar="DATASET", nargs="*" if many else "?", default=None,
                        help="dataset folder holding dataset.toml (default: the virtual DEA, data/virtual_dea)"
                        + ("; several may be given" if many else ""))


def dataset_paths(value) -> list[Path]:
    """The DATASET argument's folders, the default dataset when none was given."""
    if value is None or value == []:
        return [default_dataset_path()]
    return [Path(v) for v in (value if isinstance(value, list) else [value])]


def add_seed_argument(parser: argparse.ArgumentParser, default: int = 0, what: str = "every identifier") -> None:
    parser.add_argument("--seed", type=nonnegative_int, default=default,
                        help=f"seed of {what} (a non-negative integer, default {default})")


def add_jobs_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--jobs", type=positive_int, default=None, help="worker processes (default: all cores)")


def parse_value(raw: str):
    """A KEY=VALUE value: JSON (numbers, lists, objects, true/false/null), else true/false/none in any
    case, else the text itself."""
    raw = raw.strip()
    try:
        return json.loads(raw)
    except json.JSONDecodeError:
        return {"true": True, "false": False, "none": None}.get(raw.lower(), raw)


def parse_key_values(items: list[str], flag: str) -> dict:
    """['a=1', 'lsq.max_nfev=20'] -> {'a': 1, 'lsq.max_nfev': 20}; refused in one line otherwise."""
    out = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise CommandError(f"{flag} {item!r} is not KEY=VALUE")
        try:
            out[key] = parse_value(raw)
        except RecursionError:
            raise CommandError(f"{flag} {key}=...: value nested too deeply") from None
    return out


def parse_method_options(items: list[str], flag: str = "--option") -> dict[str, dict]:
    """['mpso.iterations=50'] -> {'mpso': {'iterations': 50}} (the key names its method first)."""
    out: dict[str, dict] = {}
    for key, value in parse_key_values(items, flag).items():
        method, dot, name = key.partition(".")
        if not (dot and method and name):
            raise CommandError(f"{flag} {key}=...: expected METHOD.KEY=VALUE")
        out.setdefault(method, {})[name] = value
    return out


def comma_list(text: str | None, flag: str) -> list[str] | None:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise CommandError(f"{flag} needs at least one name")
    return names


def check_outputs(args) -> None:
    """Refuse an unwritable ``--out`` folder or ``--json`` file before any work."""
    check_output_dir(args.out)
    if args.json:
        check_output_file(args.json)


def timed_progress(quiet: bool) -> Callable[[str], None]:
    """A progress printer to stderr, each line stamped with the seconds since it was made."""
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say
