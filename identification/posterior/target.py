"""The target: log p(theta_N, log sigma, phi | y) of a partly linear model, linear parameters
integrated out (see the package docstring for the method and ``discrepancy`` for the
discrepancy term)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numba
import numpy as np

from hysbench.data.dataset import Record
from hysbench.data.periodic import periodic_proxy
from hysbench.models.base import HysteresisModel

from ..errors import IdentificationError
from ..likelihood import LinearMarginal, marginalise_linear, nonfinite_sets, whitened_gram
from ..problem import Problem
from .discrepancy import (DISCREPANCY_KINDS, DISCREPANCY_PRIOR_GAIN, discrepancy_names, relaxation_columns,
                          relaxation_times)

NOISE_MODELS = ("ar1", "iid")
SIGMA_PRIOR_RANGE = (1e-9, 10.0)  # times max |y|
REGRESSOR_CHUNK_BYTES = 40e6  # regressor matrices built at once (see LogPosterior.grams)
SERIAL_SAMPLES = 200_000  # below this many simulated samples (x parameter sets) per record, one thread


class _numba_threads:
    """Run numba's parallel kernels on ``n`` threads inside the block (None: leave as is)."""

    def __init__(self, n: int | None):
        self.n = n

    def __enter__(self):
        self.old = numba.get_num_threads()
        if self.n is not None:
            numba.set_num_threads(min(self.n, self.old))

    def __exit__(self, *exc):
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
    basis: np.ndarray | None = None  # (n, K) discrepancy columns on the window, from the whole record

    @property
    def n_basis(self) -> int:
        return 0 if self.basis is None else self.basis.shape[1]

    @property
    def n(self) -> int:
        return self.y.size


def build_segments(model: HysteresisModel, records: Sequence[Record], input_range, check_sets: np.ndarray,
                   shorten: bool = True, taus: np.ndarray | None = None) -> list[Segment]:
    """The fitted windows of ``records``, periodic ones shortened where verified.

    A proxy is kept only if its regressors equal the full record's (max abs
    difference <= 1e-9 x max |Phi|) at every nonlinear parameter set of
    ``check_sets``. With ``taus``, each segment carries the discrepancy's
    relaxation columns, computed on the whole record.
    """
    segments = []
    for r in records:
        basis = None if taus is None or not len(taus) else relaxation_columns(r.u, r.dt, taus, r.scored)
        seg = Segment(r.file, r.u, r.dt, r.scored, r.y[r.scored].copy(), r.frequency_hz, r.u.size, basis=basis)
        found = periodic_proxy(r) if shorten else None
        if found is not None:
            u_p, w_p = found
            full = model.windowed_regressors_batch(r.u, r.dt, check_sets, r.scored, input_range)
            short = model.windowed_regressors_batch(u_p, r.dt, check_sets, w_p, input_range)
            if np.max(np.abs(full - short)) <= 1e-9 * max(1.0, float(np.max(np.abs(full)))):
                seg = Segment(r.file, u_p, r.dt, w_p, seg.y, r.frequency_hz, r.u.size, proxy=True, basis=basis)
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
            note = "integrated out; drawn from its Gaussian conditional"
            if n.startswith("delta_"):
                note = "discrepancy coefficient (input relaxation); " + note
            out.append({"name": n, "prior": "normal", "mean": float(m), "sd": float(s), "sampled": False,
                        "note": note})
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
    sampler takes as log-probability and blobs. theta_L holds the model's
    linear parameters, then the discrepancy coefficients (``discrepancy``).

    Non-finite model outputs: a parameter set whose regressors are not all
    finite gets log posterior -inf (the sampler cannot move there) and is
    counted in ``n_nonfinite`` (reported with the run); a set whose linear
    precision is not positive definite likewise in ``n_singular``.
    """

    def __init__(self, model: HysteresisModel, records: Sequence[Record], noise: str = "ar1",
                 bounds: Mapping | None = None, shorten: bool = True, seed: int | None = 0,
                 start_nonlinear: np.ndarray | None = None, discrepancy: str = "relaxation",
                 others: Sequence[Record] = ()):
        # others: the dataset's other records, whose windows' output the prior's scale never reads (Problem.build)
        if discrepancy not in DISCREPANCY_KINDS:
            raise IdentificationError(f"unknown discrepancy {discrepancy!r}; choose one of "
                                      f"{', '.join(DISCREPANCY_KINDS)}")
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
        self.problem = Problem.build(model, records, bounds, others=others)
        self.input_range = self.problem.input_range
        names = model.param_names
        self.param_names = names
        self.nonlinear_names = model.nonlinear_names
        self.model_linear_names = model.linear_names
        self.discrepancy = discrepancy
        self.taus = relaxation_times(records) if discrepancy == "relaxation" else np.zeros(0)
        self.discrepancy_names = discrepancy_names(self.taus)
        self.linear_names = self.model_linear_names + self.discrepancy_names
        self.nl_idx = np.array([names.index(n) for n in self.nonlinear_names], dtype=int)
        self.lin_idx = np.array([names.index(n) for n in self.model_linear_names], dtype=int)
        lo, hi = self.problem.lower, self.problem.upper
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            bad = [n for n, a, b in zip(names, lo, hi) if not (math.isfinite(a) and math.isfinite(b) and b > a)]
            raise IdentificationError(f"posterior: the priors need finite bounds low < high for {', '.join(bad)}")
        y_scale = self.problem.scale.y
        k = len(self.taus)
        delta_sd = DISCREPANCY_PRIOR_GAIN * y_scale / self.problem.scale.u
        self.priors = Priors(
            nonlinear_names=self.nonlinear_names,
            nonlinear_lower=lo[self.nl_idx].copy(),
            nonlinear_upper=hi[self.nl_idx].copy(),
            linear_names=self.linear_names,
            linear_mean=np.concatenate([0.5 * (lo[self.lin_idx] + hi[self.lin_idx]), np.zeros(k)]),
            linear_sd=np.concatenate([0.5 * (hi[self.lin_idx] - lo[self.lin_idx]), np.full(k, delta_sd)]),
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
                                       np.array(checks, dtype=float).reshape(len(checks), n_nl), shorten,
                                       self.taus)
        self.n_rows = sum(s.n for s in self.segments)
        self.rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 7]))
        self.n_evaluations = 0
        self.n_nonfinite = 0  # parameter sets whose model output was not finite
        self.n_singular = 0  # parameter sets whose linear precision was not positive definite

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
    def design(self, segment: Segment, nl: np.ndarray) -> np.ndarray:
        """(n_sets, n_window, p + K): the model's regressors, then the discrepancy columns."""
        Phi = self.model.windowed_regressors_batch(segment.u, segment.dt, nl, segment.window, self.input_range)
        if not segment.n_basis:
            return Phi
        B = np.broadcast_to(segment.basis, (Phi.shape[0],) + segment.basis.shape)
        return np.concatenate([Phi, B], axis=2)

    def grams(self, nl: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Prewhitened Gram matrices of [Phi*, y*] summed over records, (n, p+1, p+1), and a mask
        of the sets whose regressors were not all finite (their Gram matrices are meaningless).

        Regressors are built for about ``REGRESSOR_CHUNK_BYTES`` worth of
        parameter sets at a time, so that a chunk is still in cache when its
        Gram matrices are formed. A short record is built for all sets at once
        on one thread: waking the thread pool would cost more than it saves.
        """
        p = len(self.linear_names)
        n_set = nl.shape[0]
        G = np.zeros((n_set, p + 1, p + 1))
        threads = numba.get_num_threads()
        for s in self.segments:
            small = s.u.size * n_set < SERIAL_SAMPLES
            per_set = int(REGRESSOR_CHUNK_BYTES // (8 * s.n * p))
            chunk = n_set if small else max(threads, per_set // threads * threads)  # whole rounds of threads
            shared = np.ascontiguousarray(s.basis.T) if s.n_basis else None
            with _numba_threads(1 if small else None):
                for a in range(0, n_set, chunk):
                    sl = slice(a, a + chunk)
                    Phi = self.model.windowed_regressors_batch(s.u, s.dt, nl[sl], s.window, self.input_range)
                    # time along the last axis: a view for the play models, whose sets are column-major
                    whitened_gram(np.transpose(Phi, (0, 2, 1)), s.y, phi[sl], G[sl], shared=shared)
        bad = nonfinite_sets(G)
        G[bad] = 0.0  # never used: those sets get log posterior -inf
        self.n_evaluations += n_set
        self.n_nonfinite += int(bad.sum())
        return G, bad

    def marginal(self, X: np.ndarray) -> tuple[np.ndarray, LinearMarginal | None, np.ndarray]:
        """(log posterior (n,), the linear marginal of the in-support rows, their indices)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        lp = self.log_prior(X)
        idx = np.flatnonzero(np.isfinite(lp))
        if idx.size == 0:
            return lp, None, idx
        nl, sigma, phi = self.split(X[idx])
        G, bad = self.grams(nl, phi)
        log_jac = len(self.segments) * 0.5 * np.log1p(-phi * phi)
        marg = marginalise_linear(G, sigma, self.n_rows, log_jac, self.priors.linear_mean,
                                  self.priors.linear_precision)
        self.n_singular += int(np.sum(~marg.ok & ~bad))
        marg.ok &= ~bad
        lp = lp.copy()
        lp[idx] = np.where(marg.ok, lp[idx] + marg.loglik, -np.inf)  # counted above, never silently
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
        P[:, self.lin_idx] = linear[:, : len(self.model_linear_names)]
        return P

    def window_outputs(self, segment: Segment, nl: np.ndarray, linear: np.ndarray, chunk: int = 8) -> np.ndarray:
        """Model outputs on a segment's window for parameter sets (n, n_window)."""
        nl, linear = np.atleast_2d(nl), np.atleast_2d(linear)
        out = np.empty((nl.shape[0], segment.n))
        for a in range(0, nl.shape[0], chunk):
            Phi = self.design(segment, nl[a:a + chunk])
            out[a:a + chunk] = np.einsum("bnp,bp->bn", Phi, linear[a:a + chunk])
        return out


