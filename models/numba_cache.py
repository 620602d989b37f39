"""Numba's on-disk cache, in a folder named by the source of every hysbench file that uses numba.

numba's ``cache=True`` checks only the file that defines a kernel, not the files whose jitted
functions it calls: after a change to ``root_search.py`` alone, a kernel in ``preisach.py`` that calls
it would be loaded from the cache, compiled against the old search. Here the cache folder is
``<base>/numba-<hash>``, the hash over every such file under the four hysbench packages, so any
change to any of them starts a fresh folder; ``<base>`` is $NUMBA_CACHE_DIR if set, else
$XDG_CACHE_HOME/hysbench or ~/.cache/hysbench (the temporary folder if neither is writable).
Older folders beyond the newest ``KEEP`` are removed. Imported before any kernel is defined
(``hysbench.models`` imports it first; the other packages import ``hysbench.models`` first).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import tempfile
import time
from pathlib import Path

import numba

PACKAGES = ("hysbench.models", "hysbench.data", "hysbench.identification", "hysbench.benchmarks")
KEEP = 4  # cache folders kept beside the current one
BUSY_SECONDS = 3600.0  # a folder touched this recently may be in use by another process: kept


def package_roots() -> list[tuple[str, Path]]:
    """(package, folder) of each of PACKAGES, found without importing them."""
    out = []
    for name in PACKAGES:
        spec = importlib.util.find_spec(name)
        out += [(name, Path(root)) for root in sorted(spec.submodule_search_locations or [])]
    return out


def source_fingerprint(roots: list[tuple[str, Path]] | None = None) -> str:
    """sha256 over the path and text of every .py file under the roots that mentions numba."""
    h = hashlib.sha256()
    for name, root in package_roots() if roots is None else roots:
        for path in sorted(root.rglob("*.py")):
            text = path.read_bytes()
            if b"numba" in text:
                h.update(f"{name}/{path.relative_to(root).as_posix()}\0".encode())
                h.update(text)
    return h.hexdigest()[:16]


def _base() -> Path:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "hysbench"


def _prune(folder: Path) -> None:
    """Remove old sibling cache folders, keeping the newest KEEP and any touched within BUSY_SECONDS."""
    try:
        others = sorted((p for p in folder.parent.glob("numba-*") if p != folder and p.is_dir()),
                        key=lambda p: p.stat().st_mtime, reverse=True)
        now = time.time()
        for p in others[KEEP:]:
            if now - p.stat().st_mtime > BUSY_SECONDS:
                shutil.rmtree(p, ignore_errors=True)
    except OSError:
        pass


def configure() -> Path:
    """Point numba's cache at the fingerprinted folder; returns it."""
    name = f"numba-{source_fingerprint()}"
    for base in (_base(), Path(tempfile.gettempdir()) / "hysbench"):
        folder = base / name
        try:
            folder.mkdir(parents=True, exist_ok=True)
            os.utime(folder)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            numba.config.CACHE_DIR = str(folder)
            _prune(folder)
            return folder
    return Path(numba.config.CACHE_DIR or "")


CACHE_FOLDER = configure()
