"""Writing results: atomic files and checked output folders."""

from __future__ import annotations

import json
import math
import os
import stat
import sys
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


CREATED_FOLDERS: list[Path] = []  # folders ``ensure_dir`` created in this process, outermost first


def remove_created_empty_folders() -> None:
    """Remove the folders ``ensure_dir`` created that are still empty (a command refused after making its
    output folder leaves nothing behind), innermost first."""
    while CREATED_FOLDERS:
        try:
            CREATED_FOLDERS.pop().rmdir()  # only an empty folder is removed
        except OSError:
            pass


def ensure_dir(path: str | os.PathLike) -> Path:
    """Create ``path`` if needed and check that it is a writable folder."""
    path = Path(path)
    missing = [p for p in (path, *path.parents) if not os.path.lexists(p)][::-1]
    try:
        path.mkdir(parents=True, exist_ok=True)
        CREATED_FOLDERS.extend(missing)
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


def output_target(path: str | os.PathLike) -> Path:
    """Where a file written at ``path`` lands. A symbolic link is followed, explicitly: the file it
    points to is replaced and the link stays. What is there must be a regular file or nothing: a
    folder, device, FIFO or socket is refused in one line (renaming over it would replace it)."""
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        mode = os.stat(target).st_mode
    except FileNotFoundError:
        return target
    except OSError as exc:
        raise OutputError(f"cannot write {shown(path)}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise OutputError(f"cannot write {shown(path)}: it is a folder")
    if not stat.S_ISREG(mode):
        kind = ("a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a FIFO" if stat.S_ISFIFO(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise OutputError(f"cannot write {shown(path)}: it is {kind}, not a regular file (refused, left as it is)")
    return target


def check_output_file(path: str | os.PathLike) -> Path:
    """Check, before any work and without creating anything, that a file can be written at ``path``
    (``output_target``: an existing non-regular file is refused, a symbolic link is followed)."""
    path = Path(path)
    if os.fspath(path) == STDOUT:
        return path
    target = output_target(path)
    check_output_dir(target.resolve().parent)
    return path


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write a file through a temporary sibling and rename, so no reader sees it half-written. A symbolic
    link is followed (its target is replaced, the link stays); a non-regular file is refused
    (``output_target``)."""
    path = Path(path)
    target = output_target(path)
    if isinstance(data, str):  # paths in the text are written as the OS gave them, whatever their bytes
        data = data.encode("utf-8", "surrogateescape")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise OutputError(f"cannot write {shown(path)}: {exc.strerror or exc}") from None
    try:
        os.chmod(tmp, default_mode())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {shown(path)}: {exc.strerror or exc}") from None
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


STDOUT = "-"  # as an output file: standard output


def write_json(path: str | os.PathLike, obj) -> Path:
    """Strict JSON (see ``jsonable``: a non-finite float is written as null), written atomically;
    ``-`` writes it to standard output."""
    text = json.dumps(jsonable(obj), indent=2, sort_keys=False, allow_nan=False) + "\n"
    if os.fspath(path) == STDOUT:
        sys.stdout.write(text)
        sys.stdout.flush()
        return Path(path)
    return write_atomic(path, text)


def shown(path: str | os.PathLike) -> str:
    """A path for a message, whatever bytes its name holds (a name that is not valid UTF-8 is shown
    with escapes, never raises)."""
    return os.fsdecode(path).encode("utf-8", "backslashreplace").decode("utf-8")


def shown_path(path: str | os.PathLike) -> str:
    """A path as a report shows it: relative to the working folder when inside it, else as given."""
    rel = os.path.relpath(path)
    return str(path) if rel.startswith("..") else rel
