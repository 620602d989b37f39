"""``lsq``: nonlinear least squares over all parameters (scipy.optimize.least_squares).

The residual vector is the weighted stack of eq. 9 (rows sqrt(k_m / n_m)),
minimised with the bounded trust-region reflective method, each parameter
scaled by its bound width (``x_scale``). The Jacobian is by forward
differences, all n_params perturbed sets simulated as one batch per record
(``simulate_window_batch``, parallel over sets); a step that would leave the bounds
is taken backwards.

Starts: the start point (the model's defaults, or ``start``, or the result
of the previous stage when used as a polish: ``varpro+lsq``, ``mpso+lsq``),
plus ``n_starts`` - 1 further points drawn uniformly in the bounds (seeded);
the best result wins.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.optimize import least_squares

from .base import Identifier
from .errors import IdentificationError
from .jacobian import CachedResidual, forward_difference
from .problem import Problem

class LeastSquares(Identifier):
    """Nonlinear least squares over all parameters; see the module docstring."""

    name = "lsq"

    def __init__(self, n_starts: int = 1, max_nfev: int = 200, tol: float = 1e-10, fd_step: float = 1e-7):
        self.n_starts = n_starts
        self.max_nfev = max_nfev  # residual evaluations per start, as scipy counts them (Jacobians are extra)
        self.tol = tol  # ftol = xtol = gtol
        self.fd_step = fd_step  # forward-difference step, relative to each bound's width

    def search(self, problem, seed, start, x0=None) -> dict:
        return run(problem, seed, start, x0=x0, **self.get_params())


OPTIONS = LeastSquares().get_params()


def run(problem: Problem, seed: int | None, start: Mapping[str, float] | None, x0: np.ndarray | None = None,
        **options) -> dict:
    opts = {**OPTIONS, **options}
    rng = np.random.default_rng(seed)
    lo, hi = problem.lower, problem.upper
    free = hi > lo  # a parameter fixed by equal bounds is not varied
    width = np.where(free & np.isfinite(hi - lo), hi - lo, 1.0)
    step = opts["fd_step"] * width
    if opts["n_starts"] > 1 and not np.all(np.isfinite(hi - lo)):
        raise IdentificationError(f"method 'lsq' on model {problem.model.name!r}: random starts (n_starts > 1) "
                                  "need finite bounds for every parameter")
    base = problem.clip(np.asarray(x0, dtype=float)) if x0 is not None else problem.start_vector(start)
    starts = [base] + [lo + rng.random(lo.size) * (hi - lo) for _ in range(int(opts["n_starts"]) - 1)]

    def embed(Zf):  # free coordinates -> full parameter sets
        P = np.repeat(base[None], Zf.shape[0], axis=0)
        P[:, free] = Zf
        return P

    def compute(zf):
        r = problem.residuals_batch(embed(zf[None]))[0]
        problem.note(float(r @ r))
        return r

    residual = CachedResidual(compute)

    def jacobian(zf):
        J = forward_difference(lambda Z: problem.residuals_batch(embed(Z)), zf, residual(zf), step[free], hi[free])
        J[~np.isfinite(J)] = 0.0  # a non-finite perturbed set (counted by the problem) gives no slope
        return J

    best_x, best_f, searches = None, np.inf, []
    for x_s in starts:
        n0 = problem.n_evaluations
        base = x_s.copy()
        residual.clear()
        if not np.all(np.isfinite(residual(x_s[free]))):
            searches.append({"fitness": float("inf"), "status": -1, "message": "start is not finite",
                             "n_evaluations": problem.n_evaluations - n0})
            continue
        res = least_squares(residual, x_s[free], jac=jacobian, bounds=(lo[free], hi[free]), method="trf",
                            x_scale=width[free], ftol=opts["tol"], xtol=opts["tol"], gtol=opts["tol"],
                            max_nfev=int(opts["max_nfev"]))
        x = x_s.copy()
        x[free] = res.x
        f = float(2.0 * res.cost)
        searches.append({"fitness": f, "status": int(res.status), "message": str(res.message),
                         "n_evaluations": problem.n_evaluations - n0})
        if f < best_f:
            best_x, best_f = x, f
    if best_x is None:
        best_x = base
    return {"x": best_x, "diagnostics": {"local_searches": searches}, "notes": []}
