"""Datasets: the dataset.toml format, its loader, and data hysbench generates."""

import hysbench.models  # noqa: F401  (first: numba's cache folder, see models/numba_cache.py)
from .dataset import (
    ROLES,
    UNIFORM_STEP_TOLERANCE,
    Dataset,
    DatasetError,
    Record,
    load_dataset,
    save_dataset,
)

__all__ = [
    "ROLES",
    "UNIFORM_STEP_TOLERANCE",
    "Dataset",
    "DatasetError",
    "Record",
    "load_dataset",
    "save_dataset",
]
