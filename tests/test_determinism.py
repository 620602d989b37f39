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
