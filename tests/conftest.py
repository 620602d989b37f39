"""Shared test fixtures, and the hypothesis profile every test process runs under."""

from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from hysbench.data.dataset import shared_datasets_root

# The same commit gives the same result: examples derive from each test's source (derandomize, which
# also turns the example database off, so no earlier run's failures are replayed), no deadline (first
# calls include JIT compilation) and no health check that times the machine (outcomes must not
# depend on load). Loaded here, at import, in the main process and in every pytest-xdist worker
# (each imports this file before collecting), before any test module builds its @settings.
CI_PROFILE = "hysbench"
settings.register_profile(
    CI_PROFILE, deadline=None, derandomize=True, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(CI_PROFILE)


def pytest_configure(config):
    # hypothesis's own plugin may load a profile named by --hypothesis-profile; without that option
    # this profile stays (reloaded after every plugin's configure ran)
    if not config.getoption("--hypothesis-profile", default=None):
        settings.load_profile(CI_PROFILE)


SHARED_DATASETS = shared_datasets_root()  # ../shared/datasets beside the repository


@pytest.fixture(scope="session")
def shared_datasets() -> Path:
    if not SHARED_DATASETS.is_dir():
        pytest.skip(f"measured data not present at {SHARED_DATASETS} (not redistributable, read in place)")
    return SHARED_DATASETS
