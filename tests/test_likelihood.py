"""The AR(1) likelihood, the prewhitened Gram kernel and the exact marginalisation of the linear
parameters (identification/likelihood.py), against slow obvious references: dense multivariate
normals with the AR(1) Toeplitz covariance, NumPy Gram matrices, brute-force numerical integration."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import toeplitz
from scipy.stats import multivariate_normal

from hysbench.identification.likelihood import (_whitened_gram_parallel, _whitened_gram_serial, ar1_loglik,
                                                marginalise_linear, nonfinite_sets, prais_winsten,
                                                whitened_gram)


def dense_logpdf(r, cov):
    """log N(r; 0, cov) by a Cholesky factor (scipy refuses cov this ill-conditioned)."""
    L = np.linalg.cholesky(cov)
    w = np.linalg.solve(L, r)
    return float(-0.5 * (r.size * math.log(2 * math.pi) + w @ w) - np.sum(np.log(np.diag(L))))


def ar1_cov(n, sigma, phi):
    """The stationary AR(1) covariance, written out."""
    return sigma**2 / (1 - phi**2) * toeplitz(phi ** np.arange(n))


# --- AR(1) likelihood ----------------------------------------------------------------
@settings(max_examples=25)
@given(phi=st.floats(-0.95, 0.99), sigma=st.floats(0.01, 3.0), lengths=st.lists(st.integers(1, 40), min_size=1,
                                                                                   max_size=3),
       seed=st.integers(0, 10_000))
def test_ar1_loglik_equals_dense_gaussian(phi, sigma, lengths, seed):
    rng = np.random.default_rng(seed)
    segs = [rng.normal(0, 1, n) for n in lengths]
    dense = sum(multivariate_normal(np.zeros(n), ar1_cov(n, sigma, phi)).logpdf(e) if n > 1
                else multivariate_normal(0.0, sigma**2 / (1 - phi**2)).logpdf(e[0]) for n, e in zip(lengths, segs))
    assert ar1_loglik(segs, sigma, phi) == pytest.approx(dense, rel=1e-9, abs=1e-8)


def test_ar1_loglik_outside_support_and_whitening():
    assert ar1_loglik([np.ones(3)], 1.0, 1.0) == -math.inf
    assert ar1_loglik([np.ones(3)], 0.0, 0.5) == -math.inf
    # the transform whitens: T Sigma T' = sigma^2 I
    n, sigma, phi = 6, 0.7, 0.8
    T = prais_winsten(np.eye(n), phi).T  # row i of the result is T e_i
    np.testing.assert_allclose(T @ ar1_cov(n, sigma, phi) @ T.T, sigma**2 * np.eye(n), atol=1e-12)


@pytest.mark.parametrize("kernel", [_whitened_gram_serial, _whitened_gram_parallel])
def test_whitened_gram_equals_numpy(kernel):
    rng = np.random.default_rng(3)
    for m, k, n in ((1, 0, 1), (3, 0, 7), (2, 3, 7), (6, 0, 300), (19, 4, 1000)):
        X = rng.normal(size=(3, m, n))
        S = rng.normal(size=(k, n))
        y = rng.normal(size=n)
        phis = np.array([0.0, 0.9, -0.4])
        out = np.zeros((3, m + k + 1, m + k + 1))
        kernel(X, S, y, phis, out)
        for b in range(3):
            Z = prais_winsten(np.vstack([X[b], S, y]), phis[b])
            np.testing.assert_allclose(out[b], Z @ Z.T, rtol=1e-11, atol=1e-9)
    # accumulates over calls (records add up)
    again = whitened_gram(X, y, phis, out.copy(), shared=S)
    np.testing.assert_allclose(again, 2 * out, rtol=1e-12)


@pytest.mark.parametrize("bad_value", [np.nan, np.inf, -np.inf])
def test_a_nonfinite_regressor_marks_its_set(bad_value):
    rng = np.random.default_rng(4)
    X = rng.normal(size=(4, 5, 600))
    X[1, 3, 417] = bad_value
    X[3, 0, 0] = bad_value  # the first sample, scaled by sqrt(1 - phi^2)
    G = whitened_gram(X, rng.normal(size=600), np.array([0.5, 0.99, 0.0, 0.9]), shared=rng.normal(size=(2, 600)))
    assert nonfinite_sets(G).tolist() == [False, True, False, True]


# --- the linear parameters, integrated out ---------------------------------------------
def _tiny_problem(seed=0):
    rng = np.random.default_rng(seed)
    n1, n2 = 20, 12
    X = [np.column_stack([np.ones(n), np.linspace(-1, 1, n)]) for n in (n1, n2)]
    theta = np.array([0.3, -1.2])
    phi, sigma = 0.6, 0.4
    y = [x @ theta + rng.multivariate_normal(np.zeros(len(x)), ar1_cov(len(x), sigma, phi)) for x in X]
    return X, y, phi, sigma


def _marginal(X, y, phi, sigma, mean, precision):
    G = np.zeros((1, 3, 3))
    for x, yy in zip(X, y):
        whitened_gram(x.T[None], yy, np.array([phi]), G)
    n = sum(len(v) for v in y)
    return marginalise_linear(G, np.array([sigma]), n, np.array([len(X) * 0.5 * math.log1p(-phi**2)]), mean,
                              precision)


@pytest.mark.parametrize("prior", ["normal", "flat"])
def test_marginalisation_equals_brute_force_integration(prior):
    X, y, phi, sigma = _tiny_problem()
    mean0, sd0 = np.array([0.5, -0.5]), np.array([1.5, 2.0])
    precision = 1 / sd0**2 if prior == "normal" else None
    marg = _marginal(X, y, phi, sigma, mean0, precision)
    # brute force: integrate likelihood x prior over a fine grid in (theta0, theta1)
    mu, cov = marg.mean[0], marg.covariance(0)
    sd = np.sqrt(np.diag(cov))
    g0 = np.linspace(mu[0] - 9 * sd[0], mu[0] + 9 * sd[0], 301)
    g1 = np.linspace(mu[1] - 9 * sd[1], mu[1] + 9 * sd[1], 301)
    T0, T1 = np.meshgrid(g0, g1, indexing="ij")
    thetas = np.column_stack([T0.ravel(), T1.ravel()])
    logf = sum(multivariate_normal(np.zeros(len(yy)), ar1_cov(len(yy), sigma, phi)).logpdf(yy - thetas @ x.T)
               for x, yy in zip(X, y))
    if prior == "normal":
        logf = logf + multivariate_normal(mean0, np.diag(sd0**2)).logpdf(thetas)
    logf = logf.reshape(T0.shape)
    top = logf.max()
    w = np.exp(logf - top)
    dA = (g0[1] - g0[0]) * (g1[1] - g1[0])
    Z = w.sum() * dA
    assert marg.loglik[0] == pytest.approx(top + math.log(Z), abs=1e-6)
    m_num = np.array([(w * T0).sum(), (w * T1).sum()]) * dA / Z
    c01 = (w * (T0 - m_num[0]) * (T1 - m_num[1])).sum() * dA / Z
    v0 = (w * (T0 - m_num[0]) ** 2).sum() * dA / Z
    np.testing.assert_allclose(marg.mean[0], m_num, rtol=1e-6, atol=1e-8)
    assert cov[0, 0] == pytest.approx(v0, rel=1e-5)
    assert cov[0, 1] == pytest.approx(c01, rel=1e-5)
    # conditional draws follow N(mean, cov)
    draws = np.array([marg.draw(np.random.default_rng(k))[0] for k in range(4000)])
    np.testing.assert_allclose(draws.mean(0), mu, atol=4 * sd.max() / math.sqrt(4000))
    np.testing.assert_allclose(np.cov(draws.T), cov, rtol=0.1, atol=0.1 * np.abs(cov).max())


