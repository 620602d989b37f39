"""The suite gives the same answer twice: the hypothesis profile of conftest.py is the one in force in
this process (the main one, or a pytest-xdist worker), and in every @settings a test module builds."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

import test_baselines


def test_the_ci_profile_is_loaded_in_this_process():
    current = settings.default
    assert settings.get_current_profile_name() == "hysbench"
    assert current.derandomize and current.database is None and current.deadline is None
    assert HealthCheck.too_slow in current.suppress_health_check  # no outcome that depends on the machine's load


def test_a_test_modules_own_settings_inherit_the_profile():
    own = test_baselines.test_rate_independent_models_depend_on_the_path_only._hypothesis_internal_use_settings
    assert own.max_examples == 15  # its own value
    assert own.derandomize and own.database is None and HealthCheck.too_slow in own.suppress_health_check


def test_a_tests_examples_do_not_depend_on_the_modules_loaded_before_it(tmp_path, monkeypatch):
    """Hypothesis may draw literals of the local modules loaded in the process; a module loaded later (another
    test's import) must not change the examples a test is given."""
    import importlib
    import sys

    from hypothesis import given, strategies as st

    def examples():
        drawn = []

        @settings(max_examples=30)
        @given(st.floats(-3, 3), st.integers(-1000, 1000))
        def record(x, i):
            drawn.append((x, i))

        record()
        return drawn

    before = examples()
    (tmp_path / "hysbench_literals_probe.py").write_text(
        "VALUES = (0.123456789, 1.2345e-7, 2.5e-3, 987, -654, 0.777)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("hysbench_literals_probe")
    try:
        assert examples() == before
    finally:
        sys.modules.pop("hysbench_literals_probe", None)
