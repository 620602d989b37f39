"""Information criteria and the AR(1) effective sample size (hysbench.identification.criteria), against
slow, obvious references."""

import math

import numpy as np
import pytest

from hysbench.identification.criteria import (aic, ar1_information_ratio, bic, effective_sample_size,
                                               lag1_autocorrelation, minus_two_log_likelihood)


def _lag1_reference(e):
    e = [float(v) for v in e]
    m = sum(e) / len(e)
    d = [v - m for v in e]
    return sum(d[k] * d[k - 1] for k in range(1, len(d))) / sum(v * v for v in d)


@pytest.mark.parametrize("seed", [0, 1])
def test_lag1_autocorrelation_is_the_mean_removed_lag_one_sum(seed):
    rng = np.random.default_rng(seed)
    e = 3.0 + np.cumsum(rng.normal(size=50)) * 0.1 + rng.normal(size=50)  # an offset and some correlation
    assert lag1_autocorrelation(e) == pytest.approx(_lag1_reference(e), rel=1e-12)
    assert lag1_autocorrelation(np.full(10, 2.0)) == 0.0


def test_the_information_ratio_clips_negative_correlation_to_independent_samples():
    assert ar1_information_ratio(-0.5) == 1.0
    assert ar1_information_ratio(0.5) == pytest.approx(1 / 3)
    assert ar1_information_ratio(1.0) == pytest.approx(0.000001 / 1.999999)


def test_effective_sample_size_sums_each_blocks_ar1_share():
    rng = np.random.default_rng(2)
    blocks = [rng.normal(size=40), np.cumsum(rng.normal(size=60))]
    want = sum(b.size * (1 - min(max(_lag1_reference(b), 0.0), 0.999999)) / (1 + min(max(_lag1_reference(b), 0.0),
                                                                                         0.999999)) for b in blocks)
    assert effective_sample_size(blocks) == pytest.approx(want, rel=1e-12)
    alternating = np.tile([1.0, -1.0], 20)  # lag-1 correlation near -1: counted as independent samples
    assert effective_sample_size([alternating]) == 40.0


def test_criteria_with_an_effective_sample_size_scale_the_likelihood_and_penalise_by_its_log():
    rss, n, k, n_eff = 2.5, 200, 5, 37.0
    m2ll = n * math.log(2 * math.pi * rss / n) + n
    assert minus_two_log_likelihood(rss, n) == pytest.approx(m2ll, rel=1e-14)
    assert aic(rss, n, k, n_eff) == pytest.approx(n_eff / n * m2ll + 2 * k, rel=1e-14)
    assert bic(rss, n, k, n_eff) == pytest.approx(n_eff / n * m2ll + k * math.log(n_eff), rel=1e-14)
    assert bic(rss, n, k, 0.5) == pytest.approx(0.5 / n * m2ll, rel=1e-14)  # ln of at least one sample
