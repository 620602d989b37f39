"""Finished cells on disk: one JSON file per cell, written atomically.

A cell file is named by the cell's key (a hash of dataset content, model and
its hyperparameters, method, options, seed and a fingerprint of the code that
computes a cell), so a rerun finds what is still valid and computes only the
rest. A file of another cell format is recomputed. Temporary files left by a killed run are
removed when a store is opened.
"""

from __future__ import annotations

import json
from pathlib import Path

from hysbench.data.files import ensure_dir, write_json

from .cells import CELL_FORMAT

KEPT = ("ok", "nonfinite")  # deterministic outcomes worth keeping; a failed cell is retried


class CellStore:
    def __init__(self, out_dir: str | Path, folder: str = "cells"):
        self.folder = ensure_dir(Path(out_dir) / folder)
        for stray in self.folder.glob(".*.tmp"):
            stray.unlink(missing_ok=True)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}.json"

    def get(self, key: str) -> dict | None:
        d = read_cell(self.path(key))  # None (absent or unreadable): recompute
        ok = d is not None and d.get("key") == key and d.get("format") == CELL_FORMAT and d.get("status") in KEPT
        return d if ok else None

    def put(self, result: dict) -> Path:
        return write_json(self.path(result["key"]), result)


def read_cell(path: Path) -> dict | None:
    """A cell file's JSON object; None if it is absent, not a regular file, or damaged (not UTF-8, not JSON,
    nested too deeply, not an object)."""
    if not path.is_file():
        return None
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # ValueError: JSON and UTF-8 errors alike
        return None
    return d if isinstance(d, dict) else None
