"""The dataset format: a folder with ``dataset.toml`` and its record files.

```toml
name = "virtual-dea"
description = "free text"
time_column = "t"
input_column = "u"
output_column = "y"
input_unit = "kV"
output_unit = "mm"
# optional: csv_columns = ["t", "u", "y"] names the columns of CSV files that have
# no header row; delimiter = "," (default)

[[records]]
file = "f0.02Hz.csv"      # relative to dataset.toml; CSV with a header row, or .npz
frequency_hz = 0.02        # optional for records that are not periodic
role = "identification"    # or "validation"
weight = 4                 # k_m of eq. 9; default 1
window = [950.0, 1000.0]   # optional [start, end] in s: what is fitted and scored
```

Without ``window`` a periodic record is scored on its last full period, any
other record on all of it. Models are always simulated from a record's first
sample. Time must increase with a uniform step: every step within
``UNIFORM_STEP_TOLERANCE`` (1 %) of the median step. A drive frequency must lie
below the Nyquist frequency 0.5/dt, and the output must vary in the scored window.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
import os
import re
import shutil
import stat
import tempfile
import zipfile
import tomllib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from hysbench.models.errors import HysbenchError

ROLES = ("identification", "validation")
UNIFORM_STEP_TOLERANCE = 0.01
MAX_MAGNITUDE = 1e100  # |value| of any column: squares summed over many samples stay finite
MIN_MAGNITUDE = float(np.finfo(float).tiny)  # a non-zero |value| below it is subnormal: too few digits to scale
MAX_RECORD_BYTES = 2**30  # an array file's columns, as float64 once loaded, read from its header before loading
TOP_REQUIRED = ("name", "time_column", "input_column", "output_column", "records")
TOP_OPTIONAL = ("description", "input_unit", "output_unit", "csv_columns", "delimiter")
RECORD_REQUIRED = ("file", "role")
RECORD_OPTIONAL = ("frequency_hz", "weight", "window")


class DatasetError(HysbenchError):
    """A dataset that the loader refuses; the message names the file and the problem."""


@dataclass
class Record:
    """One measured (or simulated) record: time, input, output and its role.

    Attributes
    ----------
    file : str
        The record's file name, relative to the dataset folder (its key in the dataset).
    t : numpy.ndarray
        Sample times, s, shape (n,), increasing and uniformly spaced.
    u : numpy.ndarray
        The input, shape (n,), in the dataset's ``input_unit``.
    y : numpy.ndarray
        The measured output, shape (n,), in the dataset's ``output_unit``.
    role : str
        "identification" (fitted) or "validation" (never fitted).
    frequency_hz : float or None
        The drive frequency, Hz (None: not a periodic drive).
    weight : float
        k_m of eq. 9 when the record is fitted.
    window : tuple[float, float] or None
        The scored window [start, end) in s as the manifest gives it (None: the last full period of a
        periodic record, else all of it).
    start, stop : int
        Sample indices [start, stop) of the scored window.
    dt : float
        The sample time, s (a property).
    scored : slice
        ``slice(start, stop)``: the samples that are fitted and scored (a property).
    n_scored : int
        The number of scored samples (a property).
    label : str
        "0.2 Hz" for a periodic record, else the file's stem (a property).
    """

    file: str
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    role: str = "identification"
    frequency_hz: float | None = None
    weight: float = 1.0
    window: tuple[float, float] | None = None
    start: int = field(default=0)
    stop: int = field(default=-1)

    def __post_init__(self):
        self.t = np.ascontiguousarray(self.t, dtype=float)
        self.u = np.ascontiguousarray(self.u, dtype=float)
        self.y = np.ascontiguousarray(self.y, dtype=float)
        if self.stop < 0:
            self.start, self.stop = scored_window(self.file, self.t, self.frequency_hz, self.window)

    @property
    def dt(self) -> float:
        """The sample time, s."""
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1)) if self.t.size > 1 else 0.0

    @property
    def scored(self) -> slice:
        """The samples that are fitted and scored."""
        return slice(self.start, self.stop)

    @property
    def n_scored(self) -> int:
        return self.stop - self.start

    @property
    def label(self) -> str:
        return f"{self.frequency_hz:g} Hz" if self.frequency_hz else Path(self.file).stem


@dataclass
class Dataset:
    """A plain container: metadata and records with fixed roles.

    Attributes
    ----------
    name : str
        The dataset's name (``name`` in dataset.toml).
    records : list[Record]
        Every record, in the manifest's order.
    description : str
        Free text from the manifest.
    time_column, input_column, output_column : str
        The column names (or 0-based indices as text) the records were read from.
    input_unit, output_unit : str
        The units of ``u`` and ``y`` ("" when the manifest names none).
    path : pathlib.Path or None
        The folder the dataset was read from (None: built in memory).
    identification : list[Record]
        The records with role "identification" (a property).
    validation : list[Record]
        The records with role "validation" (a property).
    """

    name: str
    records: list[Record]
    description: str = ""
    time_column: str = "t"
    input_column: str = "u"
    output_column: str = "y"
    input_unit: str = ""
    output_unit: str = ""
    path: Path | None = None

    @property
    def identification(self) -> list[Record]:
        return [r for r in self.records if r.role == "identification"]

    @property
    def validation(self) -> list[Record]:
        return [r for r in self.records if r.role == "validation"]

    def record(self, file: str) -> Record:
        for r in self.records:
            if r.file == file:
                return r
        raise DatasetError(f"dataset {self.name!r} has no record {file!r}")

    def content_hash(self) -> str:
        """SHA-256 over metadata and every record's arrays and settings."""
        h = hashlib.sha256()
        h.update(repr((self.name, self.time_column, self.input_column, self.output_column)).encode())
        for r in self.records:
            h.update(repr((r.file, r.role, r.frequency_hz, r.weight, r.window, r.start, r.stop)).encode())
            for a in (r.t, r.u, r.y):
                h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        return h.hexdigest()


# --- loading ---------------------------------------------------------------
def shared_datasets_root() -> Path:
    """``../shared/datasets`` beside the repository: the measured datasets, read in place, never copied."""
    return Path(__file__).resolve().parents[2] / "shared" / "datasets"


def load_dataset(path: str | os.PathLike) -> Dataset:
    """Read and check a dataset folder (or its dataset.toml)."""
    path = Path(path)
    toml_path = path if path.suffix == ".toml" else path / "dataset.toml"
    if path.suffix != ".toml" and path.is_file():
        raise DatasetError(f"{path}: a file, not a dataset folder (a dataset is a folder holding dataset.toml; "
                           "for a CSV file, hysbench dataset init writes one)")
    if toml_path.exists() and not toml_path.is_file():
        raise DatasetError(f"{toml_path}: not a regular file (a dataset is a folder holding dataset.toml)")
    if not toml_path.is_file():
        raise DatasetError(f"{toml_path}: no such dataset file (a dataset is a folder holding dataset.toml)")
    try:
        meta = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{toml_path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise DatasetError(f"{toml_path}: not valid TOML: arrays or tables nested too deeply") from None
    _check_keys(toml_path.name, meta, TOP_REQUIRED, TOP_OPTIONAL)
    for key in ("name", "time_column", "input_column", "output_column", "description", "input_unit", "output_unit"):
        if key in meta and not isinstance(meta[key], str):
            raise DatasetError(f"{toml_path.name}: {key} must be a string")
    records_meta = meta["records"]
    if not isinstance(records_meta, list) or not records_meta:
        raise DatasetError(f"{toml_path.name}: records must be a non-empty list of [[records]] tables")
    csv_columns = meta.get("csv_columns")
    if csv_columns is not None and not (
        isinstance(csv_columns, list) and all(isinstance(c, str) for c in csv_columns)
    ):
        raise DatasetError(f"{toml_path.name}: csv_columns must be a list of column names")
    delimiter = meta.get("delimiter", ",")
    if not (isinstance(delimiter, str) and len(delimiter) == 1):
        raise DatasetError(f"{toml_path.name}: delimiter must be one character")
    columns = (meta["time_column"], meta["input_column"], meta["output_column"])
    _check_distinct_columns(toml_path.name, columns)
    records = []
    for i, rm in enumerate(records_meta):
        if not isinstance(rm, dict):
            raise DatasetError(f"{toml_path.name}: records[{i}] must be a table")
        records.append(_load_record(toml_path.parent, i, rm, columns, csv_columns, delimiter))
    _check_held_out(records)
    _unique_keys(records)
    return Dataset(
        name=meta["name"],
        description=meta.get("description", ""),
        time_column=columns[0],
        input_column=columns[1],
        output_column=columns[2],
        input_unit=meta.get("input_unit", ""),
        output_unit=meta.get("output_unit", ""),
        records=records,
        path=toml_path.parent,
    )


def _check_distinct_columns(where: str, columns) -> None:
    keys = ("time_column", "input_column", "output_column")
    for i in range(3):
        for j in range(i + 1, 3):
            if columns[i] == columns[j]:
                raise DatasetError(f"{where}: {keys[i]} and {keys[j]} are the same column {columns[i]!r}; "
                                   f"time, input and output must be three different columns")


def _check_held_out(records: list[Record]) -> None:
    """Held out means held out: no validation window overlaps an identification window of the same file."""
    for a in records:
        for b in records:
            if (a.file == b.file and a.role == "identification" and b.role == "validation"
                    and max(a.start, b.start) < min(a.stop, b.stop)):
                raise DatasetError(f"{a.file}: its validation window overlaps its identification window "
                                   f"({a.t[max(a.start, b.start)]:g}-{a.t[min(a.stop, b.stop) - 1]:g} s); "
                                   "validation samples must take no part in the fit")


def _unique_keys(records: list[Record]) -> None:
    """A record's ``file`` is its key everywhere (roles, fit_on, scores, reports). A file listed more than
    once (e.g. one recording, an identification and a validation window) is keyed STEM#k.SUFFIX,
    k = 1, 2, ... in manifest order; its data were read from the file itself."""
    counts = Counter(r.file for r in records)
    seen: Counter = Counter()
    for r in records:
        if counts[r.file] > 1:
            seen[r.file] += 1
            path = Path(r.file)
            r.file = str(path.with_name(f"{path.stem}#{seen[r.file]}{path.suffix}"))


def _check_keys(where: str, table: dict, required: Iterable[str], optional: Iterable[str]) -> None:
    allowed = set(required) | set(optional)
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise DatasetError(f"{where}: unknown key(s) {', '.join(unknown)} (allowed: {', '.join(sorted(allowed))})")
    missing = [k for k in required if k not in table]
    if missing:
        raise DatasetError(f"{where}: missing key(s) {', '.join(missing)}")


def _number(where: str, key: str, value, positive: bool = False, nonnegative: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DatasetError(f"{where}: {key} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise DatasetError(f"{where}: {key} must be positive, got {value!r}")
    if nonnegative and value < 0:
        raise DatasetError(f"{where}: {key} must not be negative, got {value!r}")
    return float(value)


def _load_record(folder: Path, index: int, rm: dict, columns, csv_columns, delimiter) -> Record:
    where = f"records[{index}]"
    _check_keys(f"dataset.toml {where}", rm, RECORD_REQUIRED, RECORD_OPTIONAL)
    file = rm["file"]
    if not isinstance(file, str) or not file:
        raise DatasetError(f"dataset.toml {where}: file must be a non-empty string")
    where = file
    role = rm["role"]
    if role not in ROLES:
        raise DatasetError(f"{where}: role must be 'identification' or 'validation', got {role!r}")
    freq = rm.get("frequency_hz")
    if freq is not None:
        freq = _number(where, "frequency_hz", freq, positive=True)
    weight = _number(where, "weight", rm.get("weight", 1.0), nonnegative=True)
    window = rm.get("window")
    if window is not None:
        if not (isinstance(window, list) and len(window) == 2):
            raise DatasetError(f"{where}: window must be [start, end] in seconds")
        window = (_number(where, "window start", window[0]), _number(where, "window end", window[1]))
    file_path = record_path(folder, file, where)
    (t, u, y), line_numbers = _read_columns(file_path, where, columns, csv_columns, delimiter)
    check_series(where, t, u, y, columns, line_numbers)
    record = Record(file=file, t=t, u=u, y=y, role=role, frequency_hz=freq, weight=weight, window=window)
    _check_output_span(where, record.y[record.scored])
    return record


def record_path(folder: Path, file: str, where: str) -> Path:
    """The record file's path: a relative ``file`` must stay inside the dataset folder (symbolic links
    resolved), an absolute one is taken as it is; it must be a regular file."""
    file_path = folder / file
    if not os.path.isabs(file) and not Path(os.path.realpath(file_path)).is_relative_to(os.path.realpath(folder)):
        raise DatasetError(f"{where}: a relative record path must stay inside the dataset folder "
                           f"(use an absolute path for a file elsewhere)")
    try:
        mode = os.stat(file_path).st_mode
    except FileNotFoundError:
        raise DatasetError(f"{where}: file not found ({file_path})") from None
    except OSError as exc:
        raise DatasetError(f"{where}: cannot read record file: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise DatasetError(f"{where}: is a folder, not a record file ({file_path})")
    if not stat.S_ISREG(mode):
        raise DatasetError(f"{where}: not a regular file (a device, FIFO or socket); a record is a .csv or .npz file")
    return file_path


def fitting_problems(dataset: "Dataset") -> list[str]:
    """Why no model can be identified on ``dataset`` as it is ('check' warns, commands that fit refuse)."""
    if not dataset.identification:
        return ["no identification records (every record has role 'validation'): nothing to fit on"]
    if all(float(np.ptp(r.u)) == 0 for r in dataset.identification):
        return ["the input is constant in every identification record: no hysteresis can be identified"]
    if not any(r.weight > 0 for r in dataset.identification):  # eq. 9 weighs every fitted residual by it
        return ["every identification record has weight 0: eq. 9 has nothing to fit"]
    return []


def _check_output_span(where: str, y: np.ndarray) -> None:
    """e_m and e_rms are % of the scored output's peak-to-peak: it must be positive (``check_series`` keeps
    it finite)."""
    if float(np.max(y) - np.min(y)) == 0:
        raise DatasetError(f"{where}: output is constant in the scored window: the errors e_m and e_rms "
                           f"(% of its peak-to-peak) are undefined")


def _read_columns(path: Path, where: str, columns, csv_columns, delimiter):
    """The columns' arrays and, for a CSV file, the file's line number of each sample (None for .npz)."""
    if path.suffix == ".npz":
        _check_npz_size(path, where, columns)
        try:
            with np.load(path, allow_pickle=False) as z:
                missing = [c for c in columns if c not in z.files]
                if missing:
                    raise DatasetError(f"{where}: missing column(s) {', '.join(missing)} "
                                       f"(the file holds {len(z.files)} arrays)")
                arrays = [np.asarray(z[c]) for c in columns]
        except DatasetError:
            raise
        except Exception as exc:  # zip, pickle or format errors (named by type: no file content echoed)
            raise DatasetError(f"{where}: cannot read .npz file ({type(exc).__name__})") from None
        for c, a in zip(columns, arrays):
            if a.ndim != 1:
                raise DatasetError(f"{where}: column {c} must be 1-D, has shape {a.shape}")
            if not np.issubdtype(a.dtype, np.number):
                raise DatasetError(f"{where}: column {c} is not numeric ({a.dtype})")
            if np.issubdtype(a.dtype, np.complexfloating):
                raise DatasetError(f"{where}: column {c} is complex ({a.dtype}); columns must be real numbers")
        return [a.astype(float) for a in arrays], None
    return _read_csv(path, where, columns, csv_columns, delimiter)


def _check_npz_size(path: Path, where: str, columns) -> None:
    """Refuse, from the .npy headers alone, columns that would take more than MAX_RECORD_BYTES as float64
    (a compressed file can be tiny and expand to gigabytes)."""
    total = 0
    try:
        with zipfile.ZipFile(path) as zf:
            for c in columns:
                try:
                    member = zf.open(f"{c}.npy")
                except KeyError:
                    continue  # named as missing when loaded
                with member:
                    version = np.lib.format.read_magic(member)
                    header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                              else np.lib.format.read_array_header_2_0)(member)
                shape = header[0]
                total += 8 * math.prod(int(n) for n in shape)
    except DatasetError:
        raise
    except Exception as exc:  # not a zip, a bad header
        raise DatasetError(f"{where}: cannot read .npz file ({type(exc).__name__})") from None
    if total > MAX_RECORD_BYTES:
        raise DatasetError(f"{where}: its columns would take {total / 2**20:.0f} MiB in memory, above the limit of "
                           f"{MAX_RECORD_BYTES / 2**20:.0f} MiB per record (refused before loading)")


CSV_DELIMITERS = (",", ";", "\t", " ", "|")  # the ones a missing column is checked against (a hint)


def csv_text(path: Path, where: str) -> str:
    """A CSV file's text (UTF-8, a byte-order mark dropped); one DatasetError line naming what is wrong."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DatasetError(f"{where}: cannot read CSV file: {exc.strerror or exc}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{where}: {not_utf8(raw, exc)}") from None


def _read_csv(path: Path, where: str, columns, csv_columns, delimiter):
    if path.stat().st_size > MAX_RECORD_BYTES:
        raise DatasetError(f"{where}: CSV file larger than the limit of {MAX_RECORD_BYTES / 2**20:.0f} MiB per record")
    text = csv_text(path, where)
    # blank lines are skipped; lines are numbered as an editor numbers them (\n, \r\n or \r ends one)
    numbered = [(n, ln) for n, ln in enumerate(re.split(r"\r\n|\r|\n", text), start=1) if ln.strip()]
    header_line = None
    if csv_columns is None:
        if not numbered:
            raise DatasetError(f"{where}: empty record (the file holds no header row and no data)")
        header_line = numbered[0][1]
        header = [h.strip() for h in next(csv.reader([header_line], delimiter=delimiter))]
        numbered = numbered[1:]
        names_from = "the header row"
    else:
        header = list(csv_columns)
        names_from = "csv_columns"
    line_numbers = np.array([n for n, _ in numbered], dtype=np.int64)
    body = [ln for _, ln in numbered]
    missing = [c for c in columns if c not in header]
    if missing:  # the header's own text is not echoed: the file may be anything
        other = next((d for d in CSV_DELIMITERS if d != delimiter and header_line is not None
                      and all(c in [h.strip() for h in header_line.split(d)] for c in columns)), None)
        hint = f"; its fields look separated by {other!r}: set the dataset's delimiter" if other else ""
        raise DatasetError(f"{where}: missing column(s) {', '.join(missing)} ({names_from} names "
                           f"{len(header)} column{'s' if len(header) != 1 else ''}, not these{hint})")
    for c in columns:
        if header.count(c) > 1:
            raise DatasetError(f"{where}: column name {c!r} appears {header.count(c)} times in {names_from}; "
                               f"which one is meant is ambiguous")
    if not body:
        raise DatasetError(f"{where}: empty record (no data rows)")
    wanted = [header.index(c) for c in columns]
    counts = np.array([ln.count(delimiter) + 1 for ln in body]) if '"' not in text else None
    if counts is not None and np.any(counts != len(header)):
        k = int(np.flatnonzero(counts != len(header))[0])
        runs = " " * 2 * (delimiter == " ")  # columns aligned by runs of spaces split into empty fields
        hint = ("; fields are separated by runs of spaces: the delimiter must stand once between fields"
                if runs and any(runs in ln or ln.startswith(" ") for ln in (header_line or "", body[k])) else "")
        raise DatasetError(f"{where}: columns of unequal length (line {line_numbers[k]} has {counts[k]} fields, "
                           f"{names_from} names {len(header)}{hint})")
    data = None
    if counts is not None:  # no quotes: a delimiter always splits fields, which loadtxt assumes
        try:
            # comments=None: '#' starts no comment in the format (an Excel '#N/A' must not drop its row)
            data = np.loadtxt(io.StringIO("\n".join(body)), delimiter=delimiter, usecols=wanted, ndmin=2,
                              comments=None)
        except ValueError:
            data = None
    if data is None:
        rows = list(csv.reader(body, delimiter=delimiter))
        lengths = {len(r) for r in rows}
        if len(lengths) > 1 or max(lengths) < len(header):
            raise DatasetError(f"{where}: columns of unequal length (rows have {sorted(lengths)} fields)")
        data = np.empty((len(rows), len(wanted)))
        for i, r in enumerate(rows):
            for k, j in enumerate(wanted):
                data[i, k] = _csv_number(r[j], where, int(line_numbers[i]), columns[k])
    return [data[:, k].copy() for k in range(len(columns))], line_numbers


def not_utf8(raw: bytes, exc: UnicodeDecodeError) -> str:
    """Why a CSV file's bytes are not read: the format is UTF-8 text (a BOM is allowed)."""
    if raw.startswith(b"PK\x03\x04"):
        return "is a zip archive (an .xlsx workbook?), not CSV text: export it as CSV (UTF-8)"
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "is UTF-16 text (a spreadsheet's 'Unicode text'); CSV records are read as UTF-8: save it as UTF-8"
    line = raw.count(b"\n", 0, exc.start) + 1
    return (f"is not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line}, e.g. a 'µ' written in "
            "Latin-1); CSV records are read as UTF-8: save it as UTF-8")


# a decimal number in ASCII digits (float() would also take '1_0' as 10, and digits of other scripts)
DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+([eE][+-]?\d+)?", re.ASCII)
CSV_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.ASCII | re.IGNORECASE)


def _csv_number(cell: str, where: str, line: int, column: str) -> float:
    """A CSV cell as a float, strictly: Python's float() would also read '1_0' as 10. The cell's text is not
    echoed."""
    cell = cell.strip()
    if not cell:
        raise DatasetError(f"{where}: empty cell on line {line}, column {column}")
    if not CSV_NUMBER.fullmatch(cell):
        hint = "; numbers take a decimal point, not a comma" if DECIMAL_COMMA.fullmatch(cell) else ""
        raise DatasetError(f"{where}: non-numeric value on line {line}, column {column}{hint}")
    return float(cell)


def check_series(where: str, t: np.ndarray, u: np.ndarray, y: np.ndarray, columns=("t", "u", "y"),
                 line_numbers: np.ndarray | None = None) -> None:
    """Refuse unequal lengths, empty records, NaN/inf, values beyond MAX_MAGNITUDE and non-uniform time.

    A sample is named by its file line (``line_numbers[k]``, a CSV file's) or else by its index from 0."""

    def at(k: int) -> str:
        return f"on line {line_numbers[k]}" if line_numbers is not None else f"at sample {k}"

    lengths = {c: a.size for c, a in zip(columns, (t, u, y))}
    if len(set(lengths.values())) > 1:
        raise DatasetError(f"{where}: columns of unequal length ({', '.join(f'{c}: {n}' for c, n in lengths.items())})")
    if t.size == 0:
        raise DatasetError(f"{where}: empty record")
    for c, a in zip(columns, (t, u, y)):
        if not np.all(np.isfinite(a)):
            k = int(np.flatnonzero(~np.isfinite(a))[0])
            raise DatasetError(f"{where}: column {c} holds NaN or inf (first {at(k)})")
        small = (a != 0) & (np.abs(a) < MIN_MAGNITUDE)
        if np.any(small):
            k = int(np.flatnonzero(small)[0])
            raise DatasetError(f"{where}: column {c} holds {a[k]:g} {at(k)}, subnormal (below {MIN_MAGNITUDE:g} "
                               "in magnitude): too few digits to compute with (rescale the column's unit)")
        if np.any(np.abs(a) > MAX_MAGNITUDE):
            k = int(np.flatnonzero(np.abs(a) > MAX_MAGNITUDE)[0])
            raise DatasetError(f"{where}: column {c} holds {a[k]:g} {at(k)}, beyond {MAX_MAGNITUDE:g} in "
                               "magnitude: sums of squares would overflow (rescale the column's unit)")
    if t.size < 2:
        raise DatasetError(f"{where}: a record needs at least two samples")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        raise DatasetError(f"{where}: time is not increasing ({at(k + 1)})")
    median = float(np.median(steps))
    dev = np.abs(steps - median) > UNIFORM_STEP_TOLERANCE * median
    if np.any(dev):
        k = int(np.flatnonzero(dev)[0])
        raise DatasetError(
            f"{where}: time step is not uniform (step {steps[k]:.6g} s {at(k + 1)} vs median {median:.6g} s; "
            f"tolerance {UNIFORM_STEP_TOLERANCE:.0%})"
        )


def _count_text(x: float) -> str:
    """A sample count in plain readable digits, however large."""
    if not math.isfinite(x):
        return "more than 1e308"
    return f"{x:.0f}" if x < 1e12 else f"{x:.3g}"


def scored_window(where: str, t: np.ndarray, frequency_hz: float | None, window) -> tuple[int, int]:
    """Sample indices [start, stop) that are fitted and scored."""
    n = t.size
    dt = float((t[-1] - t[0]) / (n - 1)) if n > 1 else 0.0
    if frequency_hz is not None and n > 1:
        with np.errstate(over="ignore", divide="ignore"):
            nyquist = float(0.5 / np.float64(dt))
            period_samples = float(1.0 / (np.float64(frequency_hz) * dt))  # inf if too long to count
        if frequency_hz >= nyquist:
            raise DatasetError(
                f"{where}: frequency_hz {frequency_hz:g} Hz is at or above the Nyquist frequency {nyquist:g} Hz "
                f"of the record (step {dt:g} s): a period needs more than two samples"
            )
        if not period_samples < n + 0.5:  # rounds to more than n samples
            raise DatasetError(
                f"{where}: record is shorter than a period ({n} samples, one period of {frequency_hz:g} Hz "
                f"is {_count_text(period_samples)} samples)"
            )
        period = int(round(period_samples))
    else:
        period = None
    if window is not None:
        a, b = window
        if not (a < b):
            raise DatasetError(f"{where}: window start {a:g} s is not before its end {b:g} s")
        half = 0.5 * dt
        if a < t[0] - half or b > t[-1] + dt + half:  # the end is exclusive
            raise DatasetError(f"{where}: window [{a:g}, {b:g}] s is outside the record's time [{t[0]:g}, {t[-1]:g}] s")
        start = int(np.searchsorted(t, a - half))
        stop = int(np.searchsorted(t, b - half))  # end is exclusive, like [a, b)
        if stop - start < 2:
            raise DatasetError(f"{where}: window [{a:g}, {b:g}] s holds fewer than two samples")
        return start, stop
    if period is not None:
        return n - period, n
    return 0, n


# --- scale -----------------------------------------------------------------
ORDINARY_SCALE = (2.0**-100, 2.0**100)  # max |output| within: computed as it is


def output_scale(dataset: Dataset) -> float:
    """``scale_of_outputs`` of every record's output."""
    return scale_of_outputs(r.y for r in dataset.records)


def scale_of_outputs(outputs: Iterable[np.ndarray]) -> float:
    """1 where max |output| lies in ORDINARY_SCALE, else the power of two 2^e with 2^e <= max |output| <
    2^(e+1): dividing by it is exact, so e.g. data at 1e-200 or 1e+90 are computed at order one with every
    digit kept (and data at ordinary scales are left untouched, bit for bit)."""
    peak = max((float(np.max(np.abs(y))) for y in outputs if np.size(y)), default=0.0)
    if ORDINARY_SCALE[0] <= peak <= ORDINARY_SCALE[1] or peak == 0.0:
        return 1.0
    return math.ldexp(0.5, math.frexp(peak)[1])


def scaled_output(dataset: Dataset, scale: float) -> Dataset:
    """A copy of ``dataset`` with every output divided by ``scale`` (a power of two: exact)."""
    if scale == 1.0:
        return dataset
    records = [Record(file=r.file, t=r.t, u=r.u, y=r.y / scale, role=r.role, frequency_hz=r.frequency_hz,
                      weight=r.weight, window=r.window, start=r.start, stop=r.stop) for r in dataset.records]
    return Dataset(name=dataset.name, records=records, description=dataset.description,
                   time_column=dataset.time_column, input_column=dataset.input_column,
                   output_column=dataset.output_column, input_unit=dataset.input_unit,
                   output_unit=dataset.output_unit, path=dataset.path)


# --- writing ---------------------------------------------------------------
def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def dataset_toml(dataset: Dataset) -> str:
    lines = [f"{k} = {_toml_value(getattr(dataset, k))}" for k in (
        "name", "description", "time_column", "input_column", "output_column", "input_unit", "output_unit")]
    for r in dataset.records:
        lines += ["", "[[records]]", f"file = {_toml_value(r.file)}"]
        if r.frequency_hz is not None:
            lines.append(f"frequency_hz = {_toml_value(r.frequency_hz)}")
        lines.append(f"role = {_toml_value(r.role)}")
        lines.append(f"weight = {_toml_value(r.weight)}")
        if r.window is not None:
            lines.append(f"window = {_toml_value([float(x) for x in r.window])}")
    return "\n".join(lines) + "\n"


def save_dataset(dataset: Dataset, folder: str | os.PathLike, compress: bool = True) -> Path:
    """Write records (.npz or .csv, by file suffix) and dataset.toml.

    Written into a temporary sibling folder and then moved into place, so an
    interrupted write never leaves a half-written dataset.
    """
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())
        for r in dataset.records:
            target = tmp / r.file
            target.parent.mkdir(parents=True, exist_ok=True)
            arrays = {dataset.time_column: r.t, dataset.input_column: r.u, dataset.output_column: r.y}
            if target.suffix == ".npz":  # numpy writes with the default (umask) permissions
                (np.savez_compressed if compress else np.savez)(target, **arrays)
            elif target.suffix == ".csv":
                header = ",".join(arrays)
                np.savetxt(target, np.column_stack(list(arrays.values())), delimiter=",", header=header,
                           comments="", fmt="%.10g")
            else:
                raise DatasetError(f"{r.file}: record files must end in .npz or .csv")
        (tmp / "dataset.toml").write_text(dataset_toml(dataset), encoding="utf-8")
        replace_folder(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def replace_folder(new: Path, target: Path) -> None:
    """Move a finished folder into place, replacing any old one."""
    if target.exists():
        old = target.with_name(f".{target.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(target, old)
        os.replace(new, target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(new, target)
