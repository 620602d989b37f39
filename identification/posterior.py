"""Posterior of a partly linear model's parameters with emcee (``hysbench posterior``).

What is sampled. A model with a linear part (MRPIM: everything but gamma and
lambda) is y = Phi(theta_N) theta_L. The residuals of each fitted record
window are AR(1) noise with innovation sd sigma and coefficient phi (``noise
= "ar1"``), or independent (``"iid"``: phi = 0), see ``likelihood``. Given
(theta_N, sigma, phi) the linear parameters have a Gaussian conditional
posterior, so they are integrated out exactly and emcee's ensemble walks only
over (theta_N, log sigma, phi): four dimensions for MRPIM instead of 23. For
every state a walker visits, theta_L is drawn from its Gaussian conditional
and carried as the state's blob; the pairs (state, draw) are draws from the
joint posterior (a collapsed sampler: the acceptance ratio of the joint move
equals that of the marginal). The log-probability is vectorised over walkers:
one call builds the regressors of every walker (``windowed_regressors_batch``,
batched numba kernels) and the prewhitened Gram matrices (``whitened_gram``).

Priors (stated in every output, see ``Priors.describe``):

* theta_N: uniform on the identification bounds (the model's defaults scaled
  to the data, as ``identify`` uses them);
* sigma: log-uniform (Jeffreys) on [1e-9, 10] x max |y|;
* phi: uniform on (-1, 1) (a stationary AR(1));
* theta_L: independent normals centred on the middle of each parameter's
  identification bounds with sd = half their width (so +-1 sd is the search
  box of the identifiers). Weakly informative for what the data determine; for
  directions the data do not determine at all (MRPIM's operators whose
  threshold exceeds the input span are constant over every fitted window), the
  posterior is this prior, and the output says so.

Data. The fitted rows are the scored windows of the identification records
(what ``identify`` fits), every sample with the same weight: eq. 9's weights
k_m / n_m are an optimisation criterion, not a noise model. A record whose
input is periodic from its first sample and whose window starts after its
second period is simulated on a shortened input with the same window outputs
(``periodic_proxy``); the shortcut is used only after checking on the record
that it reproduces the full record's regressors.

Start. ``identify(model, dataset, "varpro")`` gives theta_N and the noise start
comes from the residuals there. Because varpro minimises eq. 9 (weighted,
independent residuals), its optimum need not be near the mode of this
posterior: it is compared with 64 Sobol points of the theta_N prior box in one
batched evaluation and the best is kept. A few Newton steps on the log
posterior (finite-difference derivatives, batched) then find its mode and a
Laplace covariance, and the walkers start as draws from that Gaussian (a
diagonal ball from the curvature where the Hessian is not negative definite).

Convergence is measured, not assumed: emcee's integrated autocorrelation time
tau per parameter (linear ones from their draws), the chain after burn-in at
least ``TAU_FACTOR`` = 50 tau long, effective sample sizes, acceptance
fractions (a walker below 5 % is called stuck). ``sample_posterior`` stops
early once that holds and every parameter has ``min_ess`` effective samples,
else after ``max_steps``; burn-in is chosen automatically (see
``convergence``) unless given. Moves: emcee's differential evolution (0.8)
with its snooker variant (0.2) by default, whose autocorrelation times on
MRPIM were about 0.6 of the stretch move's.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.models.base import HysteresisModel

from .errors import IdentificationError
from .likelihood import LinearMarginal, marginalise_linear, whitened_gram
from .problem import Problem

NOISE_MODELS = ("ar1", "iid")
TAU_FACTOR = 50  # chains after burn-in must be this many autocorrelation times long
BURN_TAUS = 5  # automatic burn-in: this many autocorrelation times
MIN_ACCEPTANCE = 0.05  # a walker accepting less is called stuck
SIGMA_PRIOR_RANGE = (1e-9, 10.0)  # times max |y|
CHAIN_FORMAT = "hysbench-posterior-chain/1"
REGRESSOR_CHUNK_BYTES = 40e6  # regressor matrices built at once (see LogPosterior.grams)
SERIAL_SAMPLES = 200_000  # below this many simulated samples (x parameter sets) per record, one thread


class _numba_threads:
    """Run numba's parallel kernels on ``n`` threads inside the block (None: leave as is)."""

    def __init__(self, n: int | None):
        self.n = n

    def __enter__(self):
        import numba

        self.old = numba.get_num_threads()
        if self.n is not None:
            numba.set_num_threads(min(self.n, self.old))

    def __exit__(self, *exc):
        import numba

        numba.set_num_threads(self.old)


# --- data: record windows, with periodic records shortened ---------------------
@dataclass
class Segment:
    """One fitted record: the input to simulate and the rows whose outputs are fitted."""

    file: str
    u: np.ndarray
    dt: float
    window: slice
    y: np.ndarray  # measured output on the window
    frequency_hz: float | None
    full_samples: int
    proxy: bool = False  # u is a shortened periodic proxy of the record's input

    @property
    def n(self) -> int:
        return self.y.size


def periodic_proxy(record: Record, rtol: float = 1e-9) -> tuple[np.ndarray, slice] | None:
    """A short input with the same outputs on the record's window, or None.

    For an input periodic with P samples from its first sample, a play
    operator's state is periodic from sample P + 1 on: its map over one period
    is a composition of clamps max(a, min(b, w)), which is again a clamp, and
    applying a clamp twice changes nothing. So the window [start, stop) of a
    record with start >= 2P sees the same regressors as rows [2P, 2P + n) of
    u[:2P-2] ++ u[start-2:stop] (the two samples before the window are the
    record's own, so derivative columns are bit-identical). This holds for
    models whose state is driven by the input alone (the P-I family); callers
    must check it on the model at hand (``build_segments`` does).
    """
    f, dt = record.frequency_hz, record.dt
    if not f or not dt > 0:
        return None
    period = int(round(1.0 / (f * dt)))
    if period < 3 or abs(period * f * dt - 1.0) > 1e-6:
        return None
    start, stop = record.start, record.stop
    if start <= 2 * period:
        return None
    u = record.u
    if np.max(np.abs(u[period:stop] - u[: stop - period])) > rtol * max(1.0, float(np.max(np.abs(u[:stop])))):
        return None
    proxy = np.concatenate((u[: 2 * period - 2], u[start - 2: stop]))
    return proxy, slice(2 * period, 2 * period + (stop - start))


def build_segments(model: HysteresisModel, records: Sequence[Record], input_range, check_sets: np.ndarray,
                   shorten: bool = True) -> list[Segment]:
    """The fitted windows of ``records``, periodic ones shortened where verified.

    A proxy is kept only if its regressors equal the full record's (max abs
    difference <= 1e-9 x max |Phi|) at every nonlinear parameter set of
    ``check_sets``.
    """
    segments = []
    for r in records:
        seg = Segment(r.file, r.u, r.dt, r.scored, r.y[r.scored].copy(), r.frequency_hz, r.u.size)
        found = periodic_proxy(r) if shorten else None
        if found is not None:
            u_p, w_p = found
            full = model.windowed_regressors_batch(r.u, r.dt, check_sets, r.scored, input_range)
            short = model.windowed_regressors_batch(u_p, r.dt, check_sets, w_p, input_range)
            if np.max(np.abs(full - short)) <= 1e-9 * max(1.0, float(np.max(np.abs(full)))):
                seg = Segment(r.file, u_p, r.dt, w_p, seg.y, r.frequency_hz, r.u.size, proxy=True)
        segments.append(seg)
    return segments


# --- priors ----------------------------------------------------------------------
@dataclass
class Priors:
    nonlinear_names: tuple[str, ...]
    nonlinear_lower: np.ndarray
    nonlinear_upper: np.ndarray
    linear_names: tuple[str, ...]
    linear_mean: np.ndarray
    linear_sd: np.ndarray
    log_sigma_range: tuple[float, float]
    noise: str

    @property
    def linear_precision(self) -> np.ndarray:
        return 1.0 / self.linear_sd**2

    def describe(self) -> list[dict]:
        """One entry per parameter: its prior in words and numbers."""
        out = []
        for n, lo, hi in zip(self.nonlinear_names, self.nonlinear_lower, self.nonlinear_upper):
            out.append({"name": n, "prior": "uniform", "low": float(lo), "high": float(hi), "sampled": True})
        for n, m, s in zip(self.linear_names, self.linear_mean, self.linear_sd):
            out.append({"name": n, "prior": "normal", "mean": float(m), "sd": float(s), "sampled": False,
                        "note": "integrated out; drawn from its Gaussian conditional"})
        lo, hi = self.log_sigma_range
        out.append({"name": "sigma", "prior": "log-uniform", "low": math.exp(lo), "high": math.exp(hi),
                    "sampled": True, "note": "innovation sd of the residual noise"})
        if self.noise == "ar1":
            out.append({"name": "phi", "prior": "uniform", "low": -1.0, "high": 1.0, "sampled": True,
                        "note": "AR(1) coefficient per sample"})
        else:
            out.append({"name": "phi", "prior": "fixed", "value": 0.0, "sampled": False,
                        "note": "independent noise"})
        return out


# --- the log posterior -------------------------------------------------------------
class LogPosterior:
    """log p(theta_N, log sigma, phi | y) with theta_L integrated out; see the module docstring.

    ``coords`` (the sampler's space) are theta_N (model order), log sigma and,
    for AR(1) noise, phi. Calling the object with an (n, d) array returns an
    (n, 1 + p) array: the log posterior and a draw of theta_L per row (NaN
    where the log posterior is -inf), which is what emcee's vectorised
    sampler takes as log-probability and blobs.
    """

    def __init__(self, model: HysteresisModel, records: Sequence[Record], noise: str = "ar1",
                 bounds: Mapping | None = None, shorten: bool = True, seed: int | None = 0,
                 start_nonlinear: np.ndarray | None = None):
        if noise not in NOISE_MODELS:
            raise IdentificationError(f"unknown noise model {noise!r}; choose one of {', '.join(NOISE_MODELS)}")
        if not model.has_linear_part:
            raise IdentificationError(
                f"posterior: model {model.name!r} has no linear parameters to integrate out; this sampler needs a "
                "partly linear model (e.g. mrpim, classical-pi)")
        records = list(records)
        if not records:
            raise IdentificationError("posterior: no records to fit")
        self.model = model
        self.noise = noise
        self.problem = Problem.build(model, records, bounds)
        self.input_range = self.problem.input_range
        names = model.param_names
        self.param_names = names
        self.nonlinear_names = model.nonlinear_names
        self.linear_names = model.linear_names
        self.nl_idx = np.array([names.index(n) for n in self.nonlinear_names], dtype=int)
        self.lin_idx = np.array([names.index(n) for n in self.linear_names], dtype=int)
        lo, hi = self.problem.lower, self.problem.upper
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            bad = [n for n, a, b in zip(names, lo, hi) if not (math.isfinite(a) and math.isfinite(b) and b > a)]
            raise IdentificationError(f"posterior: the priors need finite bounds low < high for {', '.join(bad)}")
        y_scale = self.problem.scale.y
        self.priors = Priors(
            nonlinear_names=self.nonlinear_names,
            nonlinear_lower=lo[self.nl_idx].copy(),
            nonlinear_upper=hi[self.nl_idx].copy(),
            linear_names=self.linear_names,
            linear_mean=0.5 * (lo[self.lin_idx] + hi[self.lin_idx]),
            linear_sd=0.5 * (hi[self.lin_idx] - lo[self.lin_idx]),
            log_sigma_range=(math.log(SIGMA_PRIOR_RANGE[0] * y_scale), math.log(SIGMA_PRIOR_RANGE[1] * y_scale)),
            noise=noise,
        )
        n_nl = len(self.nonlinear_names)
        self.coord_names = self.nonlinear_names + (("log_sigma", "phi") if noise == "ar1" else ("log_sigma",))
        self.ndim = len(self.coord_names)
        mid = 0.5 * (self.priors.nonlinear_lower + self.priors.nonlinear_upper)
        checks = [mid if start_nonlinear is None else np.asarray(start_nonlinear, float)]
        if n_nl:
            width = self.priors.nonlinear_upper - self.priors.nonlinear_lower
            checks += [self.priors.nonlinear_lower + 0.3 * width, self.priors.nonlinear_upper - 0.2 * width]
        self.segments = build_segments(model, records, self.input_range,
                                       np.array(checks, dtype=float).reshape(len(checks), n_nl), shorten)
        self.n_rows = sum(s.n for s in self.segments)
        self.rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 7]))
        self.n_evaluations = 0

    # --- coordinates ------------------------------------------------------------
    def split(self, X: np.ndarray):
        """(theta_N, sigma, phi) arrays from sampler coordinates (n, d)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n_nl = len(self.nonlinear_names)
        nl = X[:, :n_nl]
        sigma = np.exp(X[:, n_nl])
        phi = X[:, n_nl + 1] if self.noise == "ar1" else np.zeros(X.shape[0])
        return nl, sigma, phi

    def coords(self, nonlinear, sigma: float, phi: float = 0.0) -> np.ndarray:
        x = list(np.asarray(nonlinear, float).reshape(-1)) + [math.log(sigma)]
        if self.noise == "ar1":
            x.append(phi)
        return np.array(x)

    def in_support(self, X: np.ndarray) -> np.ndarray:
        nl, _, phi = self.split(X)
        n_nl = nl.shape[1]
        ls = np.atleast_2d(X)[:, n_nl]
        lo, hi = self.priors.log_sigma_range
        ok = np.all((nl >= self.priors.nonlinear_lower) & (nl <= self.priors.nonlinear_upper), axis=1)
        ok &= (ls >= lo) & (ls <= hi) & (np.abs(phi) < 1.0)
        return ok & np.all(np.isfinite(np.atleast_2d(X)), axis=1)

    def log_prior(self, X: np.ndarray) -> np.ndarray:
        """Normalised log prior density of the sampled coordinates (-inf outside the support)."""
        ok = self.in_support(X)
        lo, hi = self.priors.log_sigma_range
        c = -float(np.sum(np.log(self.priors.nonlinear_upper - self.priors.nonlinear_lower))) - math.log(hi - lo)
        if self.noise == "ar1":
            c -= math.log(2.0)
        return np.where(ok, c, -np.inf)

    # --- evaluation ---------------------------------------------------------------
    def grams(self, nl: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Prewhitened Gram matrices of [Phi*, y*] summed over records, (n, p+1, p+1).

        Regressors are built for about ``REGRESSOR_CHUNK_BYTES`` worth of
        parameter sets at a time, so that a chunk is still in cache when its
        Gram matrices are formed. A short record is built for all sets at once
        on one thread: waking the thread pool would cost more than it saves.
        """
        p = len(self.linear_names)
        n_set = nl.shape[0]
        G = np.zeros((n_set, p + 1, p + 1))
        import numba

        threads = numba.get_num_threads()
        for s in self.segments:
            small = s.u.size * n_set < SERIAL_SAMPLES
            per_set = int(REGRESSOR_CHUNK_BYTES // (8 * s.n * p))
            chunk = n_set if small else max(threads, per_set // threads * threads)  # whole rounds of threads
            with _numba_threads(1 if small else None):
                for a in range(0, n_set, chunk):
                    sl = slice(a, a + chunk)
                    Phi = self.model.windowed_regressors_batch(s.u, s.dt, nl[sl], s.window, self.input_range)
                    whitened_gram(np.transpose(Phi, (0, 2, 1)), s.y, phi[sl], G[sl])
        self.n_evaluations += n_set
        return G

    def marginal(self, X: np.ndarray) -> tuple[np.ndarray, LinearMarginal | None, np.ndarray]:
        """(log posterior (n,), the linear marginal of the in-support rows, their indices)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        lp = self.log_prior(X)
        idx = np.flatnonzero(np.isfinite(lp))
        if idx.size == 0:
            return lp, None, idx
        nl, sigma, phi = self.split(X[idx])
        G = self.grams(nl, phi)
        log_jac = len(self.segments) * 0.5 * np.log1p(-phi * phi)
        marg = marginalise_linear(G, sigma, self.n_rows, log_jac, self.priors.linear_mean,
                                  self.priors.linear_precision)
        lp = lp.copy()
        lp[idx] += marg.loglik
        lp[~np.isfinite(lp)] = -np.inf
        return lp, marg, idx

    def log_prob(self, X: np.ndarray) -> np.ndarray:
        return self.marginal(X)[0]

    def __call__(self, X: np.ndarray) -> np.ndarray:
        lp, marg, idx = self.marginal(X)
        out = np.full((lp.size, 1 + len(self.linear_names)), np.nan)
        out[:, 0] = lp
        if marg is not None:
            out[idx, 1:] = marg.draw(self.rng)
        out[~np.isfinite(lp), 1:] = np.nan
        return out

    # --- predictions ------------------------------------------------------------
    def full_params(self, nl: np.ndarray, linear: np.ndarray) -> np.ndarray:
        nl, linear = np.atleast_2d(nl), np.atleast_2d(linear)
        P = np.empty((nl.shape[0], len(self.param_names)))
        P[:, self.nl_idx] = nl
        P[:, self.lin_idx] = linear
        return P

    def window_outputs(self, segment: Segment, nl: np.ndarray, linear: np.ndarray, chunk: int = 8) -> np.ndarray:
        """Model outputs on a segment's window for parameter sets (n, n_window)."""
        nl, linear = np.atleast_2d(nl), np.atleast_2d(linear)
        out = np.empty((nl.shape[0], segment.n))
        for a in range(0, nl.shape[0], chunk):
            Phi = self.model.windowed_regressors_batch(segment.u, segment.dt, nl[a:a + chunk], segment.window,
                                                       self.input_range)
            out[a:a + chunk] = np.einsum("bnp,bp->bn", Phi, linear[a:a + chunk])
        return out


# --- start point: the varpro optimum, then the posterior mode and a Laplace covariance ---
def noise_estimate(post: LogPosterior, nl: np.ndarray) -> tuple[float, float]:
    """(sigma, phi) from the residuals of the conditional-mean fit at theta_N = nl."""
    phi0 = 0.0
    sigma0 = 1.0
    for _ in range(2):  # refit the linear part once under the estimated noise
        _, marg, idx = post.marginal(post.coords(nl, sigma0, phi0)[None])
        if marg is None or not marg.ok[0]:
            break
        res = [post.window_outputs(s, nl[None], marg.mean[:1])[0] - s.y for s in post.segments]
        num = sum(float(e[1:] @ e[:-1]) for e in res)
        den = sum(float(e[:-1] @ e[:-1]) for e in res)
        phi0 = min(max(num / den, -0.95), 0.9995) if (post.noise == "ar1" and den > 0) else 0.0
        innov = np.concatenate([e[1:] - phi0 * e[:-1] for e in res])
        sigma0 = max(float(np.sqrt(np.mean(innov**2))), 1e-6 * post.problem.scale.y)
    return sigma0, phi0


def _stencil(x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Points for central differences: x, x +- h_i e_i, x +- h_i e_i +- h_j e_j (i < j)."""
    d = x.size
    pts = [x]
    for i in range(d):
        for s in (1, -1):
            p = x.copy()
            p[i] += s * h[i]
            pts.append(p)
    for i in range(d):
        for j in range(i + 1, d):
            for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                p = x.copy()
                p[i] += si * h[i]
                p[j] += sj * h[j]
                pts.append(p)
    return np.array(pts)


def _derivatives(f: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = h.size
    f0 = f[0]
    fp, fm = f[1:1 + 2 * d:2], f[2:2 + 2 * d:2]
    g = (fp - fm) / (2 * h)
    H = np.diag((fp - 2 * f0 + fm) / h**2)
    k = 1 + 2 * d
    for i in range(d):
        for j in range(i + 1, d):
            pp, pm, mp, mm = f[k:k + 4]
            H[i, j] = H[j, i] = (pp - pm - mp + mm) / (4 * h[i] * h[j])
            k += 4
    return g, H


def find_mode(post: LogPosterior, x0: np.ndarray, max_iter: int = 12) -> tuple[np.ndarray, np.ndarray, dict]:
    """Newton steps on the log posterior from x0 with finite-difference derivatives.

    Returns (mode, covariance for the walkers' start, info): the Laplace
    covariance if the Hessian is negative definite at the end
    (``info["laplace"]``), else a diagonal ball.
    """
    x = np.asarray(x0, dtype=float).copy()
    d = x.size
    n_nl = len(post.nonlinear_names)
    width = np.ones(d)
    width[:n_nl] = post.priors.nonlinear_upper - post.priors.nonlinear_lower
    h = 1e-4 * width
    f_x = float(post.log_prob(x[None])[0])
    cov = None
    diag_sd = None
    info = {"iterations": 0, "start_log_posterior": f_x}
    for it in range(max_iter):
        if post.noise == "ar1":  # keep the stencil inside |phi| < 1
            h[-1] = min(h[-1], 0.25 * (1.0 - abs(x[-1])))
        f = post.log_prob(_stencil(x, h))
        info["iterations"] = it + 1
        if not np.all(np.isfinite(f)):
            h *= 0.25
            continue
        g, H = _derivatives(f, h)
        curv = -np.diag(H)
        diag_sd = np.where(curv > 0, 1.0 / np.sqrt(np.where(curv > 0, curv, 1.0)), np.nan)
        try:
            L = np.linalg.cholesky(-H)
            cov = np.linalg.inv(-H)
            step = np.linalg.solve(L.T, np.linalg.solve(L, g))
        except np.linalg.LinAlgError:
            cov = None
            step = np.sign(g) * h
        cands = x[None] + np.outer([1.0, 0.5, 0.25, 0.125], step)
        fc = post.log_prob(cands)
        k = int(np.argmax(fc))
        gain = float(fc[k] - f_x)
        if gain > 0:
            x, f_x = cands[k], float(fc[k])
        if cov is not None:
            sd = np.sqrt(np.diag(cov))
            h = np.clip(0.5 * sd, 1e-10 * width, 0.05 * width)
            if gain < 1e-3 and np.all(np.abs(step) < 0.05 * sd):
                break
        elif gain <= 0:
            h *= 0.5
    info["log_posterior"] = f_x
    if cov is not None:  # re-check at the final point with its own step sizes
        f = post.log_prob(_stencil(x, h))
        if np.all(np.isfinite(f)):
            _, H = _derivatives(f, h)
            try:
                np.linalg.cholesky(-H)
                cov = np.linalg.inv(-H)
            except np.linalg.LinAlgError:
                cov = None
    info["laplace"] = cov is not None
    if cov is None:  # a diagonal ball: the curvature where it is negative, else 1e-3 of the prior width
        fallback = np.full(d, 1e-3)
        fallback[:n_nl] = 1e-3 * width[:n_nl]
        sd = fallback if diag_sd is None else np.where(np.isfinite(diag_sd), np.minimum(diag_sd, 10 * fallback),
                                                       fallback)
        cov = np.diag(sd**2)
        info["ball_sd"] = [float(v) for v in sd]
    return x, cov, info


def screen_start(post: LogPosterior, nl0: np.ndarray, sigma: float, phi: float, seed, n: int = 64) -> np.ndarray:
    """The best of nl0 and ``n`` scrambled Sobol points of the nonlinear prior box, by log posterior
    at the given noise parameters (one batched evaluation): the identifiers' optimum (weighted
    least squares) need not be near the mode under the AR(1) likelihood."""
    from scipy.stats import qmc

    d = nl0.size
    if d == 0:
        return nl0
    lo, hi = post.priors.nonlinear_lower, post.priors.nonlinear_upper
    pts = lo + qmc.Sobol(d, scramble=True, seed=np.random.default_rng(seed)).random(n) * (hi - lo)
    cands = np.vstack([nl0[None], pts])
    X = np.array([post.coords(c, sigma, phi) for c in cands])
    lp = post.log_prob(X)
    return cands[int(np.argmax(lp))]


def initial_walkers(post: LogPosterior, mode: np.ndarray, cov: np.ndarray, n_walkers: int,
                    rng: np.random.Generator) -> np.ndarray:
    """Walkers drawn from the Laplace Gaussian (or a diagonal ball), inside the prior support."""
    d = mode.size
    L = np.linalg.cholesky(cov + 1e-300 * np.eye(d))
    out = np.empty((0, d))
    for _ in range(100):
        cand = mode[None] + rng.standard_normal((4 * n_walkers, d)) @ L.T
        cand = cand[post.in_support(cand)]
        out = np.vstack([out, cand])
        if out.shape[0] >= n_walkers:
            return out[:n_walkers]
    raise IdentificationError("posterior: cannot place the walkers inside the prior support around the mode")


# --- convergence -------------------------------------------------------------------
def autocorr_times(x: np.ndarray) -> np.ndarray:
    """emcee's integrated autocorrelation time per parameter of x (steps, walkers, params).

    Parameters that never change (e.g. fixed) get NaN.
    """
    import emcee

    x = np.asarray(x, dtype=float)
    taus = np.full(x.shape[2], np.nan)
    for k in range(x.shape[2]):
        col = x[:, :, k]
        if x.shape[0] < 2 or not np.all(np.isfinite(col)) or np.all(col == col[0]):
            continue
        taus[k] = float(emcee.autocorr.integrated_time(col[:, :, None], c=5, tol=0, quiet=True)[0])
    return taus


@dataclass
class Convergence:
    n_steps: int
    burn: int
    tau: np.ndarray  # per reported parameter, on the kept chain
    ess: np.ndarray
    acceptance: np.ndarray  # per walker
    tau_factor: float = TAU_FACTOR
    min_ess: float = 0.0

    @property
    def kept(self) -> int:
        return self.n_steps - self.burn

    @property
    def tau_max(self) -> float:
        t = self.tau[np.isfinite(self.tau)]
        return float(np.max(t)) if t.size else math.inf

    @property
    def length_in_tau(self) -> float:
        return self.kept / self.tau_max if self.tau_max > 0 else 0.0

    @property
    def problems(self) -> list[str]:
        p = []
        if not np.all(np.isfinite(self.tau)):
            p.append("the autocorrelation time of some parameter could not be estimated")
        if self.length_in_tau < self.tau_factor:
            p.append(f"the chain after burn-in is {self.length_in_tau:.1f} autocorrelation times long "
                     f"(< {self.tau_factor:g}): run more steps")
        stuck = int(np.sum(self.acceptance < MIN_ACCEPTANCE))
        if stuck:
            p.append(f"{stuck} walker(s) accepted fewer than {MIN_ACCEPTANCE:.0%} of their moves (stuck)")
        return p

    @property
    def converged(self) -> bool:
        return not self.problems

    @property
    def ess_met(self) -> bool:
        return bool(np.all(np.isfinite(self.ess)) and np.min(self.ess) >= self.min_ess)


def convergence(chain: np.ndarray, draws: np.ndarray, accepted: np.ndarray, burn: int | str = "auto",
                min_ess: float = 0.0, log_prob: np.ndarray | None = None) -> Convergence:
    """Burn-in, tau, ESS of the reported parameters (sampled coordinates and linear draws).

    Automatic burn-in: the larger of ``BURN_TAUS`` tau (estimated on the
    second half) and the first step at which the walkers' median log
    posterior reaches the median of the second half, plus 2 tau (walkers
    started far from the typical set need that long to get there).
    """
    n = chain.shape[0]
    if draws.ndim == 2:  # one linear parameter
        draws = draws[:, :, None]
    both = np.concatenate([chain, draws], axis=2)
    if burn == "auto":
        half = both[n // 2:]
        t = autocorr_times(half)
        t_max = float(np.nanmax(t)) if np.any(np.isfinite(t)) else n / 2
        burn = math.ceil(BURN_TAUS * t_max)
        if log_prob is not None and n >= 4:
            level = float(np.median(log_prob[n // 2:]))
            reached = np.flatnonzero(np.median(log_prob, axis=1) >= level)
            if reached.size:
                burn = max(burn, int(reached[0]) + math.ceil(2 * t_max))
        burn = int(min(burn, n - 2))
    burn = int(burn)
    if not 0 <= burn < n:
        raise IdentificationError(f"posterior: burn-in {burn} must be below the chain length {n}")
    kept = both[burn:]
    tau = autocorr_times(kept)
    ess = kept.shape[0] * kept.shape[1] / tau
    return Convergence(n, burn, tau, ess, accepted / max(n, 1), min_ess=min_ess)


# --- the chain file ------------------------------------------------------------------
def settings_fingerprint(post: LogPosterior, dataset: Dataset, n_walkers: int, seed, moves: str) -> dict:
    return {
        "format": CHAIN_FORMAT,
        "dataset_hash": dataset.content_hash(),
        "fitted_records": [s.file for s in post.segments],
        "model": post.model.name,
        "hyperparameters": {k: (v if isinstance(v, (int, float, str, bool)) or v is None else repr(v))
                            for k, v in post.model.get_hyperparameters().items()},
        "noise": post.noise,
        "walkers": int(n_walkers),
        "seed": None if seed is None else int(seed),
        "moves": moves,
        "priors": post.priors.describe(),
    }


def _checkpointed_backend_class():
    import emcee
    import h5py

    class CheckpointedBackend(emcee.backends.Backend):
        """emcee's in-memory backend, written to an HDF5 file every ``every`` steps and on ``flush()``.

        The file has the layout of emcee's ``HDFBackend`` (group "mcmc"), so
        emcee can read it. emcee's own HDF5 backend opens the file at every
        step, which cost about ten times a sampler step here.
        """

        def __init__(self, path: Path, every: int = 50):
            super().__init__()
            self.path = Path(path)
            self.every = int(every)
            self.flushed = 0

        def load(self) -> None:
            """The chain stored in the file, into memory."""
            stored = emcee.backends.HDFBackend(str(self.path), read_only=True)
            n = int(stored.iteration)
            n_walkers, ndim = stored.shape
            self.reset(n_walkers, ndim)
            blobs = stored.get_blobs()
            self.grow(n, None if blobs is None else blobs[0])
            self.chain[:n] = stored.get_chain()
            self.log_prob[:n] = stored.get_log_prob()
            if blobs is not None:
                self.blobs[:n] = blobs
            self.accepted = np.array(stored.accepted, dtype=float)
            self.random_state = stored.random_state
            self.iteration = n
            self.flushed = n

        def save_step(self, state, accepted):
            super().save_step(state, accepted)
            if self.iteration - self.flushed >= self.every:
                self.flush()

        def flush(self) -> None:
            a, b = self.flushed, self.iteration
            if b <= a:
                return
            with h5py.File(self.path, "a") as f:
                if "mcmc" not in f:
                    g = f.create_group("mcmc")
                    g.attrs.update(version=emcee.__version__, nwalkers=self.nwalkers, ndim=self.ndim,
                                   has_blobs=self.blobs is not None, iteration=0)
                    g.create_dataset("accepted", data=np.zeros(self.nwalkers))
                    g.create_dataset("chain", (0, self.nwalkers, self.ndim),
                                     maxshape=(None, self.nwalkers, self.ndim), dtype=float)
                    g.create_dataset("log_prob", (0, self.nwalkers), maxshape=(None, self.nwalkers), dtype=float)
                    if self.blobs is not None:
                        dt = np.dtype((self.blobs.dtype, self.blobs.shape[2:]))
                        g.create_dataset("blobs", (0, self.nwalkers), maxshape=(None, self.nwalkers), dtype=dt)
                g = f["mcmc"]
                names = ["chain", "log_prob"] + (["blobs"] if self.blobs is not None else [])
                for name in names:
                    g[name].resize(b, axis=0)
                    g[name][a:b] = getattr(self, name)[a:b]
                g["accepted"][:] = self.accepted
                for i, v in enumerate(self.random_state):
                    g.attrs[f"random_state_{i}"] = v
                g.attrs["iteration"] = b
            self.flushed = b

    return CheckpointedBackend


def open_backend(path: Path, fingerprint: dict, restart: bool, every: int = 50):
    """A checkpointed chain at ``path``: (backend, steps already stored, stored start info).

    A file that holds a chain for the same settings is loaded to be resumed;
    one for other settings is refused unless ``restart``.
    """
    import h5py

    key = json.dumps(fingerprint, sort_keys=True)
    backend = _checkpointed_backend_class()(path, every)
    if path.exists() and not restart:
        try:
            with h5py.File(path, "r") as f:
                stored = f.attrs.get("hysbench_settings")
                start_info = f.attrs.get("hysbench_start")
                has_chain = "mcmc" in f and int(f["mcmc"].attrs.get("iteration", 0)) > 0
        except OSError:
            raise IdentificationError(f"{path} exists but is not an HDF5 chain file; use --restart to replace it")
        if stored is None:
            raise IdentificationError(f"{path} is not a hysbench posterior chain; use --restart to replace it")
        if stored != key:
            old = json.loads(stored)
            diff = sorted(k for k in set(old) | set(fingerprint) if old.get(k) != fingerprint.get(k))
            raise IdentificationError(
                f"{path} holds a chain for other settings (differs in: {', '.join(diff)}); use --restart to "
                "discard it, or another --chain file")
        if has_chain:
            backend.load()
            return backend, backend.iteration, (json.loads(start_info) if start_info is not None else None)
    if path.exists():
        path.unlink()
    with h5py.File(path, "w") as f:
        f.attrs["hysbench_settings"] = key
    return backend, 0, None


def _store_start(path: Path | None, start: dict) -> None:
    if path is None:
        return
    import h5py

    with h5py.File(path, "a") as f:
        f.attrs["hysbench_start"] = json.dumps(start)


# --- the run ------------------------------------------------------------------------
MOVES = {
    "stretch": lambda emcee: None,
    "de": lambda emcee: [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)],
}


@dataclass
class PosteriorRun:
    """What ``sample_posterior`` returns; ``summary()`` gives the JSON body."""

    post: LogPosterior
    chain: np.ndarray  # (steps, walkers, d) sampler coordinates
    draws: np.ndarray  # (steps, walkers, p) linear parameters
    log_prob: np.ndarray  # (steps, walkers)
    conv: Convergence
    start: dict
    wall_seconds: float  # over every run that built the chain (resumed runs add up)
    sampling_seconds: float
    this_run_seconds: float
    resumed_from: int
    n_walkers: int
    moves: str
    seed: int | None
    dataset: str
    chain_file: str | None
    notes: list[str] = field(default_factory=list)

    # --- reported parameters: model order, then sigma and phi -------------------------
    @property
    def names(self) -> list[str]:
        return list(self.post.param_names) + ["sigma", "phi"]

    def samples(self, thin: int = 1) -> np.ndarray:
        """Kept draws of every reported parameter, flattened: (n, len(names))."""
        b = self.conv.burn
        ch = self.chain[b::thin]
        dr = self.draws[b::thin]
        nl, sigma, phi = self.post.split(ch.reshape(-1, ch.shape[-1]))
        full = self.post.full_params(nl, dr.reshape(-1, dr.shape[-1]))
        return np.column_stack([full, sigma, phi])

    def reported_tau(self) -> tuple[np.ndarray, np.ndarray]:
        """(tau, ess) in ``names`` order."""
        d_nl = len(self.post.nonlinear_names)
        p = len(self.post.linear_names)
        tau_c, tau_l = self.conv.tau[: self.post.ndim], self.conv.tau[self.post.ndim:]
        ess_c, ess_l = self.conv.ess[: self.post.ndim], self.conv.ess[self.post.ndim:]
        tau = np.full(len(self.names), np.nan)
        ess = np.full(len(self.names), np.nan)
        tau[self.post.nl_idx], ess[self.post.nl_idx] = tau_c[:d_nl], ess_c[:d_nl]
        tau[self.post.lin_idx], ess[self.post.lin_idx] = tau_l[:p], ess_l[:p]
        k = len(self.post.param_names)
        tau[k], ess[k] = tau_c[d_nl], ess_c[d_nl]
        if self.post.noise == "ar1":
            tau[k + 1], ess[k + 1] = tau_c[d_nl + 1], ess_c[d_nl + 1]
        return tau, ess

    def parameter_table(self) -> dict:
        S = self.samples()
        tau, ess = self.reported_tau()
        q = np.quantile(S, [0.05, 0.5, 0.95], axis=0)
        out = {}
        for i, n in enumerate(self.names):
            out[n] = {"mean": float(np.mean(S[:, i])), "sd": float(np.std(S[:, i], ddof=1)),
                      "q05": float(q[0, i]), "q50": float(q[1, i]), "q95": float(q[2, i]),
                      "ess": _num(ess[i]), "tau": _num(tau[i])}
        return out

    def correlation(self) -> tuple[list[str], np.ndarray]:
        """Correlation matrix of the model parameters and the noise parameters that vary."""
        S = self.samples()
        keep = [i for i in range(S.shape[1]) if np.std(S[:, i]) > 0]
        return [self.names[i] for i in keep], np.corrcoef(S[:, keep], rowvar=False)

    def summary(self) -> dict:
        c = self.conv
        tau, ess = self.reported_tau()
        names, corr = self.correlation()
        return {
            "format": "hysbench-posterior/1",
            "dataset": self.dataset,
            "model": self.post.model.name,
            "hyperparameters": self.post.model.get_hyperparameters(),
            "noise_model": {"name": self.post.noise,
                            "description": ("stationary AR(1) residuals per record window, exact likelihood "
                                            "(Prais-Winsten)" if self.post.noise == "ar1"
                                            else "independent Gaussian residuals (phi = 0)")},
            "linear_parameters": "integrated out analytically (Gaussian conditional); drawn from it per state",
            "converged": c.converged,
            "convergence_problems": c.problems,
            "ess_target": c.min_ess,
            "ess_target_met": c.ess_met,
            "min_ess": _num(np.nanmin(ess)) if np.any(np.isfinite(ess)) else None,
            "parameters": self.parameter_table(),
            "priors": self.post.priors.describe(),
            "sampler": {
                "package": "emcee", "walkers": self.n_walkers, "steps": c.n_steps, "burn_in": c.burn,
                "kept_steps": c.kept, "moves": self.moves, "sampled_coordinates": list(self.post.coord_names),
                "tau_max": _num(c.tau_max), "chain_length_in_tau": _num(c.length_in_tau),
                "tau_factor_required": TAU_FACTOR,
                "acceptance_fraction": {"mean": float(np.mean(c.acceptance)), "min": float(np.min(c.acceptance)),
                                        "max": float(np.max(c.acceptance))},
                "log_posterior_evaluations": self.post.n_evaluations,
                "resumed_from_step": self.resumed_from, "seed": self.seed, "chain_file": self.chain_file,
            },
            "data": {
                "rows": self.post.n_rows,
                "records": [{"file": s.file, "frequency_hz": s.frequency_hz, "rows": s.n,
                             "samples": s.full_samples, "simulated_samples": int(s.u.size), "shortened": s.proxy}
                            for s in self.post.segments],
                "input_range": list(self.post.input_range),
            },
            "start": self.start,
            "correlation": {"names": names, "matrix": [[round(float(v), 4) for v in row] for row in corr]},
            "wall_seconds": self.wall_seconds,
            "sampling_seconds": self.sampling_seconds,
            "this_run_seconds": self.this_run_seconds,
            "notes": self.notes,
        }


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def sample_posterior(model: HysteresisModel, dataset: Dataset, *, noise: str = "ar1", n_walkers: int = 16,
                     max_steps: int = 4000, min_ess: float = 1000.0, fixed_steps: bool = False,
                     burn: int | str = "auto", seed: int | None = 0, moves: str = "de",
                     chain_file: str | os.PathLike | None = None, restart: bool = False,
                     progress: bool | None = None, check_every: int = 50, start_params: Mapping | None = None,
                     log=None) -> PosteriorRun:
    """Sample the posterior of ``model``'s parameters given ``dataset``'s identification records.

    ``max_steps`` bounds the chain; unless ``fixed_steps``, sampling stops at
    the first check (every ``check_every`` steps) where the chain after
    burn-in is >= 50 tau long and every parameter has >= ``min_ess``
    effective samples. With ``chain_file`` the chain is kept in emcee's HDF5
    backend and a later call with the same settings resumes it. The start is
    ``start_params`` if given, else the ``varpro`` optimum.
    """
    import emcee

    from .api import identify

    t0 = time.perf_counter()
    say = log or (lambda msg: None)
    if moves not in MOVES:
        raise IdentificationError(f"unknown moves {moves!r}; choose one of {', '.join(MOVES)}")
    records = dataset.identification
    if not records:
        raise IdentificationError(f"dataset {dataset.name!r} has no identification records to fit")
    for name, value, lo in (("walkers", n_walkers, 2), ("steps", max_steps, 2), ("check_every", check_every, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise IdentificationError(f"{name} must be an integer >= {lo}, got {value!r}")
    if not (isinstance(min_ess, (int, float)) and min_ess >= 0):
        raise IdentificationError(f"min_ess must be a number >= 0, got {min_ess!r}")

    post = LogPosterior(model, records, noise=noise, seed=seed)
    if n_walkers < 2 * post.ndim or n_walkers % 2:
        raise IdentificationError(
            f"walkers must be an even number >= {2 * post.ndim} (twice the {post.ndim} sampled coordinates "
            f"{', '.join(post.coord_names)}), got {n_walkers}")
    backend, done, start = None, 0, None
    fingerprint = settings_fingerprint(post, dataset, n_walkers, seed, moves)
    path = Path(chain_file) if chain_file is not None else None
    if path is not None:
        backend, done, start = open_backend(path, fingerprint, restart)
    if done and start is None:
        start = {}
    p0 = None
    if not done:
        ts = time.perf_counter()
        if start_params is None:
            say("start: identify (varpro) ...")
            fit = identify(model, dataset, method="varpro", seed=seed)
            start_params, start_method = fit.params, "varpro"
        else:
            start_method = "given"
        nl0 = np.array([float(start_params[n]) for n in post.nonlinear_names])
        nl0 = np.clip(nl0, post.priors.nonlinear_lower, post.priors.nonlinear_upper)
        sigma0, phi0 = noise_estimate(post, nl0)
        nl1 = screen_start(post, nl0, sigma0, phi0, seed)
        if not np.array_equal(nl1, nl0):
            nl0 = nl1
            sigma0, phi0 = noise_estimate(post, nl0)
        x0 = post.coords(nl0, sigma0, phi0)
        say("start: posterior mode and Laplace covariance ...")
        mode, cov, info = find_mode(post, x0)
        start = {"method": start_method, "params": {k: float(v) for k, v in start_params.items()},
                 "noise_from_residuals": {"sigma": sigma0, "phi": phi0},
                 "mode": dict(zip(post.coord_names, map(float, mode))),
                 "screened_start": dict(zip(post.nonlinear_names, map(float, nl0))),
                 "start_sd": dict(zip(post.coord_names, map(float, np.sqrt(np.diag(cov))))),
                 "mode_search": info, "seconds": time.perf_counter() - ts}
        rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 11]))
        p0 = initial_walkers(post, mode, cov, n_walkers, rng)
        _store_start(path, start)
    else:
        post.rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 7, done]))

    sampler = emcee.EnsembleSampler(n_walkers, post.ndim, post, vectorize=True, backend=backend,
                                    moves=MOVES[moves](emcee))
    if p0 is not None:
        sampler.random_state = np.random.RandomState(0 if seed is None else int(seed)).get_state()
    else:  # resuming: the last stored state (coordinates, log posterior, draws, random state)
        p0 = sampler.get_last_sample()
    if progress is None:
        progress = sys.stderr.isatty()
    remaining = max(0, max_steps - done)
    ts = time.perf_counter()
    conv = None
    if done >= 2 and not fixed_steps:  # a resumed chain that already meets the stopping rule is only re-reported
        c = convergence(sampler.get_chain(), sampler.get_blobs(), sampler.backend.accepted, burn, min_ess,
                        sampler.get_log_prob())
        if c.converged and c.ess_met:
            conv, remaining = c, 0
    if remaining:
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=max_steps, initial=done, desc="sampling", unit="step", file=sys.stderr,
                       dynamic_ncols=True)
        try:
            for k, _ in enumerate(sampler.sample(p0, iterations=remaining, progress=False), start=done + 1):
                if bar is not None:
                    bar.update(1)
                if not fixed_steps and k % check_every == 0 and k >= 2 * check_every:
                    c = convergence(sampler.get_chain(), sampler.get_blobs(), sampler.backend.accepted, burn,
                                    min_ess, sampler.get_log_prob())
                    if bar is not None:
                        bar.set_postfix_str(f"tau {c.tau_max:.1f}, {c.length_in_tau:.0f} tau, "
                                            f"ESS min {np.nanmin(c.ess):.0f}")
                    if c.converged and c.ess_met:
                        conv = c
                        break
        finally:
            if bar is not None:
                bar.close()
            if hasattr(sampler.backend, "flush"):
                sampler.backend.flush()
    sampling_seconds = time.perf_counter() - ts
    chain = sampler.get_chain()
    draws = sampler.get_blobs()
    if draws.ndim == 2:  # a single linear parameter
        draws = draws[:, :, None]
    if conv is None or conv.n_steps != chain.shape[0]:
        conv = convergence(chain, draws, sampler.backend.accepted, burn, min_ess, sampler.get_log_prob())
    wall = time.perf_counter() - t0
    earlier = {"wall": 0.0, "sampling": 0.0}
    if path is not None:  # seconds spent on this chain file, over every run that built it
        import h5py

        with h5py.File(path, "a") as f:
            earlier = json.loads(f.attrs.get("hysbench_seconds", json.dumps(earlier)))
            f.attrs["hysbench_seconds"] = json.dumps({"wall": earlier["wall"] + wall,
                                                      "sampling": earlier["sampling"] + sampling_seconds})
    return PosteriorRun(post=post, chain=chain, draws=draws, log_prob=sampler.get_log_prob(), conv=conv,
                        start=start, wall_seconds=earlier["wall"] + wall,
                        sampling_seconds=earlier["sampling"] + sampling_seconds, this_run_seconds=wall,
                        resumed_from=done, n_walkers=n_walkers, moves=moves, seed=seed, dataset=dataset.name,
                        chain_file=None if path is None else str(path))


# --- posterior predictive ------------------------------------------------------------------
def ar1_noise(n: int, sigma: np.ndarray, phi: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise paths, one per (sigma, phi): (len(sigma), n)."""
    from scipy.signal import lfilter

    sigma, phi = np.atleast_1d(sigma), np.atleast_1d(phi)
    out = np.empty((sigma.size, n))
    for k in range(sigma.size):
        eps = rng.standard_normal(n) * sigma[k]
        eps[0] /= math.sqrt(1.0 - phi[k] ** 2)
        out[k] = lfilter([1.0], [1.0, -phi[k]], eps)
    return out


def predictive(run: PosteriorRun, records: Sequence[Record], n_draws: int = 200, level: float = 0.9,
               seed: int | None = 0) -> list[dict]:
    """Posterior predictive bands on records' scored windows and the share of measured samples inside.

    For ``n_draws`` kept states (evenly spaced) the model output is computed
    and an AR(1) (or iid) noise path with that state's sigma, phi added;
    ``observation`` bands include the noise (what a new measurement should
    fall in), ``model`` bands only the parameter uncertainty.
    """
    post = run.post
    rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 13]))
    b = run.conv.burn
    ch = run.chain[b:].reshape(-1, run.chain.shape[-1])
    dr = run.draws[b:].reshape(-1, run.draws.shape[-1])
    pick = np.linspace(0, ch.shape[0] - 1, min(n_draws, ch.shape[0])).round().astype(int)
    nl, sigma, phi = post.split(ch[pick])
    lin = dr[pick]
    lo_q, hi_q = (1 - level) / 2, 1 - (1 - level) / 2
    nl_names = post.nonlinear_names
    check = nl[:1] if len(nl_names) else np.zeros((1, 0))
    segs = build_segments(post.model, records, post.input_range, check)
    out = []
    for s in segs:
        Y = post.window_outputs(s, nl, lin)
        Yobs = Y + ar1_noise(s.n, sigma, phi, rng)
        mlo, mhi = np.quantile(Y, [lo_q, hi_q], axis=0)
        olo, ohi = np.quantile(Yobs, [lo_q, hi_q], axis=0)
        y = s.y
        out.append({
            "file": s.file, "frequency_hz": s.frequency_hz, "rows": s.n,
            "fraction_inside_observation_band": float(np.mean((y >= olo) & (y <= ohi))),
            "fraction_inside_model_band": float(np.mean((y >= mlo) & (y <= mhi))),
            "mean_observation_band_width": float(np.mean(ohi - olo)),
            "mean_model_band_width": float(np.mean(mhi - mlo)),
            "rms_error_of_median": float(np.sqrt(np.mean((np.median(Y, axis=0) - y) ** 2))),
            "_t": (np.arange(s.n) * s.dt), "_y": y, "_median": np.median(Y, axis=0),
            "_obs": (olo, ohi), "_model": (mlo, mhi),
        })
    return out


# --- synthetic data with AR(1) noise (calibration checks, benchmarks) ----------------------------
def simulated_ar1_dataset(model: HysteresisModel, params: Mapping[str, float], *, sigma: float, phi: float,
                          seed: int = 0, **protocol) -> Dataset:
    """The paper's protocol simulated from ``model`` with stationary AR(1) noise added to every record
    (innovation sd ``sigma``, coefficient ``phi`` per sample); ``protocol`` goes to
    ``benchmarks.protocol.simulated_dataset`` (n_periods, dt, frequencies, name)."""
    from hysbench.data.protocol import simulated_dataset

    ds = simulated_dataset(model, params, noise_sd=0.0, **protocol)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 17]))
    for r in ds.records:
        r.y = r.y + ar1_noise(r.y.size, np.array([sigma]), np.array([phi]), rng)[0]
    ds.description = (f"{ds.description}; stationary AR(1) noise per record, innovation sd {sigma:g}, "
                      f"phi {phi:g} per sample, seed {seed}")
    return ds
