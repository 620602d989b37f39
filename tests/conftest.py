"""Shared test fixtures, the hypothesis profile every test process runs under, and the order in which the
test processes take their work."""

import json
from collections import defaultdict
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


def _no_local_constants():
    """Hypothesis (6.131 and later) mixes into its examples the literals of every local module loaded in
    the process, so a test's examples would depend on which other tests and lazy imports ran before it in its
    worker. Without them a test's examples derive from its source alone."""
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:
        return
    if hasattr(providers, "_get_local_constants") and hasattr(providers, "Constants"):
        empty = providers.Constants()
        providers._get_local_constants = lambda: empty


_no_local_constants()


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


# Measured seconds per test (setup, call and teardown), written by `pytest -n 2 --store-durations`.
DURATIONS = Path(__file__).with_name("durations.json")


def pytest_addoption(parser):
    parser.addoption("--store-durations", action="store_true",
                     help=f"write each test's measured seconds to {DURATIONS.name} (orders the next runs' work)")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """A test that uses a module-scoped fixture runs in the worker of the other tests of its module that use
    one (per value of a parametrised one), so each such fixture is computed once (pyproject: --dist
    loadgroup, which reads this group). A test already given a group keeps it. Then the work units
    (a group, or a test of none) are ordered longest first by their measured durations, so that no
    process is left with a long unit while the other has finished (pyproject: --no-loadscope-reorder
    keeps this order); units never measured keep their collection order, after the measured ones."""
    _group_by_shared_fixture(items)
    seconds = json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}
    unit_of = {item.nodeid: _unit(item) for item in items}
    total = defaultdict(float)
    for item in items:
        total[unit_of[item.nodeid]] += seconds.get(item.nodeid, 0.0)
    first = {}
    for i, item in enumerate(items):
        first.setdefault(unit_of[item.nodeid], i)
    items.sort(key=lambda item: (-total[unit_of[item.nodeid]], first[unit_of[item.nodeid]]))


def _unit(item) -> str:
    marker = item.get_closest_marker("xdist_group")
    return f"@{marker.args[0] if marker.args else marker.kwargs.get('name')}" if marker else item.nodeid


def _group_by_shared_fixture(items):
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


_measured = defaultdict(float)


def pytest_runtest_logreport(report):
    # in the controlling process under xdist; a grouped test's id there ends in "@group"
    _measured[report.nodeid.rsplit("@", 1)[0] if "@" in report.nodeid else report.nodeid] += report.duration


def pytest_sessionfinish(session, exitstatus):
    if session.config.getoption("--store-durations") and not hasattr(session.config, "workerinput"):
        seconds = json.loads(DURATIONS.read_text()) if DURATIONS.is_file() else {}
        seconds.update({k: round(v, 1) for k, v in _measured.items()})  # tests not run keep their figure
        DURATIONS.write_text(json.dumps({k: v for k, v in sorted(seconds.items()) if v >= 0.5}, indent=0) + "\n")
