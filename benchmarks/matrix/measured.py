"""The measured suite: every dataset folder under a root (by default ../shared/datasets beside the
repository) that holds a dataset.toml; a folder without one gets a one-line hint naming
``hysbench dataset init``, a manifest the loader refuses is named with its problem."""

from __future__ import annotations

from pathlib import Path

from hysbench.data.dataset import Dataset, DatasetError, load_dataset
from hysbench.models import list_models

# Registered out of the DEA matrix because they are not DEA models, but scored on measured data:
# the Bouc-Wen benchmark's own structure (force -> displacement oscillator).
MEASURED_ONLY_MODELS = ("bouc-wen-oscillator",)

MEASURED_CSV = "matrix_measured.csv"
MEASURED_REPORT = "report_measured.md"
MEASURED_CELLS = "cells_measured"


def suite_models() -> list[str]:
    """The measured suite's models: the default matrix's and MEASURED_ONLY_MODELS (those registered)."""
    return list_models(matrix_only=True) + [m for m in MEASURED_ONLY_MODELS if m in list_models()]


def init_hint(folder: Path) -> str:
    data = sorted(p.name for p in folder.iterdir() if p.suffix.lower() in (".csv", ".txt", ".dat"))
    csv_file = folder / data[0] if data else folder / "FILE.csv"
    return (f"{folder} has no dataset.toml; describe it with: hysbench dataset init {csv_file} "
            "--time COL --input COL --output COL [--frequency F] [--role ...]")


def discover(root: Path) -> tuple[list[tuple[Path, Dataset]], list[str]]:
    """(every loadable dataset under root, sorted by folder name; one line per folder skipped and why)."""
    found, skipped = [], []
    for folder in sorted(p for p in Path(root).iterdir() if p.is_dir() and not p.name.startswith(".")):
        if not (folder / "dataset.toml").is_file():
            skipped.append(init_hint(folder))
            continue
        try:
            found.append((folder, load_dataset(folder)))
        except DatasetError as exc:
            skipped.append(f"{folder}: refused: {exc}")
    return found, skipped
