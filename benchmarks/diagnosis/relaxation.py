"""Relaxation: first-order low-pass histories of the input (1, 2, ... time constants, greedy)."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from hysbench.models.extended import TAU_BOUNDS

from .candidates import MAX_RELAXATION, Candidate, is_log


def fit_relaxation(screen, max_relaxation: int = MAX_RELAXATION, seeds: Sequence[float] = (),
               powers: Sequence[int] = (1,), stop_threshold: float | None = None) -> list[Candidate]:
    """Relaxation variants of 1, 2, ... time constants, one more fitted while it lowers BIC by ``stop_threshold``
    (default: the policy's ``bic_threshold``)."""
    stop_threshold = screen.policy.bic_threshold if stop_threshold is None else stop_threshold
    T = screen.drive_time
    lo, hi = TAU_BOUNDS[0] * T, TAU_BOUNDS[1] * T
    grid = list(np.exp(np.linspace(math.log(lo), math.log(hi), 25))) + [float(s) for s in seeds if lo <= s <= hi]
    out, taus = [], []
    for k in range(1, max_relaxation + 1):
        model = screen.extension(("relaxation",), n_relaxation=k, relaxation_powers=list(powers))
        names = [f"tau{i}" for i in range(1, k + 1)]
        z, _ = screen.grid(model, [dict(zip(names, taus + [g])) for g in grid])
        if k > 1:
            z = screen.refine(model, z, [(n, True) for n in names])
        else:
            z = screen.line_search(model, "tau1", grid, log=True)
        taus = [z[n] for n in names]
        label = f"relaxation, {k} time constant{'s' if k > 1 else ''}"
        out.append(screen.candidate("relaxation", label, model, z,
                                  {"n_relaxation": k, "relaxation_powers": list(powers)}))
        if k > 1 and out[-1].bic > out[-2].bic - stop_threshold:  # one more did not help: stop
            break
    return out


def without_pinned(screen, c: Candidate, pinned: Sequence[str], max_nfev: int = 10) -> Candidate | None:
    """The relaxation of one time constant fewer: ``c``'s time constants at a search bound (``pinned``)
    dropped, the rest and the base's nonlinear parameters as ``c`` has them, then refined together. A time
    constant at its bound is not identified, and the nested variant started from ``c``'s other ones can
    find the fit its own greedy search missed. None if nothing is pinned or nothing would be left."""
    taus = [n for n in c.model.nonlinear_names if n.startswith("tau")]
    drop = [n for n in pinned if n in taus]
    kept = sorted(float(c.params[n]) for n in taus if n not in drop)
    if not drop or not kept:
        return None
    k = len(kept)
    hyper = {"n_relaxation": k, "relaxation_powers": list(c.hyperparameters.get("relaxation_powers", [1]))}
    model = screen.extension(("relaxation",), **hyper)
    start = {**{n: c.params[n] for n in model.nonlinear_names if n in c.params},
             **{f"tau{i}": v for i, v in enumerate(kept, 1)}}
    z = screen.refine(model, start, [(n, is_log(n)) for n in model.nonlinear_names], max_nfev=max_nfev)
    return screen.candidate("relaxation", f"relaxation, {k} time constant{'s' if k > 1 else ''}", model, z, hyper,
                            stage="joint")
