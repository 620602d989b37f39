"""The start: the varpro optimum, screened against Sobol points of the prior box, then Newton
steps to a posterior mode and its Laplace covariance, from which walkers are drawn (``modes``
runs the search from several candidates)."""

from __future__ import annotations

import numpy as np
from scipy.stats import qmc

from ..errors import IdentificationError
from .target import LogPosterior


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


def screen_candidates(post: LogPosterior, nl0: np.ndarray, sigma: float, phi: float, seed,
                      n: int = 64) -> np.ndarray:
    """nl0 and ``n`` scrambled Sobol points of the nonlinear prior box, best first by log posterior at
    the given noise parameters (one batched evaluation; non-finite last): the identifiers' optimum
    (weighted least squares) need not be near the mode under the AR(1) likelihood."""
    d = nl0.size
    if d == 0:
        return nl0[None]
    lo, hi = post.priors.nonlinear_lower, post.priors.nonlinear_upper
    pts = lo + qmc.Sobol(d, scramble=True, seed=np.random.default_rng(seed)).random(n) * (hi - lo)
    cands = np.vstack([nl0[None], pts])
    lp = post.log_prob(np.array([post.coords(c, sigma, phi) for c in cands]))
    return cands[np.argsort(-np.where(np.isfinite(lp), lp, -np.inf), kind="stable")]


def initial_walkers(post: LogPosterior, mode: np.ndarray, cov: np.ndarray, n_walkers: int,
                    rng: np.random.Generator) -> np.ndarray:
    """Walkers drawn from the Laplace Gaussian (or a diagonal ball), inside the prior support."""
    d = mode.size
    if n_walkers == 0:
        return np.empty((0, d))
    L = np.linalg.cholesky(cov + 1e-300 * np.eye(d))
    out = np.empty((0, d))
    for _ in range(100):
        cand = mode[None] + rng.standard_normal((4 * n_walkers, d)) @ L.T
        cand = cand[post.in_support(cand)]
        out = np.vstack([out, cand])
        if out.shape[0] >= n_walkers:
            return out[:n_walkers]
    raise IdentificationError("posterior: cannot place the walkers inside the prior support around the mode")



