"""Creep in place of a named relaxation's slowest part.

Under drives of one mean level a first-order relaxation slower than every drive period and a drift
since the start are nearly the same function: the records do not show that the slow part depends on
the input. ``selection`` already names creep when creep alone predicts as well as the relaxation. When
the relaxation has faster time constants too, creep alone cannot; then the relaxation without its
slowest time constant plus creep (a composite, refined from both fits and scored like every finalist,
its nonlinear parameters refitted per fold) is compared with it. If that passes and the relaxation does
not predict better by z >= ``z_same`` (policy), the slow part is ambiguous between the two causes, and the
verdict says so.
"""

from __future__ import annotations

import copy

from .candidates import Candidate
from .search import score_candidate
from .selection import Folds, pairwise_z, passes


def slow_part_composite(screen, folds: Folds, errors: dict, chosen: Candidate | None, candidates, variants
                        ) -> Candidate | None:
    """The composite (relaxation without its slowest time constant) + creep, scored on held-out records
    (its out-of-fold residuals stored in ``errors``); None where the test does not apply."""
    if chosen is None or chosen.cause != "relaxation":
        return None
    taus = sorted(chosen.estimates["tau_s"])
    if len(taus) < 2 or taus[-1] < screen.creep_min / screen.policy.creep_periods:
        return None
    fewer = [v for v in variants if len(v.estimates["tau_s"]) == len(taus) - 1]
    creep = [c for c in candidates if c.cause == "creep"]
    if not fewer or not creep:
        return None
    fast = copy.copy(fewer[0])  # the faster time constants, and the named fit's base parameters
    fast.params = {**fewer[0].params, **{n: chosen.params[n] for n in screen.base_nl_names},
                   **{f"tau{i + 1}": t for i, t in enumerate(taus[:-1])}}
    slow = copy.copy(creep[0])  # creep starting at the slowest time constant, within creep's bounds
    lo, hi = screen.bounds_of(slow.model, "creep_time")
    slow.params = {**slow.params, "creep_time": min(max(taus[-1], 1.05 * lo), hi / 1.05)}
    comp = screen.composite(fast, slow)
    if comp is None:
        return None
    score_candidate(screen, folds, errors[id(screen.null)], errors, comp, refit=True)
    return comp


def predicts_as_well(folds: Folds, errors: dict, chosen: Candidate, comp: Candidate) -> bool:
    """The composite passes on its own and the named relaxation does not predict better by z >= ``z_same``."""
    return passes(comp, folds.policy) and pairwise_z(folds, errors, chosen, comp) < folds.policy.z_same
