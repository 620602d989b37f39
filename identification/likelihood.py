"""Gaussian likelihoods with AR(1) noise, and the linear parameters marginalised exactly.

Noise model. The residuals e = y - y_model of each record's fitted window are
a stationary AR(1) process, independent between records:

    e_1 ~ N(0, sigma^2 / (1 - phi^2)),   e_t = phi e_{t-1} + eps_t,   eps_t ~ N(0, sigma^2),   |phi| < 1.

``phi = 0`` is independent noise. We use the *exact* likelihood (the first
sample of each record keeps its stationary variance) rather than the
conditional one (which drops it): it costs nothing, keeps one record's
likelihood a proper density for every |phi| < 1, and the two differ by one
term per record. It is computed with the Prais-Winsten transform T:

    z_1 = sqrt(1 - phi^2) e_1,   z_t = e_t - phi e_{t-1}   (t > 1),   z ~ N(0, sigma^2 I),
    log p(e) = sum_records [ 1/2 log(1 - phi^2) ] - N/2 log(2 pi sigma^2) - |z|^2 / (2 sigma^2).

Linear parameters. For a model y = Phi(theta_N) theta_L, T is linear, so the
prewhitened regression T y = (T Phi) theta_L + z stays linear in theta_L. With
a Gaussian prior theta_L ~ N(m0, S^-1) the posterior of theta_L given
(theta_N, sigma, phi) is Gaussian, N(mu, P^-1), and theta_L integrates out:

    P  = Phi*' Phi* / sigma^2 + S,     b = Phi*' y* / sigma^2 + S m0,     mu = P^-1 b,
    log p(y | theta_N, sigma, phi) = log|T| - N/2 log(2 pi sigma^2) + 1/2 log|S| - 1/2 log|P|
                                     - 1/2 (y*' y* / sigma^2 + m0' S m0 - b' P^-1 b),

with Phi* = T Phi, y* = T y. Everything it needs is the Gram matrix of the
prewhitened augmented design [Phi*, y*], which ``whitened_gram`` accumulates
record by record. ``S = 0`` (a flat prior, density 1) is allowed: the result
is then the integral of the likelihood over theta_L, where 1/2 log|S| is
replaced by p/2 log(2 pi), and needs Phi* of full column rank.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .errors import IdentificationError


# --- AR(1) residual likelihood -------------------------------------------------
def prais_winsten(e: np.ndarray, phi: float) -> np.ndarray:
    """The whitening transform of one AR(1) segment, along the last axis."""
    e = np.asarray(e, dtype=float)
    z = np.empty_like(e)
    z[..., 0] = math.sqrt(1.0 - phi * phi) * e[..., 0]
    z[..., 1:] = e[..., 1:] - phi * e[..., :-1]
    return z


def ar1_loglik(residual_segments, sigma: float, phi: float) -> float:
    """Exact log-likelihood of independent AR(1) segments (one per record)."""
    if not (sigma > 0 and -1.0 < phi < 1.0):
        return -math.inf
    total, n = 0.0, 0
    for e in residual_segments:
        e = np.asarray(e, dtype=float)
        if e.size == 0:
            continue
        z = prais_winsten(e, phi)
        total += 0.5 * math.log1p(-phi * phi) - float(z @ z) / (2.0 * sigma * sigma)
        n += e.size
    return total - 0.5 * n * math.log(2.0 * math.pi * sigma * sigma)


# --- prewhitened Gram matrices -----------------------------------------------------
_CHUNK = 256  # time samples per block (the block stays in the L1/L2 cache)


# fast-math without the no-NaN/no-inf assumptions: a non-finite regressor must reach the diagonal
_GRAM_FASTMATH = {"reassoc", "contract", "arcp", "nsz", "afn"}


@njit(cache=True, fastmath=_GRAM_FASTMATH, nogil=True)
def _gram_one(X, S, y, phi, out):
    """out += Z Z' with Z = T_phi [X; S; y] (one AR(1) segment); X (m1, n), S (m2, n) rows
    shared by every set (may be empty), out (m+1, m+1), m = m1 + m2.

    Z is formed block by block (``_CHUNK`` samples) and multiplied in 4 x 4
    register tiles; the first sample is scaled by sqrt(1 - phi^2).
    """
    m1, n = X.shape
    m = m1 + S.shape[0]
    mp = ((m + 1 + 3) // 4) * 4
    head = np.sqrt(1.0 - phi * phi)
    buf = np.zeros((mp, _CHUNK))
    G = np.zeros((mp, mp))
    for t0 in range(0, n, _CHUNK):
        t1 = min(n, t0 + _CHUNK)
        width = t1 - t0
        first = 0
        if t0 == 0:
            for i in range(m1):
                buf[i, 0] = head * X[i, 0]
            for i in range(m1, m):
                buf[i, 0] = head * S[i - m1, 0]
            buf[m, 0] = head * y[0]
            first = 1
        for i in range(m1):
            for t in range(first, width):
                buf[i, t] = X[i, t0 + t] - phi * X[i, t0 + t - 1]
        for i in range(m1, m):
            for t in range(first, width):
                buf[i, t] = S[i - m1, t0 + t] - phi * S[i - m1, t0 + t - 1]
        for t in range(first, width):
            buf[m, t] = y[t0 + t] - phi * y[t0 + t - 1]
        for I in range(0, mp, 4):
            for J in range(I, mp, 4):
                a00 = a01 = a02 = a03 = a10 = a11 = a12 = a13 = 0.0
                a20 = a21 = a22 = a23 = a30 = a31 = a32 = a33 = 0.0
                for t in range(width):
                    x0 = buf[I, t]
                    x1 = buf[I + 1, t]
                    x2 = buf[I + 2, t]
                    x3 = buf[I + 3, t]
                    z0 = buf[J, t]
                    z1 = buf[J + 1, t]
                    z2 = buf[J + 2, t]
                    z3 = buf[J + 3, t]
                    a00 += x0 * z0
                    a01 += x0 * z1
                    a02 += x0 * z2
                    a03 += x0 * z3
                    a10 += x1 * z0
                    a11 += x1 * z1
                    a12 += x1 * z2
                    a13 += x1 * z3
                    a20 += x2 * z0
                    a21 += x2 * z1
                    a22 += x2 * z2
                    a23 += x2 * z3
                    a30 += x3 * z0
                    a31 += x3 * z1
                    a32 += x3 * z2
                    a33 += x3 * z3
                G[I, J] += a00
                G[I, J + 1] += a01
                G[I, J + 2] += a02
                G[I, J + 3] += a03
                G[I + 1, J] += a10
                G[I + 1, J + 1] += a11
                G[I + 1, J + 2] += a12
                G[I + 1, J + 3] += a13
                G[I + 2, J] += a20
                G[I + 2, J + 1] += a21
                G[I + 2, J + 2] += a22
                G[I + 2, J + 3] += a23
                G[I + 3, J] += a30
                G[I + 3, J + 1] += a31
                G[I + 3, J + 2] += a32
                G[I + 3, J + 3] += a33
    for i in range(m + 1):
        for j in range(i, m + 1):
            v = G[i, j]  # i <= j: an upper tile, or a diagonal tile (computed whole)
            out[i, j] += v
            if j != i:
                out[j, i] += v


@njit(cache=True, parallel=True)
def _whitened_gram_parallel(X, S, y, phis, out):
    for b in prange(X.shape[0]):
        _gram_one(X[b], S, y, phis[b], out[b])


@njit(cache=True)
def _whitened_gram_serial(X, S, y, phis, out):
    for b in range(X.shape[0]):
        _gram_one(X[b], S, y, phis[b], out[b])


# below this many multiply-adds a call runs on one thread: waking the thread pool costs more
PARALLEL_MIN_WORK = 4_000_000


def whitened_gram(X: np.ndarray, y: np.ndarray, phis: np.ndarray, out: np.ndarray | None = None,
                  shared: np.ndarray | None = None) -> np.ndarray:
    """Add the Gram matrices of the prewhitened augmented designs [X_b; shared; y] to ``out``.

    X: (B, m1, n), the regressors of one record with time along the last axis
    (``model.windowed_regressors_batch(...).transpose(0, 2, 1)``); shared: (m2, n),
    rows the same for every set (the discrepancy's columns), appended after X's; y: (n,);
    phis: (B,). The record is one AR(1) segment. Returns out, (B, m+1, m+1) with
    m = m1 + m2, whose last row and column hold Phi*' y* and y*' y*.
    A non-finite regressor makes that set's diagonal non-finite (see ``nonfinite_sets``).
    """
    X = np.ascontiguousarray(X, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    phis = np.ascontiguousarray(phis, dtype=float).reshape(-1)
    n_set, m1, n = X.shape
    S = np.zeros((0, n)) if shared is None else np.ascontiguousarray(shared, dtype=float)
    m = m1 + S.shape[0]
    if y.shape != (n,) or phis.shape != (n_set,) or S.shape[1:] != (n,):
        raise IdentificationError(f"whitened_gram: shapes X {X.shape}, shared {S.shape}, y {y.shape}, "
                                  f"phis {phis.shape} do not match")
    if out is None:
        out = np.zeros((n_set, m + 1, m + 1))
    if n_set > 1 and n_set * n * (m + 1) * (m + 2) // 2 >= PARALLEL_MIN_WORK:
        _whitened_gram_parallel(X, S, y, phis, out)
    else:
        _whitened_gram_serial(X, S, y, phis, out)
    return out


def nonfinite_sets(G: np.ndarray) -> np.ndarray:
    """(B,) True where a Gram matrix from ``whitened_gram`` is not finite on its diagonal: a
    regressor of that set was NaN or inf (its prewhitened square sums to NaN or inf)."""
    d = np.diagonal(G, axis1=1, axis2=2)
    return ~np.isfinite(d).all(axis=1)


# --- the linear parameters, integrated out --------------------------------------
@dataclass
class LinearMarginal:
    """Batched result of ``marginalise_linear``: one entry per parameter set."""

    loglik: np.ndarray  # (B,) log p(y | theta_N, sigma, phi), theta_L integrated out
    mean: np.ndarray  # (B, p) posterior mean of theta_L
    chol: np.ndarray  # (B, p, p) lower Cholesky factor L of the column-scaled precision D^-1 P D^-1
    scale: np.ndarray  # (B, p) D = sqrt(diag P)
    ok: np.ndarray  # (B,) False where P was not positive definite (loglik = -inf)

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """One draw of theta_L per set from N(mean, P^-1); NaN where not ok."""
        xi = rng.standard_normal(self.mean.shape)
        out = np.empty_like(self.mean)
        _draw_kernel(self.mean, self.chol, self.scale, xi, out)  # theta = mu + D^-1 L^-T xi
        out[~self.ok] = np.nan
        return out

    def covariance(self, b: int) -> np.ndarray:
        """P^-1 of set b."""
        Linv = np.linalg.inv(self.chol[b])
        return (Linv.T @ Linv) / np.outer(self.scale[b], self.scale[b])


@njit(cache=True)
def _marginal_kernel(G, s2, S, m0, n_rows, log_jac, logdet_S, loglik, mean, L, D, ok):
    """Per set b: P = Gxx/s2 + diag(S), Cholesky of D^-1 P D^-1, log marginal, posterior mean."""
    n_set = G.shape[0]
    p = G.shape[1] - 1
    m0Sm0 = 0.0
    for i in range(p):
        m0Sm0 += m0[i] * S[i] * m0[i]
    w = np.empty(p)
    for b in range(n_set):
        good = True
        for i in range(p):
            d = G[b, i, i] / s2[b] + S[i]
            if not (d > 0.0 and d < np.inf):
                good = False
                d = 1.0
            D[b, i] = np.sqrt(d)
        # L L' = D^-1 P D^-1 (Cholesky-Banachiewicz)
        logdet = 0.0
        for i in range(p):
            for j in range(i + 1):
                v = G[b, i, j] / s2[b] / (D[b, i] * D[b, j])
                if i == j:
                    v += S[i] / (D[b, i] * D[b, i])
                for k in range(j):
                    v -= L[b, i, k] * L[b, j, k]
                if i == j:
                    if not (v > 0.0):
                        good = False
                        v = 1.0
                    L[b, i, i] = np.sqrt(v)
                    logdet += 2.0 * np.log(L[b, i, i]) + 2.0 * np.log(D[b, i])
                else:
                    L[b, i, j] = v / L[b, j, j]
            for j in range(i + 1, p):
                L[b, i, j] = 0.0
        ok[b] = good
        if not good:
            loglik[b] = -np.inf
            for i in range(p):
                mean[b, i] = np.nan
            continue
        # L w = D^-1 b,  b = Gxy/s2 + S m0
        ww = 0.0
        for i in range(p):
            v = (G[b, i, p] / s2[b] + S[i] * m0[i]) / D[b, i]
            for k in range(i):
                v -= L[b, i, k] * w[k]
            w[i] = v / L[b, i, i]
            ww += w[i] * w[i]
        # L' v = w, mean = v / D
        for i in range(p - 1, -1, -1):
            v = w[i]
            for k in range(i + 1, p):
                v -= L[b, k, i] * mean[b, k] * D[b, k]
            mean[b, i] = v / L[b, i, i] / D[b, i]
        quad = G[b, p, p] / s2[b] + m0Sm0 - ww
        loglik[b] = (log_jac[b] - 0.5 * n_rows * np.log(2.0 * np.pi * s2[b]) + 0.5 * logdet_S - 0.5 * logdet
                     - 0.5 * quad)


@njit(cache=True)
def _draw_kernel(mean, L, D, xi, out):
    """out[b] = mean[b] + D^-1 L^-T xi[b]."""
    n_set, p = mean.shape
    z = np.empty(p)
    for b in range(n_set):
        for i in range(p - 1, -1, -1):
            v = xi[b, i]
            for k in range(i + 1, p):
                v -= L[b, k, i] * z[k]
            z[i] = v / L[b, i, i]
        for i in range(p):
            out[b, i] = mean[b, i] + z[i] / D[b, i]


def marginalise_linear(G: np.ndarray, sigma: np.ndarray, n_rows: int, log_jacobian: np.ndarray,
                       prior_mean: np.ndarray, prior_precision: np.ndarray | None) -> LinearMarginal:
    """Integrate the linear parameters out of a Gaussian linear model (module docstring).

    G: (B, p+1, p+1) Gram matrices of the prewhitened [Phi*, y*]; sigma: (B,);
    n_rows: N; log_jacobian: (B,) log|T| (sum of 1/2 log(1 - phi^2) over
    records); prior_mean: (p,); prior_precision: (p,) diagonal of S, or None
    for a flat prior of density 1. The precision is factored after scaling
    its diagonal to one (D^-1 P D^-1 = L L'); a set whose P is not positive
    definite gets loglik -inf and ok False.
    """
    G = np.ascontiguousarray(G, dtype=float)
    n_set, p1, _ = G.shape
    p = p1 - 1
    s2 = np.ascontiguousarray(np.asarray(sigma, dtype=float).reshape(n_set) ** 2)
    flat = prior_precision is None
    S = np.zeros(p) if flat else np.ascontiguousarray(prior_precision, dtype=float)
    m0 = np.ascontiguousarray(prior_mean, dtype=float)
    logdet_S = p * math.log(2.0 * math.pi) if flat else float(np.sum(np.log(S)))
    loglik = np.empty(n_set)
    mean = np.empty((n_set, p))
    L = np.zeros((n_set, p, p))
    D = np.empty((n_set, p))
    ok = np.empty(n_set, dtype=np.bool_)
    log_jac = np.ascontiguousarray(np.broadcast_to(np.asarray(log_jacobian, dtype=float), (n_set,)))
    _marginal_kernel(G, s2, S, m0, float(n_rows), log_jac, logdet_S, loglik, mean, L, D, ok)
    loglik[~np.isfinite(loglik)] = -np.inf
    for b in np.flatnonzero(~ok):
        L[b] = np.eye(p)
        D[b] = 1.0
    return LinearMarginal(loglik=loglik, mean=mean, chol=L, scale=D, ok=ok)
