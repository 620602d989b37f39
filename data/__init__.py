"""Datasets: the dataset.toml format, its loader, and data hysbench generates."""

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
