"""Information criteria and the effective sample size of correlated residuals (one home).

A Gaussian likelihood with residual variance at its maximum-likelihood value
rss / n gives -2 ln L = n ln(2 pi rss / n) + n (+ a constant from row weights).
Then AIC = -2 ln L + 2 k and BIC = -2 ln L + k ln n, k counting every fitted
parameter (the noise variance included, if the caller counts it).

Model error is smooth, so residuals are strongly autocorrelated and n samples
carry far fewer independent pieces of information. ``effective_sample_size``
is the AR(1) estimate sum_m n_m (1 - rho_m) / (1 + rho_m), rho_m the lag-1
autocorrelation of block m; ``aic``/``bic`` with ``n_effective`` scale the
likelihood term by n_effective / n and use ln n_effective in the BIC penalty.
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np


def minus_two_log_likelihood(rss: float, n: int, constant: float = 0.0) -> float:
    """-2 ln L of n Gaussian residuals with variance at its ML value rss / n (+ ``constant``)."""
    if n <= 0:
        raise ValueError(f"need at least one residual, got n = {n}")
    if not rss > 0:
        return -math.inf
    return n * math.log(2.0 * math.pi * rss / n) + n + constant


def aic(rss: float, n: int, k: int, n_effective: float | None = None, constant: float = 0.0) -> float:
    m2ll = minus_two_log_likelihood(rss, n, constant)
    scale = 1.0 if n_effective is None else n_effective / n
    return scale * m2ll + 2 * k


def bic(rss: float, n: int, k: int, n_effective: float | None = None, constant: float = 0.0) -> float:
    m2ll = minus_two_log_likelihood(rss, n, constant)
    if n_effective is None:
        return m2ll + k * math.log(n)
    return (n_effective / n) * m2ll + k * math.log(max(n_effective, 1.0))


def lag1_autocorrelation(residual: np.ndarray) -> float:
    """Lag-1 autocorrelation of a residual block (mean removed); 0 for a constant block."""
    e = np.asarray(residual, dtype=float)
    e = e - e.mean()
    den = float(e @ e)
    return float(e[1:] @ e[:-1]) / den if den > 0 and e.size > 1 else 0.0


def ar1_information_ratio(rho: float) -> float:
    """(1 - rho) / (1 + rho), rho clipped to [0, 0.999999]: independent samples per sample of an AR(1) series."""
    rho = min(max(rho, 0.0), 0.999999)
    return (1.0 - rho) / (1.0 + rho)


def effective_sample_size(blocks: Iterable[np.ndarray]) -> float:
    """AR(1) effective sample size of residual blocks: sum n_m (1 - rho_m) / (1 + rho_m)."""
    return float(sum(np.size(b) * ar1_information_ratio(lag1_autocorrelation(b)) for b in blocks))
