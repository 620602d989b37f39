"""Convergence, measured: autocorrelation times, burn-in, effective sample sizes, acceptance."""

from __future__ import annotations

import math
from dataclasses import dataclass

import emcee
import numpy as np

from ..errors import IdentificationError

TAU_FACTOR = 50  # chains after burn-in must be this many autocorrelation times long
BURN_TAUS = 5  # automatic burn-in: this many autocorrelation times
MIN_ACCEPTANCE = 0.05  # a walker accepting less is called stuck


# --- convergence -------------------------------------------------------------------
def autocorr_times(x: np.ndarray) -> np.ndarray:
    """emcee's integrated autocorrelation time per parameter of x (steps, walkers, params).

    Parameters that never change (e.g. fixed) get NaN, and so does a parameter on which some walker did not
    move over the whole window (emcee averages the walkers' autocorrelation functions, and a constant walker's
    is 0/0), or whose estimate is not positive (a window of a few steps); callers report NaN as "could not be
    estimated".
    """
    x = np.asarray(x, dtype=float)
    taus = np.full(x.shape[2], np.nan)
    for k in range(x.shape[2]):
        col = x[:, :, k]
        if x.shape[0] < 2 or not np.all(np.isfinite(col)) or np.all(col == col[0]):
            continue
        with np.errstate(invalid="ignore", divide="ignore"):  # a stuck walker: NaN, reported, not a warning
            t = float(emcee.autocorr.integrated_time(col[:, :, None], c=5, tol=0, quiet=True)[0])
        taus[k] = t if t > 0 else np.nan
    return taus


@dataclass
class Convergence:
    """Burn-in, autocorrelation times and effective sample sizes of a chain.

    Attributes
    ----------
    n_steps : int
        Steps in the chain, burn-in included.
    burn : int
        Steps discarded as burn-in.
    tau : numpy.ndarray
        Integrated autocorrelation time, in steps, on the kept chain: one per sampled coordinate, then one
        per linear parameter drawn (``PosteriorRun.reported_tau`` gives them in its ``names`` order).
    ess : numpy.ndarray
        Effective sample size of each, in the order of ``tau``.
    acceptance : numpy.ndarray
        Acceptance fraction of each walker, shape (walkers,).
    tau_factor : float
        The kept chain must be this many times ``tau_max`` long to count as converged.
    min_ess : float
        The effective sample size every parameter must reach for ``ess_met``.
    kept : int
        Steps after burn-in (a property).
    tau_max : float
        The largest finite ``tau`` (inf when none is finite; a property).
    length_in_tau : float
        ``kept / tau_max`` (a property).
    problems : list[str]
        Why the chain is not converged, in words (empty: converged; a property).
    converged : bool
        No ``problems`` (a property).
    ess_met : bool
        Every ``ess`` is finite and at least ``min_ess`` (a property).
    """

    n_steps: int
    burn: int
    tau: np.ndarray
    ess: np.ndarray
    acceptance: np.ndarray
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
        if self.kept < self.tau_factor:  # tau >= 1 for these chains: fewer steps cannot be long enough
            p.append(f"the chain after burn-in is {self.kept} steps long (< {self.tau_factor:g}), too short to "
                     f"measure its autocorrelation time: run more steps")
        elif self.length_in_tau < self.tau_factor:
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


