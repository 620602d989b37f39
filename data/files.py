"""Writing results: atomic files and checked output folders."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from hysbench.models.errors import HysbenchError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def default_mode(folder: bool = False) -> int:
    """Permissions a plain open()/mkdir() would give (temp files start private)."""
    return (0o777 if folder else 0o666) & ~_umask()


class OutputError(HysbenchError):
    """An output folder or file that cannot be written."""


def ensure_dir(path: str | os.PathLike) -> Path:
    """Create ``path`` if needed and check that it is a writable folder."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {path}: {exc.strerror or exc}") from None
    return _writable_folder(path)


def _writable_folder(path: Path, inside: Path | None = None) -> Path:
    """``path`` if it is a writable folder; ``inside``: the folder to be created in it, named in the message."""
    lead = f"cannot create output folder {inside}: {path}" if inside else None
    if not path.is_dir():
        raise OutputError(f"{lead} is not a folder" if lead else f"output path {path} is not a folder")
    try:  # a probe, not os.access: that says root may write anywhere, /proc included
        with tempfile.NamedTemporaryFile(dir=path, prefix=".hysbench-probe-"):
            pass
    except OSError:
        raise OutputError(f"{lead} is not writable" if lead else f"output folder {path} is not writable") from None
    return path


def check_output_dir(path: str | os.PathLike) -> Path:
    """Check, before any work and without creating anything, that ``path`` is a writable folder or can be
    created as one (its nearest existing ancestor is a writable folder)."""
    path = Path(path)
    if path.exists():
        return _writable_folder(path)
    ancestor = path.resolve().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    _writable_folder(ancestor, inside=path)
    return path


def check_output_file(path: str | os.PathLike) -> Path:
    """Check, before any work and without creating anything, that a file can be written at ``path``."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"cannot write {path}: it is a folder")
    check_output_dir(path.resolve().parent)
    return path


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write a file through a temporary sibling and rename, so no reader sees it half-written."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"cannot write {path}: it is a folder")
    mode = "wb" if isinstance(data, bytes) else "w"
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        os.chmod(tmp, default_mode())
        with os.fdopen(fd, mode, **({} if isinstance(data, bytes) else {"encoding": "utf-8"})) as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
        raise
    return path


def jsonable(obj):
    """Plain, strict JSON: numpy values as Python ones, tuples as lists, keys as strings, and non-finite
    floats as null (JSON has no NaN or infinity; jq and JavaScript refuse them)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj


def write_json(path: str | os.PathLike, obj) -> Path:
    """Strict JSON (see ``jsonable``: a non-finite float is written as null), written atomically."""
    return write_atomic(path, json.dumps(jsonable(obj), indent=2, sort_keys=False, allow_nan=False) + "\n")


def shown_path(path: str | os.PathLike) -> str:
    """A path as a report shows it: relative to the working folder when inside it, else as given."""
    rel = os.path.relpath(path)
    return str(path) if rel.startswith("..") else rel
