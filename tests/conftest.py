"""Shared test fixtures, and the hypothesis profile every test process runs under."""

from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from threadpoolctl import threadpool_limits

from hysbench.data.dataset import shared_datasets_root

# One BLAS thread per test process: the suite runs in two processes on two cores (-n 2), and BLAS threads
# that wait for a busy core spin, so a small QR takes ten times as long as on one thread.
threadpool_limits(1, user_api="blas")

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


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """A test that uses a module-scoped fixture runs in the worker of the other tests of its module that use
    one (per value of a parametrised one), so each such fixture is computed once (pyproject: --dist
    loadgroup, which reads this group). A test already given a group keeps it."""
    for item in items:
        if item.get_closest_marker("xdist_group"):
            continue
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        params = getattr(getattr(item, "callspec", None), "params", {})
        shared = [name for name in item.fixturenames
                  if (defs := info.name2fixturedefs.get(name)) and defs[-1].scope == "module"]
        if shared:
            values = ",".join(f"{n}={params[n]}" for n in sorted(shared) if n in params)
            item.add_marker(pytest.mark.xdist_group(f"{item.module.__name__}[{values}]"))
