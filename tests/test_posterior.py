"""The posterior: AR(1) likelihood, exact marginalisation of the linear
parameters (the likelihood itself: test_likelihood.py), the periodic shortcut, convergence checks,
calibration, the CLI.

Slow obvious references live here: dense multivariate normals with the AR(1)
Toeplitz covariance, brute-force numerical integration over the linear
parameters, NumPy Gram matrices, the base ``regressors`` interface.

Calibration check, reduced to stay within CI's budget (same property checked;
the full study is in benchmarks/speed/bench_posterior.py): MRPIM with 4
operators and a quadratic polynomial (10 parameters instead of 21), the four
identification frequencies at a 20 ms step (instead of 1 ms) over two periods,
16 walkers run until the chain is >= 50 tau long with >= 300 effective samples
(instead of 1000). Its truth is that reduced model's varpro fit to Table 2's
noise-free output at a 10 ms step (rounded).
"""

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import block_diag

from hysbench.benchmarks.cli import main as cli_main
from hysbench.data.dataset import Dataset, Record, save_dataset
from hysbench.data.protocol import IDENTIFICATION_WEIGHTS
from hysbench.identification.errors import IdentificationError
from hysbench.data.periodic import periodic_proxy, trim_history
from hysbench.identification.posterior import (Calibration, calibrate_scale, LogPosterior, autocorr_times, build_segments,
                                               convergence, predictive, sample_posterior, simulated_ar1_dataset)
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel, Parameter
from misspecified_data import planted_relaxation_dataset, virtual_dea_dataset
from test_likelihood import ar1_cov, dense_logpdf

SMALL = dict(n_operators=4, poly_order=2)
TRUTH = {"gamma": 0.0305, "lambda": -0.0317, "p1": 3.255, "p2": 0.9785, "q": 0.0251, "a1": -4.6812,
         "a2": 0.8303, "a3": 0.2917, "a4": 2.4706, "offset": 0.4419}
SIGMA, PHI = 0.02, 0.9  # innovation sd (mm) and AR(1) coefficient per sample


def test_log_posterior_equals_dense_marginal_likelihood():
    """LogPosterior (windowed regressors, discrepancy columns, Gram kernel, marginalisation) against
    y ~ N(Phi m0, Sigma_AR1 + Phi S^-1 Phi') built from the base ``regressors`` and a loop for the
    input relaxations."""
    model = get_model("mrpim", **SMALL)
    ds = simulated_ar1_dataset(model, TRUTH, sigma=SIGMA, phi=PHI, seed=5, n_periods=2, dt=0.05,
                               frequencies=(0.4, 1.0))
    post = LogPosterior(model, ds.identification, noise="ar1")
    for nl, sigma, phi in (([0.03, -0.03], 0.03, 0.85), ([-0.02, 0.05], 0.1, -0.3), ([0.0, 0.0], 0.05, 0.0)):
        x = post.coords(nl, sigma, phi)
        lp = post.log_prob(x[None])[0] - post.log_prior(x[None])[0]
        Phi_all = np.vstack([np.column_stack([model.regressors(r.u, r.dt, dict(zip(post.nonlinear_names, nl)),
                                                               post.input_range)]
                                             + [_relaxation(r.u, r.dt, tau) - r.u for tau in post.taus])[r.scored]
                             for r in ds.identification])
        Sig = block_diag(*[ar1_cov(r.n_scored, sigma, phi) for r in ds.identification])
        cov = Sig + Phi_all @ np.diag(post.priors.linear_sd**2) @ Phi_all.T
        y_all = np.concatenate([r.y[r.scored] for r in ds.identification])
        joint = dense_logpdf(y_all - Phi_all @ post.priors.linear_mean, cov)
        assert lp == pytest.approx(joint, abs=1e-6 * max(1.0, abs(joint)))
    assert post.log_prob(post.coords([0.03, -0.03], 0.03, 1.0)[None])[0] == -math.inf
    assert post.log_prob(post.coords([5.0, -0.03], 0.03, 0.5)[None])[0] == -math.inf


def _relaxation(u, dt, tau):
    """x_k = a x_{k-1} + (1 - a) u_k, a = exp(-dt / tau), x_0 = u_0: the exact step response of
    x' = (u - x) / tau for an input held over each step."""
    a = math.exp(-dt / tau)
    x = np.empty_like(u)
    x[0] = u[0]
    for k in range(1, u.size):
        x[k] = a * x[k - 1] + (1 - a) * u[k]
    return x


# --- the periodic shortcut ------------------------------------------------------------
def _long_record(frequency=0.5, periods=10, dt=0.01):
    n = int(round(periods / (frequency * dt)))
    t = np.arange(n) * dt
    u = np.sin(2 * np.pi * frequency * t - np.pi / 2) + 1.5
    return Record(file="long.npz", t=t, u=u, y=np.zeros(n), frequency_hz=frequency)


@settings(max_examples=20)
@given(gamma=st.floats(-0.1, 0.1), lam=st.floats(-0.1, 0.1))
def test_periodic_proxy_reproduces_the_full_record(gamma, lam):
    model = get_model("mrpim")
    r = _long_record()
    u_p, w_p = periodic_proxy(r)
    assert u_p.size < r.u.size / 2
    sets = np.array([[gamma, lam]])
    full = model.windowed_regressors_batch(r.u, r.dt, sets, r.scored, (0.5, 2.5))
    short = model.windowed_regressors_batch(u_p, r.dt, sets, w_p, (0.5, 2.5))
    np.testing.assert_allclose(short, full, rtol=0, atol=1e-12)


class _Drifting(HysteresisModel):
    """A model whose state never forgets (a running integral): no periodic shortcut."""

    name = "drifting"

    def __init__(self):
        pass

    def parameters(self, scale=None):
        return (Parameter("k", 0.0, -1, 1, False), Parameter("a", 0.0, -1, 1, True))

    def regressors(self, u, dt, nonlinear, input_range=None):
        return (np.cumsum(u) * dt * (1 + nonlinear["k"]))[:, None]


def test_proxy_is_refused_when_it_changes_the_regressors():
    r = _long_record()
    assert periodic_proxy(r) is not None
    seg = build_segments(_Drifting(), [r], (0.5, 2.5), np.array([[0.1]]))[0]
    assert not seg.proxy and seg.u.size == r.u.size
    seg = build_segments(get_model("mrpim"), [r], (0.5, 2.5), np.array([[0.03, -0.03]]))[0]
    assert seg.proxy and seg.u.size < r.u.size
    # not periodic: no proxy
    r2 = _long_record()
    r2.u[5] += 0.1
    assert periodic_proxy(r2) is None


def test_trim_history_and_the_proxy_give_the_full_records_window():
    """data/periodic.py's two shapes of the shortcut (the ablation's trimmed dataset, the posterior's
    proxy) reproduce the full record's MRPIM regressors on the window; a non-periodic record is kept."""
    model = get_model("mrpim")
    r = _long_record()
    sets = np.array([[0.04, -0.02]])
    full = model.windowed_regressors_batch(r.u, r.dt, sets, r.scored, (0.5, 2.5))
    trimmed, info = trim_history(Dataset(name="x", records=[r]), periods=1)
    t = trimmed.records[0]
    assert info[0]["trimmed"] and t.u.size < r.u.size and t.stop == t.u.size
    np.testing.assert_allclose(model.windowed_regressors_batch(t.u, t.dt, sets, t.scored, (0.5, 2.5)), full,
                               rtol=0, atol=1e-12)
    r2 = _long_record()
    r2.u[5] += 0.1
    kept, info2 = trim_history(Dataset(name="y", records=[r2]))
    assert kept.records[0].u.size == r2.u.size and "not periodic" in info2[0]["reason"]


class _Blowup(_Drifting):
    """Non-finite output once k >= 0.5."""

    name = "blowup"

    def regressors(self, u, dt, nonlinear, input_range=None):
        col = np.cumsum(u) * dt * (1 + nonlinear["k"])
        return (col if nonlinear["k"] < 0.5 else np.full_like(col, np.nan))[:, None]


def test_nonfinite_model_outputs_are_counted_not_scored():
    post = LogPosterior(_Blowup(), [_long_record(periods=3)], discrepancy="none")
    X = np.array([post.coords([k], 0.1, 0.5) for k in (0.0, 0.2, 0.7, 0.9)])
    lp = post.log_prob(X)
    assert np.all(np.isfinite(lp[:2])) and np.all(lp[2:] == -np.inf)
    assert post.n_nonfinite == 2 and post.n_evaluations == 4


# --- convergence diagnostics ------------------------------------------------------------
def test_autocorrelation_time_and_convergence_flags():
    rng = np.random.default_rng(0)
    rho, n, W = 0.8, 4000, 8
    x = np.empty((n, W))
    x[0] = rng.normal(size=W)
    for t in range(1, n):
        x[t] = rho * x[t - 1] + math.sqrt(1 - rho**2) * rng.normal(size=W)
    tau = autocorr_times(x[:, :, None])[0]
    assert tau == pytest.approx((1 + rho) / (1 - rho), rel=0.15)  # 9
    long = convergence(x[:, :, None], np.zeros((n, W, 0)), np.full(W, 0.4 * n), burn=0)
    assert long.converged and long.length_in_tau > 50
    assert long.ess[0] == pytest.approx(n * W / tau)
    short = convergence(x[:300, :, None], np.zeros((300, W, 0)), np.full(W, 0.4 * 300), burn=0)
    assert not short.converged and "autocorrelation times long" in short.problems[0]
    stuck = convergence(x[:, :, None], np.zeros((n, W, 0)), np.r_[np.full(W - 1, 0.4 * n), 0.0], burn=0)
    assert not stuck.converged and "stuck" in stuck.problems[-1]


def test_a_walker_that_never_moves_gives_no_autocorrelation_time_and_no_warning():
    """emcee averages the walkers' autocorrelation functions; a walker constant over the window makes that 0/0.
    The time is NaN (not estimated, said so by the convergence check), without numpy's RuntimeWarning."""
    rng = np.random.default_rng(1)
    x = rng.normal(size=(500, 6, 1)).cumsum(axis=0)
    x[:, 2, 0] = x[0, 2, 0]  # walker 2 never moves
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tau = autocorr_times(x)
    assert np.isnan(tau[0])
    c = convergence(x, np.zeros((500, 6, 0)), np.r_[np.full(5, 200.0), 0.0], burn=0)
    assert not c.converged and any("could not be estimated" in q for q in c.problems)


# --- calibration -------------------------------------------------------------------------
# The suite's check: 6 data sets (72 pairs); the full study (20 data sets, 240 pairs, 80-97 %) is
# benchmarks/speed/bench_posterior.py. Bounds for 72 pairs at a true 90 %: the binomial's 3-sd limits,
# 0.90 -/+ 3 * sqrt(0.9 * 0.1 / 72) = 0.79 / 1.01, so only a clearly too-narrow interval fails, and the
# independent-noise likelihood (47 % in the full study) must stay clearly below 80 %.
N_DATASETS = 6
N_IID = 3


def credible_interval_coverage(n_datasets: int, n_iid: int) -> tuple[float, float, int, int]:
    """Share of (data set, parameter) pairs whose 90 % interval holds the truth, with the AR(1) likelihood on
    ``n_datasets`` simulated data sets and the independent-noise one on the first ``n_iid``; and the pair
    counts."""
    model = get_model("mrpim", **SMALL)
    truth_ar1 = dict(TRUTH, sigma=SIGMA, phi=PHI)
    hits = {"ar1": [], "iid": []}
    for k in range(n_datasets):
        ds = simulated_ar1_dataset(model, TRUTH, sigma=SIGMA, phi=PHI, seed=1000 + k, n_periods=2, dt=0.02,
                                   frequencies=tuple(IDENTIFICATION_WEIGHTS))
        for noise in ("ar1", "iid") if k < n_iid else ("ar1",):
            run = sample_posterior(model, ds, noise=noise, n_walkers=16, max_steps=3000, min_ess=300, seed=k,
                                   progress=False, discrepancy="none", calibrate=False)
            assert run.conv.converged, (k, noise, run.conv.problems)
            table = run.parameter_table()
            truth = truth_ar1 if noise == "ar1" else TRUTH  # under iid, sigma is another quantity
            hits[noise] += [table[n]["q05"] <= v <= table[n]["q95"] for n, v in truth.items()]
    return float(np.mean(hits["ar1"])), float(np.mean(hits["iid"])), len(hits["ar1"]), len(hits["iid"])


def test_credible_intervals_are_calibrated_under_ar1_noise():
    """90 % intervals hold the truth for at least 79 % of the pairs with the AR(1) likelihood; the
    independent-noise likelihood on the same data is clearly off (the check has teeth)."""
    ar1, iid, n_ar1, n_iid = credible_interval_coverage(N_DATASETS, N_IID)
    print(f"\n90 % interval coverage: AR(1) likelihood {ar1:.1%} ({n_ar1} pairs), independent-noise likelihood "
          f"{iid:.1%} ({n_iid} pairs)")
    assert ar1 >= 0.79
    assert iid < 0.80


# --- predictive calibration under misspecification -------------------------------------------
# Data the fitted model cannot reproduce, fitted by plain MRPIM (the reduced one above); judged on
# the validation records (0.05, 0.2, 0.8 Hz), which the fit never sees. Coarse CI version: 10 data
# sets per generator at a 20 ms step over 3 periods; the full one is benchmarks/speed/bench_posterior.py.
N_MISSPECIFIED = 10


@pytest.fixture(scope="module")
def misspecified_coverage(request):
    """Held-out 90 % coverage of every validation record over 10 misspecified data sets."""
    generator = request.param
    model = get_model("mrpim", **SMALL)
    cov, calibrations = [], []
    for k in range(N_MISSPECIFIED):
        ds = planted_relaxation_dataset(k, model) if generator == "planted relaxation" else virtual_dea_dataset(k)
        run = sample_posterior(model, ds, n_walkers=16, max_steps=1200, min_ess=150, seed=k, progress=False)
        cov += [r["coverage"]["90"] for r in predictive(run, ds.validation, n_draws=100, seed=k)]
        calibrations.append(run.calibration)
    cov = np.array(cov)
    print(f"\n{generator}: held-out 90 % coverage mean {cov.mean():.1%} (records: min {cov.min():.1%}, "
          f"median {np.median(cov):.1%}, max {cov.max():.1%}; {np.mean((cov >= 0.8) & (cov <= 0.97)):.0%} of "
          f"{cov.size} in 80-97 %, {np.mean(cov >= 0.5):.0%} at >= 50 %)")
    return generator, cov, calibrations


# the tests of one generator share a worker, so its fixture is computed once (pyproject: --dist loadgroup)
GENERATORS = [pytest.param(g, marks=pytest.mark.xdist_group(f"misspecified {g}"))
              for g in ("virtual DEA", "planted relaxation")]


@pytest.mark.parametrize("misspecified_coverage", GENERATORS, indirect=True)
def test_predictive_intervals_are_not_too_narrow_when_the_model_is_wrong(misspecified_coverage):
    """Mean held-out 90 % coverage >= 80 % on misspecified data, and at least 90 % of the records (27 of 30)
    covered at >= 50 %. Not the single worst record: with the same code and seeds it ranges from 29 % to 61 %
    across machines (the chains are chaotic in the last bits, which BLAS and the vector width change).
    A band that is systematically too narrow (the plain AR(1) predictive on the virtual DEA left one record
    in three at 42 %) fails both."""
    _, cov, _ = misspecified_coverage
    assert cov.mean() >= 0.80
    assert np.mean(cov >= 0.5) >= 0.9, np.sort(cov)[:5]


@pytest.mark.parametrize("misspecified_coverage", GENERATORS, indirect=True)
def test_predictive_intervals_are_not_too_wide_when_the_model_is_wrong(misspecified_coverage):
    _, cov, _ = misspecified_coverage
    assert cov.mean() <= 0.97


@pytest.mark.parametrize("misspecified_coverage", GENERATORS, indirect=True)
def test_pooled_scale_covers_the_fitted_records_at_90_and_the_end_records_set_the_outside_scale(misspecified_coverage):
    """The pooled scale is the smallest that covers the fitted records' own residuals at 90 % on average (at
    most a step of the coverage above), and the end records held out are covered at >= 90 % on average
    by the scale beyond the fitted range."""
    _, _, calibrations = misspecified_coverage
    for cal in calibrations:
        assert cal.constant is None and cal.outside is not None
        ends = [f for f in cal.folds if f["used"]]
        assert {f["frequency_hz"] for f in ends} == {min(cal.frequencies), max(cal.frequencies)}
        assert np.mean([f["coverage_90_scaled"] for f in ends]) >= 0.9
        assert all(not f["interior"] for f in ends)
        assert min(cal.in_sample) <= cal.pooled <= max(cal.in_sample)


def test_predictive_scale_is_pooled_inside_the_fitted_range_and_held_out_beyond():
    """c(f): the pooled scale inside [min f, max f] of the fitted records, max(pooled, outside) beyond it or for
    an unknown frequency, the constant when there is one."""
    cal = Calibration(0.9, frequencies=[0.02, 0.1, 0.4, 1.0], in_sample=[0.5, 1.0, 2.0, 0.8], pooled=1.1, outside=2.5)
    for f in (0.02, 0.05, 0.2, 0.8, 1.0):
        assert cal.scale_at(f) == 1.1
    for f in (0.01, 2.0, None):
        assert cal.scale_at(f) == 2.5
    assert Calibration(0.9, frequencies=[0.1, 1.0], pooled=1.1, outside=0.7).scale_at(5.0) == 1.1  # never below pooled
    assert Calibration(0.9, frequencies=[0.1, 1.0], pooled=1.1).scale_at(5.0) == 1.1  # no end fold refitted
    assert Calibration(0.9, constant=1.3).scale_at(0.2) == 1.3
    d = cal.describe()
    assert d["kind"] == "pooled" and d["pooled_in_sample_scale"] == 1.1 and d["outside_range_scale"] == 2.5
    assert d["beyond_range_scale"] == 2.5
    low = Calibration(0.9, frequencies=[0.1, 1.0], pooled=1.1, outside=0.7).describe()
    assert low["beyond_range_scale"] == 1.1 and low["outside_range_scale"] == 0.7
    assert Calibration(0.9, frequencies=[0.1, 1.0], pooled=1.1).describe()["beyond_range_scale"] is None


def test_pooled_scale_against_a_direct_search():
    """calibrate_scale's pooled scale and outside scale against a plain grid search over c on the same errors."""
    model = get_model("mrpim", **SMALL)
    ds = planted_relaxation_dataset(3, model)
    run = sample_posterior(model, ds, n_walkers=16, max_steps=200, min_ess=10, seed=3, progress=False)
    nl, sigma, phi = run.median_state()
    cal = calibrate_scale(run.post, nl, sigma, phi)
    post = run.post
    noise_var = sigma**2 / (1 - phi**2)
    rows = []
    for s in post.segments:
        X, y = post.design(s, nl[None])[0], s.y
        rows.append((X, y))

    def fit(keep):  # the Gaussian conditional of the linear parameters, written out (AR(1) prewhitened)
        prec = np.diag(post.priors.linear_precision) if np.ndim(post.priors.linear_precision) == 1 else \
            post.priors.linear_precision
        A, b = prec.copy(), prec @ post.priors.linear_mean
        for j in keep:
            X, y = rows[j]
            Xw = np.vstack([X[:1] * math.sqrt(1 - phi**2), X[1:] - phi * X[:-1]])
            yw = np.concatenate([y[:1] * math.sqrt(1 - phi**2), y[1:] - phi * y[:-1]])
            A += Xw.T @ Xw / sigma**2
            b += Xw.T @ yw / sigma**2
        cov = np.linalg.inv(A)
        return cov @ b, cov

    def cov_at(pairs, c):
        return np.mean([np.mean(np.abs(e) <= 1.6448536269514722 * c * np.sqrt(v)) for e, v in pairs])

    def ev(i, f):
        X, y = rows[i]
        return y - X @ f[0], np.einsum("ij,jk,ik->i", X, f[1], X) + noise_var

    grid = np.exp(np.linspace(np.log(0.05), np.log(20), 4000))
    full = fit(range(len(rows)))
    own = [ev(i, full) for i in range(len(rows))]
    c_pool = grid[np.argmax([cov_at(own, c) >= 0.9 for c in grid])]
    assert cal.pooled == pytest.approx(c_pool, rel=2e-3)
    freqs = [s.frequency_hz for s in post.segments]
    ends = [i for i in range(len(rows)) if freqs[i] in (min(freqs), max(freqs))]
    out = [ev(i, fit([j for j in range(len(rows)) if j != i])) for i in ends]
    c_out = grid[np.argmax([cov_at(out, c) >= 0.9 for c in grid])]
    assert cal.outside == pytest.approx(c_out, rel=2e-3)


# --- the command line ----------------------------------------------------------------------
def _hysbench(capsys, *args):
    """Run the CLI in this process: (exit status, stdout, stderr)."""
    capsys.readouterr()
    try:
        code = cli_main(list(args))
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    model = get_model("mrpim", **SMALL)
    ds = simulated_ar1_dataset(model, TRUTH, sigma=SIGMA, phi=PHI, seed=7, n_periods=2, dt=0.02, name="tiny")
    folder = tmp_path_factory.mktemp("tiny")
    save_dataset(ds, folder)
    return folder


@pytest.mark.parametrize("args, fragment", [
    (["/no/such/folder"], "no such dataset"),
    (["{ds}", "--model", "nope"], "unknown model"),
    (["{ds}", "--walkers", "7"], "walkers must be an even number"),
    (["{ds}", "--walkers", "x"], "expected an integer >= 1"),
    (["{ds}", "--noise", "white"], "invalid choice"),
    (["{ds}", "--burn", "-3"], "expected an integer >= 0"),
    (["{ds}", "--min-ess", "nan"], "expected a finite number"),
])
def test_cli_bad_input_is_one_line_and_exit_2(tiny_dataset, tmp_path, capsys, args, fragment):
    args = [a.format(ds=tiny_dataset) for a in args]
    code, _, err = _hysbench(capsys, "posterior", *args, "--out", str(tmp_path / "o"), "--quiet")
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], err


def test_cli_bad_input_through_the_console_script(tmp_path):
    p = subprocess.run([sys.executable, "-m", "hysbench.benchmarks.cli", "posterior", str(tmp_path / "missing")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr


def test_cli_writes_outputs_warns_when_not_converged_and_resumes(tiny_dataset, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = _hysbench(capsys, "posterior", str(tiny_dataset), "--model", "mrpim", "--out", str(out),
                             "--steps", "40", "--fixed-steps", "--walkers", "8", "--draws", "20", "--quiet")
    assert code == 0, err
    assert "NOT converged" in err
    summary = json.loads((out / "posterior.json").read_text())
    assert summary["converged"] is False and summary["sampler"]["steps"] == 40
    assert summary["noise_model"]["name"] == "ar1" and summary["wall_seconds"] > 0
    deltas = set(summary["discrepancy"]["coefficients"])
    assert len(deltas) >= 2 and all(d.startswith("delta_tau") for d in deltas)
    assert set(summary["parameters"]) == set(get_model("mrpim").param_names) | deltas | {"sigma", "phi"}
    validation = {p["file"] for p in summary["predictive"]["validation"]}
    assert set(summary["predictive_coverage"]) == validation
    for c in summary["predictive_coverage"].values():
        assert set(c) == {"50", "90", "width_50", "width_90"} and 0 <= c["50"] <= c["90"] <= 1
        assert 0 < c["width_50"] < c["width_90"]
    assert summary["nonfinite_model_outputs"]["log_posterior_evaluations"] == 0
    for v in summary["parameters"].values():
        assert set(v) == {"mean", "sd", "q05", "q50", "q95", "ess", "tau"}
        assert v["q05"] <= v["q50"] <= v["q95"]
    md = (out / "posterior.md").read_text()
    assert md.startswith("> **NOT CONVERGED.**") and "## Priors" in md and "## Identifiability" in md
    for f in ("posterior_corner.png", "posterior_predictive.png", "posterior_trace.png", "posterior_chain.h5"):
        assert (out / f).stat().st_size > 0
    assert 0 <= summary["predictive"]["validation"][0]["fraction_inside_observation_band"] <= 1
    # same settings: the chain file is resumed and extended
    code, _, err = _hysbench(capsys, "posterior", str(tiny_dataset), "--out", str(out), "--steps", "60",
                             "--fixed-steps", "--walkers", "8", "--draws", "20", "--quiet", "--no-figures")
    assert code == 0, err
    summary = json.loads((out / "posterior.json").read_text())
    assert summary["sampler"]["resumed_from_step"] == 40 and summary["sampler"]["steps"] == 60
    # other settings: refused in one line, unless --restart
    code, _, err = _hysbench(capsys, "posterior", str(tiny_dataset), "--out", str(out), "--steps", "60",
                             "--walkers", "10", "--quiet")
    assert code == 2 and "other settings (differs in: walkers)" in err
    assert len(err.strip().splitlines()) == 1


def test_cli_flags_validation_records_outside_the_fitted_frequency_range(tmp_path, capsys):
    """A validation record beyond the identification records' frequencies is marked extrapolated in the JSON,
    posterior.md and on stderr; the records inside are not."""
    model = get_model("mrpim", **SMALL)
    ds = simulated_ar1_dataset(model, TRUTH, sigma=SIGMA, phi=PHI, seed=7, n_periods=2, dt=0.02, name="edge")
    for r in ds.records:  # identify on 0.05-0.4 Hz: 0.02, 0.8 and 1 Hz are validation, beyond the range
        r.role = "identification" if 0.05 <= r.frequency_hz <= 0.4 else "validation"
    folder = tmp_path / "edge"
    save_dataset(ds, folder)
    out = tmp_path / "out"
    code, _, err = _hysbench(capsys, "posterior", str(folder), "--out", str(out), "--steps", "40", "--fixed-steps",
                             "--walkers", "8", "--draws", "20", "--quiet", "--no-figures", "--no-chain")
    assert code == 0, err
    rows = json.loads((out / "posterior.json").read_text())["predictive"]
    flags = {p["frequency_hz"]: p["inside_fitted_range"] for p in rows["validation"]}
    assert flags == {0.02: False, 0.8: False, 1.0: False}
    assert all(p["inside_fitted_range"] for p in rows["identification"])
    assert "outside the identification records' frequency range" in err and "f0.8Hz" in err
    assert "**Outside the fitted frequency range:" in (out / "posterior.md").read_text()


def test_a_given_burn_in_longer_than_the_first_checks_is_sampled_past():
    """``burn`` = 120 with checks every 50 steps: the checks before step 121 are skipped, not refused; a burn-in
    that leaves no step of ``max_steps`` is refused before any sampling."""
    ds = simulated_ar1_dataset(get_model("mrpim", **SMALL), TRUTH, sigma=SIGMA, phi=PHI, n_periods=2, dt=0.05,
                               frequencies=(0.4, 1.0))
    kw = dict(n_walkers=8, min_ess=1e9, seed=0, progress=False, discrepancy="none", calibrate=False,
              start_params=TRUTH)
    run = sample_posterior(get_model("mrpim", **SMALL), ds, max_steps=160, burn=120, **kw)
    assert run.chain.shape[0] == 160 and run.conv.burn == 120
    with pytest.raises(IdentificationError, match="burn-in 160 leaves no step of the at most 160 steps"):
        sample_posterior(get_model("mrpim", **SMALL), ds, max_steps=160, burn=160, **kw)


def test_the_burn_in_help_states_the_automatic_rule(capsys):
    """--help states the automatic burn-in that ``convergence`` computes, both of its parts."""
    code, out, _ = _hysbench(capsys, "posterior", "--help")
    help_text = " ".join(out.split())  # argparse wraps the lines
    assert code == 0
    assert "the larger of 5 autocorrelation times and the step where the walkers' median log posterior" in help_text


def test_api_refuses_models_without_a_linear_part_and_bad_settings():
    ds = simulated_ar1_dataset(get_model("mrpim", **SMALL), TRUTH, sigma=SIGMA, phi=PHI, n_periods=2, dt=0.05,
                               frequencies=(0.4, 1.0))
    with pytest.raises(IdentificationError, match="no linear parameters"):
        LogPosterior(_NoLinear(), ds.identification)
    with pytest.raises(IdentificationError, match="unknown noise model"):
        LogPosterior(get_model("mrpim", **SMALL), ds.identification, noise="white")


class _NoLinear(_Drifting):
    def parameters(self, scale=None):
        return (Parameter("k", 0.0, -1, 1, False),)


def test_a_chain_of_a_few_steps_is_too_short_to_be_converged_and_gives_no_warning():
    """On a few steps emcee's estimate of tau is 0 or far below 1 (no correlation can be resolved), which would
    give an infinite or huge effective sample size: it is NaN, and a chain shorter after burn-in than
    ``TAU_FACTOR`` steps is never called converged."""
    rng = np.random.default_rng(2)
    for n in (2, 3, 4, 6, 20):
        x = rng.normal(size=(n, 8, 2)).cumsum(axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            c = convergence(x, np.zeros((n, 8, 0)), np.full(8, 0.4 * n), burn=0)
        assert np.all(np.isnan(c.tau) | (c.tau > 0)) and not np.any(np.isinf(c.ess)), (n, c.tau, c.ess)
        assert not c.converged and any("steps long" in q for q in c.problems), (n, c.problems)
