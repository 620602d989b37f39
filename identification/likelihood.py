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
record by record. ``S = 0`` (a flat prior) is allowed; the result is then
defined up to a constant and needs Phi* of full column rank.
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


@njit(cache=True, parallel=True, fastmath=True)
def _whitened_gram(X, y, phis, out):
    """out[b] += Z Z' with Z = T_phi[b] [X[b]; y] (one AR(1) segment), X (B, m, n), out (B, m+1, m+1).

    Z is formed block by block (``_CHUNK`` samples) and multiplied in 4 x 4
    register tiles; the first sample is scaled by sqrt(1 - phi^2).
    """
    n_set, m, n = X.shape
    mp = ((m + 1 + 3) // 4) * 4
    for b in prange(n_set):
        phi = phis[b]
        head = np.sqrt(1.0 - phi * phi)
        buf = np.zeros((mp, _CHUNK))
        G = np.zeros((mp, mp))
        for t0 in range(0, n, _CHUNK):
            t1 = min(n, t0 + _CHUNK)
            width = t1 - t0
            for i in range(m + 1):
                for t in range(width):
                    k = t0 + t
                    cur = X[b, i, k] if i < m else y[k]
                    if k == 0:
                        buf[i, t] = head * cur
                    else:
                        prev = X[b, i, k - 1] if i < m else y[k - 1]
                        buf[i, t] = cur - phi * prev
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
                out[b, i, j] += v
                if j != i:
                    out[b, j, i] += v


def whitened_gram(X: np.ndarray, y: np.ndarray, phis: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Add the Gram matrices of the prewhitened augmented designs [X_b; y] to ``out``.

    X: (B, m, n), the regressors of one record with time along the last axis
    (``model.windowed_regressors_batch(...).transpose(0, 2, 1)``); y: (n,);
    phis: (B,). The record is one AR(1) segment. Returns out, (B, m+1, m+1),
    whose last row and column hold Phi*' y* and y*' y*.
    """
    X = np.ascontiguousarray(X, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    phis = np.ascontiguousarray(phis, dtype=float).reshape(-1)
    n_set, m, n = X.shape
    if y.shape != (n,) or phis.shape != (n_set,):
        raise IdentificationError(f"whitened_gram: shapes X {X.shape}, y {y.shape}, phis {phis.shape} do not match")
    if out is None:
        out = np.zeros((n_set, m + 1, m + 1))
    _whitened_gram(X, y, phis, out)
    return out


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
        n_set, p = self.mean.shape
        xi = rng.standard_normal((n_set, p))
        out = np.full((n_set, p), np.nan)
        for b in np.flatnonzero(self.ok):  # theta = mu + D^-1 L^-T xi
            out[b] = self.mean[b] + np.linalg.solve(self.chol[b].T, xi[b]) / self.scale[b]
        return out

    def covariance(self, b: int) -> np.ndarray:
        """P^-1 of set b."""
        Linv = np.linalg.inv(self.chol[b])
        return (Linv.T @ Linv) / np.outer(self.scale[b], self.scale[b])


def marginalise_linear(G: np.ndarray, sigma: np.ndarray, n_rows: int, log_jacobian: np.ndarray,
                       prior_mean: np.ndarray, prior_precision: np.ndarray | None) -> LinearMarginal:
    """Integrate the linear parameters out of a Gaussian linear model (module docstring).

    G: (B, p+1, p+1) Gram matrices of the prewhitened [Phi*, y*]; sigma: (B,);
    n_rows: N; log_jacobian: (B,) log|T| (sum of 1/2 log(1 - phi^2) over
    records); prior_mean: (p,); prior_precision: (p,) diagonal of S, or None
    for a flat prior (then the constant 1/2 log|S| is dropped).
    """
    G = np.asarray(G, dtype=float)
    n_set, p1, _ = G.shape
    p = p1 - 1
    s2 = np.asarray(sigma, dtype=float).reshape(n_set) ** 2
    Gxx, Gxy, Gyy = G[:, :p, :p], G[:, :p, p], G[:, p, p]
    flat = prior_precision is None
    S = np.zeros(p) if flat else np.asarray(prior_precision, dtype=float)
    m0 = np.asarray(prior_mean, dtype=float)
    P = Gxx / s2[:, None, None]
    P[:, np.arange(p), np.arange(p)] += S
    b = Gxy / s2[:, None] + S * m0
    diag = np.einsum("bii->bi", P)
    ok = np.all(diag > 0, axis=1) & np.all(np.isfinite(P), axis=(1, 2))
    D = np.sqrt(np.where(diag > 0, diag, 1.0))
    Ps = P / (D[:, :, None] * D[:, None, :])
    L = np.zeros_like(Ps)
    I = np.eye(p)
    try:
        L[ok] = np.linalg.cholesky(Ps[ok])
    except np.linalg.LinAlgError:  # some set is not positive definite: factor one by one
        for k in np.flatnonzero(ok):
            try:
                L[k] = np.linalg.cholesky(Ps[k])
            except np.linalg.LinAlgError:
                ok[k] = False
    L[~ok] = I
    w = np.linalg.solve(L, (b / D)[:, :, None])[:, :, 0]  # L w = D^-1 b
    mean = np.linalg.solve(np.transpose(L, (0, 2, 1)), w[:, :, None])[:, :, 0] / D
    logdet_P = 2.0 * np.sum(np.log(np.einsum("bii->bi", L)), axis=1) + 2.0 * np.sum(np.log(D), axis=1)
    quad = Gyy / s2 + float(m0 @ (S * m0)) - np.einsum("bi,bi->b", w, w)
    logdet_S = 0.0 if flat else float(np.sum(np.log(S)))
    loglik = (np.asarray(log_jacobian, dtype=float) - 0.5 * n_rows * np.log(2.0 * np.pi * s2)
              + 0.5 * logdet_S - 0.5 * logdet_P - 0.5 * quad)
    loglik = np.where(ok & np.isfinite(loglik), loglik, -np.inf)
    return LinearMarginal(loglik=loglik, mean=mean, chol=L, scale=D, ok=ok)
