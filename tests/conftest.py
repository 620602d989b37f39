"""Shared test fixtures."""

from pathlib import Path

import pytest

from hysbench.data.dataset import shared_datasets_root

SHARED_DATASETS = shared_datasets_root()  # ../shared/datasets beside the repository


@pytest.fixture(scope="session")
def shared_datasets() -> Path:
    if not SHARED_DATASETS.is_dir():
        pytest.skip(f"measured data not present at {SHARED_DATASETS} (not redistributable, read in place)")
    return SHARED_DATASETS

from hypothesis import settings  # noqa: E402

# Fixed seeds: hypothesis derandomised; no deadline (first calls include JIT compilation).
settings.register_profile("hysbench", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("hysbench")
