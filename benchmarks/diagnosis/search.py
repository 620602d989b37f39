"""Fit every candidate cause on the screen and score each on held-out records.

Order: the library screen (evidence, relaxation seeds); each cause's
extension with the base's nonlinear parameters held (stage 1); a quick
held-out score for each (``selection``); the passing ones refined with the
base's nonlinear parameters free (stage 2: the best of each cause, at most ``max_joint``) and scored
again; a relaxation with a time constant at its search bound gives the variant of one fewer, started from
its other ones (``relaxation.without_pinned``), which replaces that variant if it predicts better, both
with their own parameters refitted per fold; finally every passing candidate scored with its own nonlinear
parameters refitted per fold (the honest score, and the uncertainty).
"""

from __future__ import annotations

from typing import Callable, Sequence

from .candidates import MAX_RELAXATION, Candidate
from .creep import fit_creep
from .delay import fit_delay
from .interference import fit_interference, same_line
from .library_screen import library_screen
from .relaxation import fit_relaxation, without_pinned
from .residuals import RecordResidual
from .resonance import fit_resonance
from .saturation import fit_saturation, joint_saturation
from .selection import (Folds, bound_flags, fold_uncertainty, heldout_errors, heldout_null, line_worth_refit,
                        passes, promising, score)


def score_candidate(screen, folds: Folds, e_null, errors: dict, c: Candidate, refit: bool = False) -> None:
    """Held-out score of ``c`` (its out-of-fold residuals stored in ``errors``); with ``refit`` its own
    nonlinear parameters are refitted per fold, and their spread is its uncertainty."""
    c.train_residuals = []
    e, fold_est = heldout_errors(screen, folds, c, refit=refit, train_residuals=c.train_residuals)
    c.heldout = {**score(folds, e_null, e), **bound_flags(screen, c), "refit_per_fold": refit}
    if refit and c.cause == "interference":
        c.heldout["same_line"] = same_line(screen, fold_est)
    if fold_est:
        c.uncertainty = fold_uncertainty(screen, fold_est)
    errors[id(c)] = e


def run_screen(screen, residuals: Sequence[RecordResidual], max_relaxation: int = MAX_RELAXATION,
               joint_nfev: int = 10, max_joint: int = 4, progress: Callable[[str], None] | None = None) -> dict:
    """Every candidate fitted and scored; returns {"library", "candidates" (best per cause),
    "relaxation_variants", "folds", "errors" (out-of-fold residuals by id; the base's under id(screen.null))}."""
    say = progress or (lambda s: None)
    say("library screen (pysindy FROLS)")
    library = library_screen(screen, residuals)
    say("relaxation")
    variants = fit_relaxation(screen, max_relaxation, seeds=library["relaxation_taus"])
    cands = []
    for name, fit in (("delay", fit_delay), ("resonance", fit_resonance), ("creep", fit_creep),
                      ("interference", fit_interference), ("saturation", fit_saturation)):
        say(name)
        c = fit(screen)
        if c is not None:
            cands.append(c)
    say("held-out scores (leave one identification record out)")
    folds = Folds.of(screen)
    screen.null.train_residuals = []
    e_null = heldout_null(screen, folds, screen.null.train_residuals)
    errors = {id(screen.null): e_null}
    for c in variants + cands:
        score_candidate(screen, folds, e_null, errors, c)
    # stage 2: the base's nonlinear parameters free as well, for what predicts some of the held-out misfit
    best_of = {}
    for c in variants + cands:  # the best promising candidate of each cause
        if promising(c, screen.policy) and (c.cause not in best_of or c.heldout_gain > best_of[c.cause].heldout_gain):
            best_of[c.cause] = c
    for c in sorted(best_of.values(), key=lambda c: -c.heldout_gain)[:max_joint]:
        say(f"{c.label} (joint)")
        j = joint_saturation(screen, c, joint_nfev) if c.cause == "saturation" else screen.joint(c, joint_nfev)
        if j is not c:
            score_candidate(screen, folds, e_null, errors, j)
            if j.heldout_gain > c.heldout_gain:
                pool = variants if c in variants else cands
                pool[pool.index(c)] = j
    # a time constant at its bound: one fewer, from the others
    for c in [v for v in variants if promising(v, screen.policy)]:
        r = without_pinned(screen, c, c.heldout["at_bound"])
        if r is None:
            continue
        say(f"{r.label} (from {c.label} without its pinned time constant)")
        # compared refitted per fold: with the parameters held, both have seen the left-out record
        score_candidate(screen, folds, e_null, errors, r, refit=True)
        same = [v for v in variants if v.hyperparameters["n_relaxation"] == r.hyperparameters["n_relaxation"]]
        if same and not same[0].heldout["refit_per_fold"]:
            score_candidate(screen, folds, e_null, errors, same[0], refit=True)
        if same and r.heldout_gain > same[0].heldout_gain:
            variants[variants.index(same[0])] = r
    say("held-out scores with each finalist's own parameters refitted per fold")
    for c in variants + cands:
        if (passes(c, screen.policy) or line_worth_refit(c, screen.policy)) and not c.heldout["refit_per_fold"]:
            score_candidate(screen, folds, e_null, errors, c, refit=True)
    best_relax = max(variants, key=lambda c: c.heldout_gain)
    return {"library": library, "candidates": [best_relax] + cands, "relaxation_variants": variants,
            "folds": folds, "errors": errors}
