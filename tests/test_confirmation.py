"""The validation records' confirmation: a gain counts only beyond the records' own noise.

``residuals.noise_floor`` against a slow per-bin median, and ``residuals.gain_z`` against Monte Carlo draws of
noise made here with ``scipy.signal.lfilter`` (AR(1) up to phi = 0.99, and a line the floor must not count), not
with the code under test.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal, stats

from hysbench.benchmarks.diagnosis import validation
from hysbench.benchmarks.diagnosis.extensions import gain
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.residuals import FLOOR_HALF_WIDTH, gain_z, noise_floor
from diagnosed_cases import diagnosed


def _floor_by_hand(x: np.ndarray) -> np.ndarray:
    x = x - x.mean()
    p = np.abs(np.fft.rfft(x)) ** 2 / x.size
    p[0] = p[1]
    out = []
    for k in range(p.size):
        h = min(FLOOR_HALF_WIDTH, max(2, k // 2))
        out.append(np.median(p[max(1, k - h):k + h + 1]))
    return np.array(out) / math.log(2.0)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(4, 400), seed=st.integers(0, 2**31 - 1))
def test_noise_floor_is_the_running_median_of_the_periodogram(n, seed):
    x = np.random.default_rng(seed).normal(size=n)
    np.testing.assert_allclose(noise_floor(x), _floor_by_hand(x), rtol=1e-12, atol=1e-15)


def _ar1(rng, n, phi, sd):
    e = signal.lfilter([1.0], [1.0, -phi], rng.normal(size=n + 500))[500:]
    return sd * e / np.std(e)


def test_noise_floor_ignores_a_line_and_follows_a_coloured_spectrum():
    rng = np.random.default_rng(3)
    n, dt = 8000, 1e-3
    t = np.arange(n) * dt
    white = rng.normal(0.0, 0.01, n)
    floor = noise_floor(white + 0.05 * np.sin(2 * np.pi * 50.0 * t))
    assert floor[400] < 3 * 0.01**2  # the 50 Hz bin holds a line of periodogram power 5: not noise
    assert np.mean(floor[200:600]) == pytest.approx(0.01**2, rel=0.15)
    red = _ar1(rng, n, 0.95, 0.01)
    f = noise_floor(red)
    assert f[5] > 20 * f[2000]  # low frequencies hold most of an AR(1)'s power


@pytest.mark.parametrize("phi", [0.0, 0.9, 0.99])
def test_gain_z_is_standard_normal_when_the_change_is_unrelated_to_the_noise(phi):
    """r_b = e + d/2, r_a = e - d/2 with a fixed slow change d well below the noise: the sums of squares differ
    by 2 sum(d e), mean 0, so z must be about N(0, 1) (a white-noise variance sum(d^2) sd^2 would give sd(z)
    of 3-10 at phi 0.9-0.99). And as a change unrelated to the records is used (r_b = e, r_a = e - 100 d), it is
    confirmed in at most 5 % of draws: it costs sum(d^2), and its own power raises the floor."""
    rng = np.random.default_rng(11)
    n = 5000
    t = np.arange(n) * 2e-3
    d = 0.00004 * np.sin(2 * np.pi * 0.2 * t) + 0.00002 * (1.0 - np.exp(-t / 2.0))
    noise = [_ar1(rng, n, phi, 0.01) for _ in range(300)]
    z = np.array([gain_z([(e + d / 2, e - d / 2)]) for e in noise])
    assert abs(np.mean(z)) < 0.2
    assert 0.8 < np.std(z) < 1.2, np.std(z)
    z_null = np.array([gain_z([(e, e - 100 * d)]) for e in noise])
    assert np.mean(z_null >= stats.norm.isf(0.05)) <= 0.05


def test_gain_z_finds_a_change_the_records_carry():
    """The records hold d and the change removes it: d of a fifth of the power of AR(1) noise (phi 0.9, most of
    its power at d's low frequencies) is found across two records, while the same change on records without it
    is not confirmed."""
    rng = np.random.default_rng(5)
    n = 5000
    t = np.arange(n) * 2e-3
    d = 0.008 * np.sin(2 * np.pi * 1.0 * t) ** 3
    es = [_ar1(rng, n, 0.9, 0.01) for _ in range(2)]
    assert gain_z([(e + d, e) for e in es]) > 3.0
    assert gain_z([(e, e - d) for e in es]) < -3.0


def test_a_relaxation_found_in_coloured_noise_is_not_confirmed():
    """AR(1) noise (phi 0.91) on MRPIM sines: a 1.8 s relaxation removes 4 % of the held-out misfit and about
    1 % of the validation records' residual, which is z of about 1 against the records' own noise: not
    confirmed, and the report says why. The relaxation candidate is checked on the validation records whatever
    the verdict, so the test checks the confirmation even when nothing is named. (The diagnosis is shared with
    the other tests of this case, so the base refitted here on whole records is computed on a copy.)"""
    d, _ = diagnosed(("null-ar1",), "mrpim", "sines", 3500082)
    d = copy.copy(d)
    relaxation = next(c for c in d.candidates if c.cause == "relaxation")
    if not d.base_whole:
        validation.refit_base_whole(d, lambda s: None)
    _, after, _ = validation.fit_extension(d, relaxation, lambda s: None)
    v = gain(d.base_whole, after, "validation")
    assert v["explained_whole"] > 0 and v["z_whole"] < Policy().z_confirm
    assert not validation.borne_out(v, "relaxation", {}, Policy())
    assert d.confirmed is not True
    if d.cause != "none":
        assert d.confirmed is False and d.warning
