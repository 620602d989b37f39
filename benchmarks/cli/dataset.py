"""``hysbench dataset init CSV --time COL --input COL --output COL``: a dataset.toml for a bare CSV file.

Columns are given by name (a CSV with a header row) or by 0-based index (any CSV).
A CSV whose first row is all numbers is read as headerless: its columns are named
in csv_columns (time, input, output for the chosen ones, colK for the others).
The manifest is written beside the CSV (one record; --role, --frequency and
--window are the record's role, frequency_hz and window, docs/datasets.md), checked
by loading the dataset before it takes the name dataset.toml, so a refused file
leaves nothing behind. Then hysbench run DIR scores it.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
from pathlib import Path

from hysbench.data.dataset import CSV_DELIMITERS, ROLES, DatasetError, csv_text, load_dataset
from hysbench.data.files import shown, write_atomic

from .common import CommandError

EXAMPLE = "hysbench dataset init measurements/run1.csv --time 0 --input 2 --output 1 --frequency 1 --role validation"
ROLE_NAMES = ("time", "input", "output")
DELIMITER_ARG = {"\t": "tab"}  # how a delimiter is typed as --delimiter


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="dataset_command", metavar="ACTION")
    sub.required = True
    p = sub.add_parser("init", help="write dataset.toml for a bare CSV file", description=__doc__.split("\n\n")[1],
                       epilog=f"example:\n  {EXAMPLE}", formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("csv", metavar="CSV", help="the CSV file (the manifest is written in its folder)")
    for role in ROLE_NAMES:
        p.add_argument(f"--{role}", required=True, metavar="COL", help=f"{role} column: a name or a 0-based index")
    p.add_argument("--frequency", type=float, metavar="F", help="drive frequency in Hz (a periodic record)")
    p.add_argument("--role", choices=ROLES, default="identification", help="the record's role (default identification)")
    p.add_argument("--window", metavar="START,END", help="scored window in seconds (default: last period or all)")
    p.add_argument("--name", help="dataset name (default: the CSV's file name without its suffix, _ written as -)")
    p.add_argument("--input-unit", default="", help="unit of the input column")
    p.add_argument("--output-unit", default="", help="unit of the output column")
    p.add_argument("--delimiter", default=",", help="field delimiter, one character; \\t or tab for a tab (default ,)")
    p.add_argument("--force", action="store_true", help="replace an existing dataset.toml")


def first_row(path: Path, delimiter: str) -> list[str]:
    try:
        text = csv_text(path, str(path))
    except DatasetError as exc:
        raise CommandError(str(exc)) from None
    for row in csv.reader(io.StringIO(text, newline=""), delimiter=delimiter):
        if any(f.strip() for f in row):
            return [f.strip() for f in row]
    raise CommandError(f"{path} holds no rows")


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def resolve_column(spec: str, flag: str, header: list[str] | None, n_columns: int) -> int:
    """A column given by name or 0-based index, as an index; refused in one line."""
    spec = spec.strip()
    if spec.isdigit():
        k = int(spec)
        if k >= n_columns:
            raise CommandError(f"{flag} {spec}: column index out of range (the CSV has {n_columns} columns, 0-based)")
        return k
    if header is None:
        raise CommandError(f"{flag} {spec!r}: the CSV has no header row; give a 0-based column index "
                           f"(0..{n_columns - 1})")
    if spec not in header:
        raise CommandError(f"{flag} {spec!r}: no such column (has {', '.join(header)})")
    return header.index(spec)


def manifest(args, csv_path: Path, header: list[str] | None, columns: list[int], n_columns: int) -> str:
    if header is None:
        names = [f"col{k}" for k in range(n_columns)]
        for role, k in zip(ROLE_NAMES, columns):
            names[k] = role
    else:
        names = header
    chosen = [names[k] for k in columns]

    def q(text: str, what: str) -> str:
        """``text`` as a TOML basic string (a JSON string, in UTF-8); TOML is UTF-8, so a name whose bytes are not
        (a file name or argument as the OS gave it) is refused, naming what holds it."""
        try:
            text.encode("utf-8")
        except UnicodeEncodeError:
            raise CommandError(f"{what} is not valid UTF-8, so dataset.toml (UTF-8) cannot hold it") from None
        # raw UTF-8: TOML has no surrogate-pair escapes (JSON's for a character beyond U+FFFF), and U+007F, which
        # JSON leaves raw, must be escaped in TOML
        return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")

    file_name = f"the CSV's file name {shown(csv_path.name)}"
    lines = [f"name = {q(args.name, '--name') if args.name else q(csv_path.stem.replace('_', '-'), file_name)}",
             f"description = {q(f'{csv_path.name}, described by hysbench dataset init', file_name)}",
             *(f"{role}_column = {q(c, 'a column name in the header row')}" for role, c in zip(ROLE_NAMES, chosen)),
             f"input_unit = {q(args.input_unit, '--input-unit')}",
             f"output_unit = {q(args.output_unit, '--output-unit')}"]
    if header is None:
        lines.append(f"csv_columns = [{', '.join(q(n, 'a column name') for n in names)}]")
    if args.delimiter != ",":
        lines.append(f"delimiter = {q(args.delimiter, '--delimiter')}")
    lines += ["", "[[records]]", f"file = {q(csv_path.name, file_name)}", f"role = {q(args.role, '--role')}"]
    if args.frequency is not None:
        lines.append(f"frequency_hz = {args.frequency!r}")
    if args.window:
        try:
            start, end = (float(x) for x in args.window.split(","))
        except ValueError:
            raise CommandError(f"--window {args.window!r}: expected START,END in seconds") from None
        lines.append(f"window = [{start!r}, {end!r}]")
    return "\n".join(lines) + "\n"


def main(args) -> int:
    csv_path = Path(args.csv)
    if csv_path.is_dir():
        raise CommandError(f"{csv_path}: is a folder; dataset init takes the CSV file itself")
    if csv_path.exists() and not csv_path.is_file():
        raise CommandError(f"{csv_path}: not a regular file (a device, FIFO or socket); dataset init takes a CSV file")
    if not csv_path.is_file():
        raise CommandError(f"{csv_path}: no such file")
    target = csv_path.parent / "dataset.toml"
    if target.exists() and not args.force:
        raise CommandError(f"{target} exists; pass --force to replace it")
    if args.delimiter in ("\\t", "tab"):  # what a shell passes for a typed \t
        args.delimiter = "\t"
    if len(args.delimiter) != 1:
        raise CommandError(f"--delimiter must be one character (\\t or tab for a tab), got {args.delimiter!r}")
    row = first_row(csv_path, args.delimiter)
    header = None if all(_is_number(f) for f in row if f) else row
    try:
        columns = [resolve_column(getattr(args, role), f"--{role}", header, len(row)) for role in ROLE_NAMES]
    except CommandError as exc:  # a first row of one field is most likely split by another separator
        other = next((d for d in CSV_DELIMITERS if d != args.delimiter and len(row) == 1
                      and len(row[0].split(d)) >= 3), None)
        if other is None:
            raise
        raise CommandError(f"{exc}; its first row is one field under --delimiter {args.delimiter!r} and looks "
                           f"separated by {other!r}: pass --delimiter {DELIMITER_ARG.get(other, other)!r}") from None
    if len(set(columns)) < 3:
        raise CommandError(f"--time, --input and --output must be three different columns, got indices {columns}")
    if header is not None:
        for role, k in zip(ROLE_NAMES, columns):
            if header.count(header[k]) > 1:
                raise CommandError(f"--{role} {getattr(args, role)}: the header row names {header.count(header[k])} "
                                   f"columns {header[k]!r}, so a manifest cannot tell them apart (rename them in "
                                   f"the CSV)")
    text = manifest(args, csv_path, header, columns, len(row))
    check = csv_path.parent / ".dataset-init.check.toml"
    write_atomic(check, text)
    try:
        ds = load_dataset(check)  # the loader's own checks (numbers, uniform time, window) before the real name
        os.replace(check, target)
    except DatasetError as exc:
        message = str(exc).removeprefix(f"{csv_path.name}: ")  # the loader names the file itself
        raise CommandError(f"{csv_path}: {message}") from None
    finally:
        check.unlink(missing_ok=True)
    rec = ds.records[0]
    print(f"wrote {target}: {rec.t.size} samples, dt {rec.dt:.6g} s, scored {rec.n_scored} samples "
          f"({rec.t[rec.start]:.6g}-{rec.t[rec.stop - 1]:.6g} s); "
          f"score it with: hysbench run {csv_path.parent}")
    return 0
