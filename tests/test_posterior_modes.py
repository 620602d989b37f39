"""Separated posterior modes: the start finds each, and the walkers start in every one.

A toy target (a mixture of two Gaussians, or one Gaussian with a ripple) stands in for the log
posterior where a property is checked against a dense reference; the virtual DEA, whose MRPIM
posterior has two modes (gamma near +0.07 and near -0.1), is the real case.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from hysbench.data.dataset import load_dataset
from hysbench.identification.posterior import (LogPosterior, find_modes, mode_search_starts, nearest_mode,
                                               noise_estimate, screen_candidates, separated, walkers_in_modes)
from hysbench.identification.posterior.modes import MODE_GAP, VALLEY_DEPTH
from hysbench.identification.errors import IdentificationError
from hysbench.models import get_model

ROOT = Path(__file__).resolve().parents[1]


class ToyPosterior:
    """Log density of a Gaussian mixture (or one Gaussian plus a ripple) on a 2-d box; only the
    attributes the mode search reads."""

    def __init__(self, centres, sds, weights, ripple=0.0):
        self.centres, self.sds, self.weights = np.asarray(centres, float), np.asarray(sds, float), weights
        self.ripple = ripple
        self.nonlinear_names = ("a", "b")
        self.noise = "iid"
        self.priors = SimpleNamespace(nonlinear_lower=np.array([-1.0, -1.0]), nonlinear_upper=np.array([1.0, 1.0]))
        self.ndim = 2

    def log_prob(self, X):
        X = np.atleast_2d(X)
        terms = [np.log(w) - 0.5 * np.sum(((X - c) / s) ** 2, axis=1) for c, s, w in
                 zip(self.centres, self.sds, self.weights)]
        lp = logsumexp(np.array(terms), axis=0) + self.ripple * np.sin(40 * X[:, 0]) * np.sin(40 * X[:, 1])
        inside = np.all((X >= -1) & (X <= 1), axis=1)
        return np.where(inside, lp, -np.inf)


def _dense_valley(post, a, b, n=2001):
    lp = post.log_prob(a[None] + np.linspace(0, 1, n)[:, None] * (b - a)[None])
    return min(lp[0], lp[-1]) - np.min(lp)


def test_two_separated_modes_are_both_found_best_first():
    post = ToyPosterior([[0.5, -0.4], [-0.6, 0.5]], [[0.05, 0.08], [0.03, 0.04]], [0.3, 0.7])
    # four starts near the first mode, one near the second: the second must still be searched
    rng = np.random.default_rng(0)
    starts = np.vstack([post.centres[0] + 0.05 * rng.standard_normal((4, 2)), post.centres[1] + [0.04, -0.03]])
    modes = find_modes(post, starts)
    assert len(modes) == 2
    found = np.array([m["x"] for m in modes])
    assert np.allclose(found[0], post.centres[1], atol=1e-3)  # the higher peak first
    assert np.allclose(found[1], post.centres[0], atol=1e-3)
    assert modes[0]["log_posterior"] > modes[1]["log_posterior"]
    # the Laplace covariance of each is its Gaussian's
    assert np.allclose(np.sqrt(np.diag(modes[1]["cov"])), post.sds[0], rtol=0.05)


def test_a_rippled_single_mode_is_one_mode():
    post = ToyPosterior([[0.1, 0.2]], [[0.2, 0.2]], [1.0], ripple=1.5)  # local maxima, no deep valley
    starts = np.array([[0.1, 0.2], [0.3, 0.0], [-0.1, 0.35], [0.25, 0.4]])
    assert len(find_modes(post, starts)) == 1


def test_a_mode_far_below_the_best_is_not_sampled():
    w = np.exp(-(MODE_GAP + 3.0))
    post = ToyPosterior([[0.5, 0.5], [-0.5, -0.5]], [[0.05, 0.05], [0.05, 0.05]], [1.0 - w, w])
    modes = find_modes(post, np.array([[-0.48, -0.5], [0.52, 0.5]]))
    assert len(modes) == 1 and np.allclose(modes[0]["x"], [0.5, 0.5], atol=1e-3)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.2, 0.9), st.floats(0.02, 0.3), st.floats(0.02, 0.3))
def test_separated_agrees_with_a_dense_valley_away_from_the_threshold(gap, sd1, sd2):
    post = ToyPosterior([[-gap / 2, 0.0], [gap / 2, 0.1]], [[sd1, sd1], [sd2, sd2]], [0.5, 0.5])
    a, b = post.centres
    depth = _dense_valley(post, a, b)
    if abs(depth - VALLEY_DEPTH) < 3.0:  # the 9-point check may miss a narrow dip near the threshold
        return
    assert separated(post, a, b) == (depth > VALLEY_DEPTH)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 4), st.integers(1, 30), st.integers(0, 10_000))
def test_nearest_mode_matches_a_loop(k, n, seed):
    rng = np.random.default_rng(seed)
    post = ToyPosterior([[0, 0]], [[1, 1]], [1.0])
    post.priors.nonlinear_upper = np.array([1.0, 3.0])  # widths 2 and 4: distances are relative to them
    modes, X = rng.uniform(-1, 1, (k, 2)), rng.uniform(-1, 1, (n, 2))
    w = post.priors.nonlinear_upper - post.priors.nonlinear_lower
    expected = [int(np.argmin([np.sum(((x - m) / w) ** 2) for m in modes])) if k > 1 else 0 for x in X]
    assert list(nearest_mode(post, X, modes)) == expected


def test_walkers_are_split_evenly_between_the_modes():
    post = ToyPosterior([[0.5, -0.4], [-0.6, 0.5], [0.0, 0.9]], [[0.05, 0.05]] * 3, [0.3, 0.3, 0.4])
    post.in_support = lambda X: np.all(np.abs(X) <= 1, axis=1)
    modes = [{"x": c, "cov": np.diag([0.05**2, 0.05**2])} for c in post.centres]
    p0 = walkers_in_modes(post, modes, 16, np.random.default_rng(1))
    assert p0.shape == (16, 2) and [m["walkers"] for m in modes] == [6, 5, 5]
    assert list(np.bincount(nearest_mode(post, p0, post.centres))) == [6, 5, 5]


def test_the_virtual_dea_posterior_has_two_modes_and_every_seed_finds_both():
    """MRPIM on the shipped virtual DEA has two separated modes (gamma > 0 and gamma < 0): the mode search
    finds both from each sampler seed tried, so no chain starts in one mode only."""
    ds = load_dataset(ROOT / "data" / "virtual_dea")
    post = LogPosterior(get_model("mrpim"), ds.identification, noise="ar1", seed=0)
    nl0 = np.array([0.0, 0.0])
    sigma0, phi0 = noise_estimate(post, nl0)
    for seed in (0, 1):
        modes = find_modes(post, mode_search_starts(post, screen_candidates(post, nl0, sigma0, phi0, seed)))
        gammas = sorted(m["x"][0] for m in modes)
        assert len(modes) == 2 and gammas[0] < -0.05 and gammas[1] > 0.03, gammas
        assert abs(modes[0]["log_posterior"] - modes[1]["log_posterior"]) < 5
        assert separated(post, modes[0]["x"], modes[1]["x"])


def test_mode_jumps_give_each_mode_its_mass():
    """Walkers started evenly in two modes of unequal mass: with the jump move the chain's shares come
    to the modes' masses (w s_1 s_2 for this unnormalised mixture); the move keeps detailed balance."""
    import emcee

    from hysbench.identification.posterior import with_mode_jumps

    post = ToyPosterior([[0.5, -0.4], [-0.6, 0.5]], [[0.05, 0.08], [0.03, 0.04]], [0.5, 0.5])
    post.in_support = lambda X: np.all(np.abs(X) <= 1, axis=1)
    mass = np.array([0.5 * 0.05 * 0.08, 0.5 * 0.03 * 0.04])
    modes = [{"x": c, "cov": np.diag(s**2)} for c, s in zip(post.centres, post.sds)]
    p0 = walkers_in_modes(post, modes, 16, np.random.default_rng(2))
    moves = with_mode_jumps([(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)], post, post.centres)
    sampler = emcee.EnsembleSampler(16, 2, post.log_prob, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(3).get_state()
    sampler.run_mcmc(p0, 3000, progress=False)
    kept = sampler.get_chain(discard=500, flat=True)
    share = np.bincount(nearest_mode(post, kept, post.centres), minlength=2) / len(kept)
    assert abs(share[0] - mass[0] / mass.sum()) < 0.05, share
    # all walkers started in one mode: DE alone never leaves it, the jumps still reach the masses
    one = walkers_in_modes(post, modes[:1], 16, np.random.default_rng(4))
    for use, expected in ((moves, mass[0] / mass.sum()), (moves[:2], 1.0)):
        sampler = emcee.EnsembleSampler(16, 2, post.log_prob, vectorize=True, moves=use)
        sampler.random_state = np.random.RandomState(5).get_state()
        sampler.run_mcmc(one, 3000, progress=False)
        kept = sampler.get_chain(discard=500, flat=True)
        share = np.bincount(nearest_mode(post, kept, post.centres), minlength=2) / len(kept)
        assert abs(share[0] - expected) < 0.05, (len(use), share)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 3), st.integers(1, 12), st.integers(0, 10_000))
def test_draws_are_scaled_about_their_own_modes_median(k, n, seed):
    from hysbench.identification.posterior.predictive import scale_about_mode_medians

    rng = np.random.default_rng(seed)
    Y, mode, scales = rng.normal(size=(n, 5)), rng.integers(0, k, n), rng.uniform(0.1, 3, k)
    out = scale_about_mode_medians(Y, mode, scales)
    for i in range(n):  # reference: one draw at a time
        same = Y[mode == mode[i]]
        centre = np.array([sorted(same[:, t])[len(same) // 2] if len(same) % 2 else
                           0.5 * (sorted(same[:, t])[len(same) // 2 - 1] + sorted(same[:, t])[len(same) // 2])
                           for t in range(5)])
        assert np.allclose(out[i], centre + scales[mode[i]] * (Y[i] - centre))


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 3), st.integers(5, 40), st.integers(0, 10_000))
def test_multiplier_for_coverage_against_direct_bands(k, n, seed):
    """The per-sample needed multipliers reproduce the coverage of bands rebuilt at any multiplier, and
    the multiplier reported for 80 / 90 / 97 % is the smallest that reaches it."""
    from hysbench.identification.posterior.predictive import (multiplier_for_coverage, needed_multipliers,
                                                              scale_about_mode_medians)

    rng = np.random.default_rng(seed)
    T = 60
    mode = np.sort(rng.integers(0, k, n))
    Y = rng.normal(size=(n, T)) + 0.5 * mode[:, None]
    y = rng.normal(0.2, 1.5, T)
    scales = rng.uniform(0.5, 2, k)

    def direct(M):  # the band rebuilt from scratch at multiplier M
        lo, hi = np.quantile(scale_about_mode_medians(Y, mode, M * scales), [0.05, 0.95], axis=0)
        return np.mean((y >= lo) & (y <= hi))

    m = needed_multipliers(y, Y, mode, scales)
    for M in (0.3, 0.9, 1.0, 1.7, 4.0):
        assert abs(np.mean(m <= M) - direct(M)) <= 1.5 / T, (M, np.mean(m <= M), direct(M))
    for key, M in multiplier_for_coverage(m).items():
        if M is None:
            assert direct(100.0) < int(key) / 100
        elif M > 1.01e-2:
            assert direct(M * (1 + 1e-4)) >= int(key) / 100 - 1.5 / T
            assert direct(M * (1 - 1e-3)) < int(key) / 100 + 1e-12


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 50), st.integers(1, 3), st.integers(0, 10_000))
def test_bound_shares_match_a_loop(n, d, seed):
    from hysbench.identification.posterior.run import BOUND_BAND, bound_shares

    rng = np.random.default_rng(seed)
    lo, hi = rng.uniform(-2, 0, d), rng.uniform(0.1, 2, d)
    X = lo + (hi - lo) * rng.choice([0.0, 0.005, 0.5, 0.995, 1.0, 0.02], size=(n, d))
    got = bound_shares(X, lo, hi)
    for c in range(d):
        w = BOUND_BAND * (hi[c] - lo[c])
        assert got[c, 0] == sum(1 for v in X[:, c] if v <= lo[c] + w) / n
        assert got[c, 1] == sum(1 for v in X[:, c] if v >= hi[c] - w) / n


def test_the_report_names_a_parameter_at_its_prior_bound():
    from hysbench.benchmarks.reports.posterior import bound_line

    line = bound_line({"at_prior_bound": {"gamma": {"bound": "lower", "value": -0.1, "share": 0.4}}})
    assert "gamma: 40 %" not in line and "gamma: 40% of the kept states" in line and "lower bound -0.1" in line
    assert "no nonlinear parameter" in bound_line({"at_prior_bound": {}})


@pytest.mark.parametrize("shapes", ["none", "true", "wrong"])
def test_moves_within_modes_sample_each_mode_and_the_masses(shapes):
    """DE and snooker drawing helpers from the walker's own mode (``WithinModes``), with the mode jumps:
    the kept states reproduce each mode's mean, spread and mass of a two-Gaussian mixture (unequal
    masses and shapes, a mode with too few walkers at times: the fallback to every helper). The jumps
    plain shifts, mapped by the true shapes, or by wrong centres and covariances (a pilot's noisy
    estimate): any fixed map keeps detailed balance, so only the speed may differ."""
    import emcee

    from hysbench.identification.posterior import with_mode_jumps
    from hysbench.identification.posterior.modes import WithinModes

    post = ToyPosterior([[0.5, -0.4], [-0.6, 0.5]], [[0.05, 0.08], [0.03, 0.04]], [0.8, 0.2])
    post.in_support = lambda X: np.all(np.abs(X) <= 1, axis=1)
    mass = np.array([0.8 * 0.05 * 0.08, 0.2 * 0.03 * 0.04])
    modes = [{"x": c, "cov": np.diag(s**2)} for c, s in zip(post.centres, post.sds)]
    p0 = walkers_in_modes(post, modes, 16, np.random.default_rng(7))
    covs, centres = None, None
    if shapes == "true":
        covs = [np.diag(s**2) for s in post.sds]
    elif shapes == "wrong":
        covs = [np.array([[4.0, 1.0], [1.0, 1.0]]) * s[0] ** 2 for s in post.sds]
        centres = post.centres + 0.5 * post.sds
    moves = with_mode_jumps([(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)], post, post.centres,
                            covs, centres)
    assert all(isinstance(m, WithinModes) for m, _ in moves[:2])
    sampler = emcee.EnsembleSampler(16, 2, post.log_prob, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(8).get_state()
    sampler.run_mcmc(p0, 6000, progress=False)
    kept = sampler.get_chain(discard=500, flat=True)
    which = nearest_mode(post, kept, post.centres)
    share = np.bincount(which, minlength=2) / len(kept)
    assert abs(share[0] - mass[0] / mass.sum()) < 0.04, share
    for k in range(2):
        x = kept[which == k]
        assert np.all(np.abs(x.mean(axis=0) - post.centres[k]) < 0.15 * post.sds[k]), (k, x.mean(axis=0))
        assert np.all(np.abs(x.std(axis=0) / post.sds[k] - 1) < 0.1), (k, x.std(axis=0))


def test_no_finite_start_is_refused_with_the_counts_that_say_why():
    post = ToyPosterior([[0.0, 0.0]], [[0.1, 0.1]], [1.0])
    post.log_prob = lambda X: np.full(np.atleast_2d(X).shape[0], -np.inf)
    post.n_evaluations, post.n_singular, post.n_nonfinite = 7, 5, 2
    with pytest.raises(IdentificationError, match="of 7 parameter sets evaluated, 5 had a linear part whose "
                                                   "precision is not positive definite.* and 2 a non-finite"):
        find_modes(post, np.array([[0.1, 0.1], [-0.2, 0.3]]))
