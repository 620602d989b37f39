"""Fit every candidate cause on the screen and score each on held-out records (``run_screen``)."""

from __future__ import annotations

from typing import Callable, Sequence

from .candidates import MAX_RELAXATION, Candidate, bound_flags
from .causes import CAUSES
from .heldout import (Folds, HeldOut, fold_uncertainty, heldout_errors, heldout_null, line_worth_refit, passes,
                      promising, score)
from .library_screen import library_screen
from .residuals import RecordResidual


def score_candidate(screen, held: HeldOut, c: Candidate, refit: bool = False) -> None:
    """Held-out score of ``c`` against the base's (its out-of-fold residuals added to ``held``); with ``refit``
    its own nonlinear parameters are refitted per fold, and their spread is its uncertainty."""
    folds = held.folds
    c.train_residuals = []
    e, fold_est = heldout_errors(screen, folds, c, refit=refit, train_residuals=c.train_residuals)
    c.heldout = {**score(folds, held.null, e), **bound_flags(screen, c), "refit_per_fold": refit}
    if refit:
        c.heldout.update(c.kind.fold_checks(screen, fold_est))
    if fold_est:
        c.uncertainty = fold_uncertainty(screen, fold_est)
    held.add(c, e)


def run_screen(screen, residuals: Sequence[RecordResidual], max_relaxation: int = MAX_RELAXATION,
               joint_nfev: int = 10, max_joint: int = 4, progress: Callable[[str], None] | None = None) -> dict:
    """Every candidate fitted (stage 1) and scored quickly; the best promising one of each cause refined (stage 2);
    a variant with a parameter at its bound one fewer (``Cause.one_fewer``); every finalist scored with its own
    nonlinear parameters refitted per fold. Returns {"library", "candidates" (best per cause),
    "relaxation_variants", "folds", "heldout" (``HeldOut``: the out-of-fold residuals of the base and of each)}."""
    say = progress or (lambda s: None)
    say("library screen (pysindy FROLS)")
    library = library_screen(screen, residuals)
    variants, cands = [], []  # variants: every order of a cause fitted in variants competes
    for kind in CAUSES.values():
        say(kind.name)
        (variants if kind.variants else cands).extend(kind.fit(screen, library, max_relaxation))
    say("held-out scores (leave one identification record out)")
    folds = Folds.of(screen)
    screen.null.train_residuals = []
    e_null = heldout_null(screen, folds, screen.null.train_residuals)
    held = HeldOut(folds, e_null)
    for c in variants + cands:
        score_candidate(screen, held, c)
    # stage 2: the base's nonlinear parameters free as well, for what predicts some of the held-out misfit
    best_of = {}
    for c in variants + cands:  # the best promising candidate of each cause
        if promising(c, screen.policy) and (c.cause not in best_of or c.heldout_gain > best_of[c.cause].heldout_gain):
            best_of[c.cause] = c
    for c in sorted(best_of.values(), key=lambda c: -c.heldout_gain)[:max_joint]:
        say(f"{c.label} (joint)")
        j = c.kind.joint(screen, c, joint_nfev)
        if j is not c:
            score_candidate(screen, held, j)
            if j.heldout_gain > c.heldout_gain:
                pool = variants if c in variants else cands
                pool[pool.index(c)] = j
    # a time constant at its bound: one fewer, from the others
    for c in [v for v in variants if promising(v, screen.policy)]:
        r = c.kind.one_fewer(screen, c, c.heldout["at_bound"])
        if r is None:
            continue
        say(f"{r.label} (from {c.label} without its pinned time constant)")
        # compared refitted per fold: with the parameters held, both have seen the left-out record
        score_candidate(screen, held, r, refit=True)
        same = [v for v in variants if v.hyperparameters["n_relaxation"] == r.hyperparameters["n_relaxation"]]
        if same and not same[0].heldout["refit_per_fold"]:
            score_candidate(screen, held, same[0], refit=True)
        if same and r.heldout_gain > same[0].heldout_gain:
            variants[variants.index(same[0])] = r
    say("held-out scores with each finalist's own parameters refitted per fold")
    for c in variants + cands:
        if (passes(c, screen.policy) or line_worth_refit(c, screen.policy)) and not c.heldout["refit_per_fold"]:
            score_candidate(screen, held, c, refit=True)
    best_relax = max(variants, key=lambda c: c.heldout_gain)
    return {"library": library, "candidates": [best_relax] + cands, "relaxation_variants": variants,
            "folds": folds, "heldout": held}
