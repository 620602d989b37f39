"""Relaxation: first-order low-pass histories of the input (1, 2, ... time constants, greedy)."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from hysbench.models.extended import TAU_BOUNDS
from hysbench.models.filter_kernels import first_order_foh, lowpass1_bank

from ..candidates import Candidate, is_log
from ..cause import Cause, register
from ..heldout import pairwise_z, passes

LIBRARY_TAUS = 10  # time constants of the library screen's low-pass terms


def without_pinned(screen, c: Candidate, pinned: Sequence[str], max_nfev: int = 10) -> Candidate | None:
    """``c`` without its time constants at a search bound (``pinned``: not identified), refined from the rest (the
    nested variant so started can find what its own greedy search missed); None if none or nothing is left."""
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


@register
class Relaxation(Cause):
    name = "relaxation"
    units = {"tau_s": "s"}
    log_scale = ("tau",)
    reshapes = True
    variants = True
    slow_twin = "creep"

    def owns(self, parameter: str) -> bool:
        return parameter.startswith("tau")

    def library_terms(self, screen, y_hat_rows: np.ndarray):
        T = screen.drive_time
        taus = np.exp(np.linspace(math.log(TAU_BOUNDS[0] * T * 5), math.log(TAU_BOUNDS[1] * T / 5), LIBRARY_TAUS))

        def columns(r, y_hat, t):
            a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(float(tau), r.dt) for tau in taus)))
            lp = lowpass1_bank(np.ascontiguousarray(r.u), a, b0, b1)
            return [lp[j] for j in range(len(taus))]

        return [f"L_{t:.3g}s[u]" for t in taus], columns, [float(t) for t in taus]

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        """Variants of 1, 2, ... time constants (the library's as extra starts), one more fitted while it lowers
        BIC by ``bic_threshold``."""
        T = screen.drive_time
        lo, hi = TAU_BOUNDS[0] * T, TAU_BOUNDS[1] * T
        grid = list(np.exp(np.linspace(math.log(lo), math.log(hi), 25)))
        grid += [float(s) for s in library["relaxation_taus"] if lo <= s <= hi]
        out, taus = [], []
        for k in range(1, max_order + 1):
            model = screen.extension(("relaxation",), n_relaxation=k, relaxation_powers=[1])
            names = [f"tau{i}" for i in range(1, k + 1)]
            if k == 1:
                z = screen.line_search(model, "tau1", grid, log=True)
            else:
                z, _ = screen.grid(model, [dict(zip(names, taus + [g])) for g in grid])
                z = screen.refine(model, z, [(n, True) for n in names])
            taus = [z[n] for n in names]
            label = f"relaxation, {k} time constant{'s' if k > 1 else ''}"
            out.append(screen.candidate("relaxation", label, model, z, {"n_relaxation": k, "relaxation_powers": [1]}))
            if k > 1 and out[-1].bic > out[-2].bic - screen.policy.bic_threshold:  # one more did not help: stop
                break
        return out

    def estimates(self, params, model) -> dict:
        k = getattr(model, "n_relaxation", 0)
        return {"tau_s": sorted(float(params[f"tau{i}"]) for i in range(1, k + 1))}

    def from_fit(self, estimates: dict, params) -> dict:
        k = len(estimates["tau_s"])
        return {**estimates, "tau_s": sorted(float(params[f"tau{i}"]) for i in range(1, k + 1))}

    def limit(self, screen, estimates) -> str:
        pol, taus = screen.policy, estimates["tau_s"]
        if any(b < pol.duplicate_tau_ratio * a for a, b in zip(taus, taus[1:])):
            return (f"time constants closer than a factor {pol.duplicate_tau_ratio:g}: their difference is a "
                    "band-pass, not a relaxation")
        return ""

    def slowest_time_s(self, estimates) -> float | None:
        return max(estimates["tau_s"])

    def one_fewer(self, screen, c: Candidate, pinned: list) -> Candidate | None:
        return without_pinned(screen, c, pinned)

    def merged(self, chosen: Candidate, variants, held) -> Candidate:
        """A variant with two time constants closer than their fold spread (or a factor ``duplicate_tau_ratio``)
        gives way to the variant with one fewer, if that passes and does not predict worse by ``z_same``."""
        pol = held.folds.policy
        floor = math.log(pol.duplicate_tau_ratio)
        while len(taus := chosen.estimates["tau_s"]) > 1:
            ses = sorted(((chosen.params[n], v.get("relative_se", 0.0)) for n, v in chosen.uncertainty.items()),
                         key=lambda p: p[0])
            width = [s for _, s in ses] if len(ses) == len(taus) else [0.0] * len(taus)
            close = any(math.log(taus[i + 1] / taus[i]) < max(floor, 2 * max(width[i], width[i + 1]))
                        for i in range(len(taus) - 1))
            fewer = [v for v in variants if len(v.estimates["tau_s"]) == len(taus) - 1 and passes(v, pol)
                     and pairwise_z(held, chosen, v) < pol.z_same]
            if not (close and fewer):
                break
            chosen = fewer[0]
        return chosen
