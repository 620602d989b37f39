"""pytest-benchmark suite (not run by CI): `python -m pytest benchmarks/speed --benchmark-only`."""

import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    # pyproject's addopts set the tests' xdist scheduling (--dist loadgroup); without -n no worker runs, but
    # pytest-benchmark reads any --dist other than "no" as xdist being active and turns itself off
    if not getattr(config.option, "numprocesses", None) and getattr(config.option, "dist", "no") != "no":
        config.option.dist = "no"
