"""``mpso``: a modified particle swarm optimiser over all parameters (the paper's identifier).

The paper's reference [33] is not available, so this is our documented
variant of the global-best PSO (Kennedy & Eberhart 1995) with these
modifications:

* **normalised search space**: every parameter is mapped to [0, 1] by its
  bounds, so one velocity scale fits parameters of very different size;
* **inertia schedule**: the inertia weight falls linearly from
  ``inertia_start`` = 0.7 to ``inertia_end`` = 0.2 over the iterations
  (the linearly decreasing inertia of Shi & Eberhart 1998, shifted lower),
  with acceleration coefficients c1 = c2 = 1.5;
* **velocity clamping** (the constriction used here, instead of Clerc's
  factor): every velocity component is clamped to +-``v_max`` = 0.05 of the
  normalised range;
* **bounds kept by reflection**: a particle that leaves [0, 1] is mirrored
  back inside and that velocity component is reversed and halved, so every
  evaluated position lies inside the bounds;
* **re-seeding of stalled particles**: a particle whose personal best has
  not improved for ``stall_iterations`` = 12 iterations is re-seeded at a
  uniformly random position with a small random velocity and forgets its
  personal best (the swarm's global best is kept);
* **initial swarm**: a Latin hypercube over the bounds (seeded), with the
  start point (the model's defaults, or ``start``) as particle 0.

Every iteration evaluates the whole swarm as one batch per record through
``model.simulate_window_batch`` (the batched numba kernel, parallel over
particles, storing only the scored window). The default budget
is ``swarm_size`` 40 x (``iterations`` 100 + 1) = 4,040 model evaluations.
The random stream is numpy's default_rng(seed): the same seed gives the same
result.

The defaults were chosen on data simulated from the paper's Table 2 MRPIM
(5 ms step, noise 0.01 mm) among a dozen variants (Shi-Eberhart 0.9 -> 0.4
with v_max 0.2, Clerc's constriction 0.7298 / 1.49618, stall limits 12, 25
and none, swarm 20 x 200 and 80 x 50), 3 to 5 seeds each: this one had the
lowest median fitness. Over 20 parameters and default bounds, none came
close to varpro's optimum within the budget.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.stats import qmc

from .base import Identifier
from .errors import IdentificationError
from .problem import Problem

class ParticleSwarm(Identifier):
    """hysbench's modified particle swarm (in the paper's spirit); see the module docstring."""

    name = "mpso"

    def __init__(self, swarm_size: int = 40, iterations: int = 100, inertia_start: float = 0.7,
                 inertia_end: float = 0.2, c1: float = 1.5, c2: float = 1.5, v_max: float = 0.05,
                 stall_iterations: int = 12):
        self.swarm_size = swarm_size
        self.iterations = iterations
        self.inertia_start = inertia_start
        self.inertia_end = inertia_end
        self.c1 = c1  # cognitive (personal best)
        self.c2 = c2  # social (global best)
        self.v_max = v_max  # velocity clamp, fraction of each normalised range
        self.stall_iterations = stall_iterations

    def check(self, model, problem=None) -> None:
        if self.inertia_end > self.inertia_start:
            raise IdentificationError("option inertia_end must not exceed inertia_start")
        if problem is not None and not (np.all(np.isfinite(problem.lower)) and np.all(np.isfinite(problem.upper))):
            raise IdentificationError(f"method 'mpso' needs finite bounds for every parameter of model {model.name!r}")

    def search(self, problem, seed, start, x0=None) -> dict:
        return run(problem, seed, start, **self.get_params())


OPTIONS = ParticleSwarm().get_params()


def reflect(z: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mirror positions back into [0, 1]; reverse and halve the velocity of a reflected component."""
    z = z.copy()
    v = v.copy()
    for _ in range(4):  # a velocity <= 1 needs at most one or two reflections
        low, high = z < 0.0, z > 1.0
        if not (low.any() or high.any()):
            break
        z[low] = -z[low]
        z[high] = 2.0 - z[high]
        v[low | high] *= -0.5
    return np.clip(z, 0.0, 1.0), v


def run(problem: Problem, seed: int | None, start: Mapping[str, float] | None, **options) -> dict:
    opts = {**OPTIONS, **options}
    rng = np.random.default_rng(seed)
    lo, hi = problem.lower, problem.upper
    span = hi - lo
    d = lo.size
    n = int(opts["swarm_size"])
    n_iter = int(opts["iterations"])
    v_max = float(opts["v_max"])

    def to_x(z):
        return lo + z * span

    z0 = np.where(span > 0, (problem.start_vector(start) - lo) / np.where(span > 0, span, 1.0), 0.5)
    z = qmc.LatinHypercube(d, seed=rng).random(n)
    z[0] = z0
    v = rng.uniform(-v_max, v_max, (n, d)) * 0.5
    f = problem.fitness_batch(to_x(z))
    p_best, p_f = z.copy(), f.copy()
    g = int(np.argmin(p_f))
    g_best, g_f = p_best[g].copy(), float(p_f[g])
    initial_best = g_f
    stall = np.zeros(n, dtype=int)
    n_reseeded = 0
    in_bounds = True
    for it in range(n_iter):
        w = opts["inertia_start"] + (opts["inertia_end"] - opts["inertia_start"]) * it / max(1, n_iter - 1)
        r1, r2 = rng.random((n, d)), rng.random((n, d))
        v = w * v + opts["c1"] * r1 * (p_best - z) + opts["c2"] * r2 * (g_best - z)
        np.clip(v, -v_max, v_max, out=v)
        z, v = reflect(z + v, v)
        in_bounds &= bool(np.all((z >= 0.0) & (z <= 1.0)))
        f = problem.fitness_batch(to_x(z))
        better = f < p_f
        p_best[better], p_f[better] = z[better], f[better]
        stall = np.where(better, 0, stall + 1)
        g = int(np.argmin(p_f))
        if p_f[g] < g_f:
            g_best, g_f = p_best[g].copy(), float(p_f[g])
        stalled = np.flatnonzero(stall >= opts["stall_iterations"])
        stalled = stalled[np.any(p_best[stalled] != g_best, axis=1)]  # the leader stays
        if stalled.size and it < n_iter - 1:
            z[stalled] = rng.random((stalled.size, d))
            v[stalled] = rng.uniform(-v_max, v_max, (stalled.size, d)) * 0.5
            p_best[stalled] = z[stalled]
            p_f[stalled] = np.inf  # forgotten: the next evaluation sets it
            stall[stalled] = 0
            n_reseeded += stalled.size
    diag = {
        "initial_best_fitness": initial_best,
        "iterations": n_iter,
        "swarm_size": n,
        "reseeded_particles": n_reseeded,
        "positions_in_bounds": in_bounds,
    }
    return {"x": to_x(g_best), "diagnostics": diag, "notes": []}
