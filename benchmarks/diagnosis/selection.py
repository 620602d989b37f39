"""Choosing the cause on records that took no part in fitting it, from their held-out scores (``heldout``).

Decision rule (``decide``; every threshold named here is a field of the policy, ``policy.Policy``, carried by
the folds and the screen):

1. A candidate *passes* if G >= ``min_explained``, it improves more than half
   of the folds, z >= ``z_pass`` (or G >= ``strong_gain`` with every fold
   improved: a transient misfit concentrates in few blocks), its parameters
   are within the cause's meaning and none is at its search bound (else:
   "not identified (at bound)"). An interference whose frequency, searched
   on each fold's training records alone, and amplitude agree across the
   folds (one line) passes with any G > 0 if it improves every fold with
   z >= ``z_pass`` (``line_evidence``).
2. Parsimony: among the passing candidates that the best (highest G) does not
   beat by z >= ``z_same`` and that would be a verdict themselves (rule 3),
   the one with fewest parameters is named. Another cause in that set is
   reported as ambiguous with it, with the drive that would separate them
   (``experiment``). When the named relaxation's slowest time constant is
   longer than the longest drive period and creep predicts as well (a slow
   low-pass of a drive with one mean level and a drift since the start are
   nearly the same function), creep is named instead -- the weaker claim: the
   records do not show that the slow part depends on the input -- with the
   relaxation as ambiguous, even with creep's own time scale at its limit.
   Relaxation variants with time constants closer than a factor ``duplicate_tau_ratio`` are not
   admitted (two nearly equal low-passes with opposite gains are a band-pass,
   not a relaxation); closer than their fold uncertainty, the variant with one
   fewer is named if it predicts as well.
3. A named cause that removes less than ``explain_share`` of the base's
   held-out misfit beyond white noise (n sd^2) is still named, with the rest
   reported as unexplained remainder, if it is *specific*: the part it removes
   passes the block test (z >= ``z_pass``), its fold estimates agree within
   ``partial_se`` (a mode's: its frequency, ``Cause.identifying``; its damping is
   reported), and every other passing cause that predicts as well
   (z < ``z_same``) removes the *same* part (held-out improvements
   e_null - e with cosine >= ``same_slice``): those are rival explanations of
   one part, so the one with fewest parameters is named and the others are
   ambiguous with it (as in rule 2). A rival that removes another part makes
   it a guess -- if the rival's own parameters agree across the folds; one
   whose fold estimates disagree is no explanation either. So does a
   sinusoid at a drive harmonic with the same phase in every record (no
   interference: misfit locked to the drive) that has held-out evidence.
   If the best-predicting partial cause is not specific, another passing
   cause that is (by the same test, with ``min_records_check`` or more records) is named
   with the rest as unexplained remainder (``specific_part``).
   Otherwise the verdict is ``unexplained``; so it is if nothing passes
   while the residual is structured (a candidate has held-out evidence but
   fails the rest, or removes >= ``strong_gain`` of the held-out
   squared error in all though not in most records -- either still evidence
   without the record it improves most, ``carried_by_one_record`` -- or the
   residual repeats from period to period: ``residuals.periodic_structure``).
   Otherwise nothing passes: ``none``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .candidates import DRIVE_LOCKED, OPEN_ENDED_NOTE, Candidate
from .heldout import HeldOut, carried_by_one_record, pairwise_z, passes, share_of_misfit, significant
from .policy import Policy

NONE, UNEXPLAINED = "none", "unexplained"  # the verdicts that name no cause
@dataclass
class Verdict:
    cause: str  # none, unexplained or a vocabulary cause
    chosen: Candidate | None
    ambiguous_with: list[Candidate] = field(default_factory=list)
    reason: str = ""
    not_identified: list[str] = field(default_factory=list)  # "cause: parameter (at bound)"
    partial: Candidate | None = None  # the best candidate when the verdict is unexplained
    remainder: float | None = None  # share of the held-out misfit (beyond noise) the named cause leaves
    trace: list = field(default_factory=list)  # the rules that decided it, in order (``step``)


def step(rule: str, outcome: str, **inputs) -> dict:
    """One entry of a diagnosis's trace: the rule's id (docs/diagnosis.md, "The decision rule"), what it
    decided (a cause, ``none``, ``unexplained``, or what it changed) and the inputs it decided on."""
    return {"rule": rule, "outcome": outcome, "inputs": inputs}


def _score_of(c: Candidate) -> dict:
    h = c.heldout
    return {"cause": c.cause, "label": c.label, "gain": h.get("gain"), "z": h.get("z"),
            "share_of_misfit": h.get("share_of_misfit")}


def none_reason(candidates: Sequence[Candidate], policy: Policy) -> str:
    """Why nothing is named: no candidate predicts the held-out records better, or the best that does falls
    short of evidence (or only one record shows it), or outside its cause's meaning (said with its score)."""
    best = max(candidates, key=lambda c: c.heldout_gain, default=None)
    if best is None or not best.heldout_gain > 0:
        return "no candidate predicts the held-out records better than the base model"
    h = best.heldout
    why = (f"outside its meaning ({best.limit})" if best.limit else
           "carried by one held-out record" if significant(best, policy) else
           f"not evidence (z = {h['z']:.1f}, better in {h['folds_improved']} of {h['n_folds']} held-out records)")
    return (f"no candidate predicts the held-out records better than the base model with evidence and within its "
            f"meaning; the best, {best.label} (held-out gain {100 * best.heldout_gain:.2f} %), is {why}")


def decide(screen, held: HeldOut, candidates: Sequence[Candidate], variants: Sequence[Candidate],
           structured: bool) -> Verdict:
    """See the module docstring (every variant competes, not only the best); ``held``: the held-out residuals
    of the base model and the candidates. The thresholds: ``held.folds.policy``."""
    folds, e_null = held.folds, held.null
    pol = folds.policy
    null_sse = float(e_null @ e_null)
    candidates = list({id(c): c for c in [*candidates, *variants]}.values())
    ok = [c for c in candidates if passes(c, pol)]
    not_identified = [f"{c.cause}: {', '.join(c.heldout['at_bound'])} (at bound)" for c in candidates
                      if c.heldout.get("at_bound") and c.heldout_gain > 0]  # would predict something, unidentified
    not_identified += [f"{c.cause}: {', '.join(c.heldout['open_ended'])} ({OPEN_ENDED_NOTE})" for c in candidates
                       if c.heldout.get("open_ended") and not c.heldout.get("at_bound") and c.heldout_gain > 0]
    not_identified = list(dict.fromkeys(not_identified))  # relaxation variants may repeat a line
    evidence = [c for c in candidates if (significant(c, pol) or c.heldout_gain >= pol.strong_gain)  # partly predicted
                and not carried_by_one_record(folds, e_null, held.of(c))]
    if not ok:
        seen = {"structured": structured, "evidence": [c.cause for c in evidence]}
        if structured or evidence:
            partial = max(evidence, key=lambda c: c.heldout_gain) if evidence else None
            why = ("the residual is structured (it repeats from period to period)" if structured else
                   f"{partial.label} predicts part of it on held-out records, but not consistently over the records "
                   "or not within its meaning")
            return Verdict("unexplained", None, reason=why + "; no cause's extension predicts it on held-out records",
                           not_identified=not_identified, partial=partial,
                           trace=[step("nothing-passes", "unexplained", **seen)])
        return Verdict("none", None, reason=none_reason(candidates, pol), not_identified=not_identified,
                       trace=[step("nothing-passes", "none", **seen)])

    def record_share(c: Candidate) -> None:
        c.heldout["share_of_misfit"] = share_of_misfit(screen, null_sse, c.heldout["sse"])

    for c in ok:
        record_share(c)
    best = max(ok, key=lambda c: c.heldout_gain)
    # as good as the best: not worse by z >= z_same, and explaining enough of the misfit to be a verdict itself
    same = [c for c in ok if c is best or (pairwise_z(held, best, c) < pol.z_same
                                           and c.heldout["share_of_misfit"] >= pol.explain_share)]
    if best.heldout["share_of_misfit"] < pol.explain_share:  # a partial explanation: rivals for the same slice of it
        same += [c for c in ok if c is not best and pairwise_z(held, best, c) < pol.z_same
                 and same_slice(e_null, held.of(best), held.of(c), pol) and identified(c, pol)]
    chosen = min(same, key=lambda c: (c.k, -c.heldout_gain))
    trace = [step("simplest-as-good", chosen.cause, best=_score_of(best), as_good=[_score_of(c) for c in same],
                  passing=[c.cause for c in ok])]
    merged = chosen.kind.merged(chosen, variants, held)
    if merged is not chosen:
        trace.append(step("merge-duplicates", merged.label, named=chosen.label, tau_s=chosen.estimates["tau_s"]))
        chosen = merged
    others = {}
    for c in same:
        if c.cause != chosen.cause and (c.cause not in others or c.heldout_gain > others[c.cause].heldout_gain):
            others[c.cause] = c
    slow_twin = slow_relaxation_twin(screen, held, chosen, candidates)
    drift_note = ""
    if slow_twin is not None:  # the weaker claim: a drift since the start, not a dependence on the input
        others.pop(slow_twin.cause, None)
        others = {chosen.cause: chosen, **others}
        slowest = chosen.kind.slowest_time_s(chosen.estimates)
        drift_note = (f"; named rather than relaxation: the relaxation's slowest time constant "
                      f"({slowest:.3g} s) is longer than the longest drive period, so these "
                      "records do not show that it depends on the input, and a drift since the start predicts "
                      f"them as well (z < {pol.z_same:g})")
        trace.append(step("slow-relaxation-twin", slow_twin.cause, relaxation=_score_of(chosen),
                          creep=_score_of(slow_twin), slowest_tau_s=slowest))
        chosen = slow_twin
        if "share_of_misfit" not in chosen.heldout:
            record_share(chosen)
    share = chosen.heldout.get("share_of_misfit", 1.0)
    reason = (f"predicts the held-out identification records better than the base model refitted the same way "
              f"(gain {100 * chosen.heldout_gain:.2f} %, z = {chosen.heldout['z']:.1f})")
    if chosen is not best and not drift_note:
        reason += f"; simpler than {best.label}, which does not predict better by z >= {pol.z_same:g}"
    reason += drift_note
    remainder = None
    if share < pol.explain_share:
        verdict_on = why_not_specific(held, chosen, candidates, best, e_null)
        why_not = verdict_on["text"]
        not_named = {k: verdict_on[k] for k in ("why", "rivals")}
        if why_not:
            other = specific_part(held, ok, chosen, candidates, e_null)  # their shares recorded above
            if other is not None:
                share = other.heldout["share_of_misfit"]
                trace.append(step("specific-part", other.cause, partial=_score_of(chosen), named=_score_of(other),
                                  not_specific=not_named))
                return Verdict(other.cause, other, [], (
                    f"predicts the held-out identification records better than the base model refitted the same "
                    f"way (gain {100 * other.heldout_gain:.2f} %, z = {other.heldout['z']:.1f}); it removes "
                    f"{100 * share:.0f} % of the base model's held-out misfit beyond white noise: the other "
                    f"{100 * (1 - share):.0f} % is unexplained ({chosen.label} predicts more of it, but {why_not})"
                    + loose_note(other, pol)), not_identified, remainder=1.0 - share, trace=trace)
            trace.append(step("partial-not-specific", "unexplained", partial=_score_of(chosen), not_specific=not_named))
            return Verdict("unexplained", None, reason=(
                f"the best-predicting cause ({chosen.cause}) removes only {100 * share:.0f} % of the base model's "
                f"held-out misfit beyond white noise, and {why_not}"), not_identified=not_identified, partial=chosen,
                trace=trace)
        trace.append(step("partial-specific", chosen.cause, share_of_misfit=share))
        remainder = 1.0 - share
        reason += (f"; it removes {100 * share:.0f} % of the base model's held-out misfit beyond white noise: "
                   f"the other {100 * remainder:.0f} % is unexplained")
    return Verdict(chosen.cause, chosen, list(others.values()), reason + loose_note(chosen, pol), not_identified,
                   remainder=remainder, trace=trace)


def identified(c: Candidate, policy: Policy) -> bool:
    """Every parameter refitted per fold that identifies the cause agrees across the folds within
    ``partial_se`` (relative; a clipping level relative to the output's range); a candidate with none refitted
    per fold does not show it. A mode is identified by its frequency: its damping ratio, which drives far below
    the mode barely show, is reported with its fold spread but does not decide whether the mode is there."""
    if not c.uncertainty:  # nothing refitted per fold: agreement not shown
        return False
    only = c.kind.identifying
    return all(agrees(u, policy) for name, u in c.uncertainty.items() if only is None or name in only)


def agrees(u: dict, policy: Policy) -> bool:
    """One parameter's fold estimates (``fold_uncertainty``) agree within ``partial_se``: relative, a clipping
    level relative to the output's range, else relative to the folds' mean."""
    if "relative_se" in u or "se_over_range" in u:
        return u.get("relative_se", u.get("se_over_range")) <= policy.partial_se
    return u["se"] <= policy.partial_se * max(abs(float(np.mean(u["folds"]))), 1e-300)


def loose_note(c: Candidate, policy: Policy) -> str:
    """What the reason says of a named cause's parameters that do not identify it (``Cause.identifying``) and whose
    fold estimates differ by more than ``partial_se``: e.g. a mode's damping ratio."""
    only = c.kind.identifying
    if only is None:
        return ""
    loose = [f"{n} (fold spread ±{100 * u['relative_se']:.0f} %)" for n, u in c.uncertainty.items()
             if n not in only and not agrees(u, policy)]
    if not loose:
        return ""
    agree = f" (the folds agree on {', '.join(only)})" if identified(c, policy) else ""
    return f"; its {', '.join(loose)} not identified{agree}"


def same_slice(e_null: np.ndarray, e_a: np.ndarray, e_b: np.ndarray, policy: Policy) -> bool:
    """Two candidates remove the same part of the base's held-out misfit: their improvements (e_null - e)
    point the same way (cosine >= ``same_slice``)."""
    d_a, d_b = e_null - e_a, e_null - e_b
    norm = float(np.linalg.norm(d_a) * np.linalg.norm(d_b))
    return norm > 0 and float(d_a @ d_b) / norm >= policy.same_slice


def not_specific(held: HeldOut, chosen: Candidate, candidates: Sequence[Candidate],
                 best: Candidate | None = None, e_null: np.ndarray | None = None) -> str:
    """Why a cause that removes only part of the misfit is not named, as text ("" if it is): ``why_not_specific``."""
    return why_not_specific(held, chosen, candidates, best, e_null)["text"]


def why_not_specific(held: HeldOut, chosen: Candidate, candidates: Sequence[Candidate],
                     best: Candidate | None = None, e_null: np.ndarray | None = None) -> dict:
    """Why a cause that removes only part of the misfit is not named ("" if it is): the part it removes must
    pass the block test (z >= ``z_pass``, by the best predictor of that part), its parameters must agree across
    the folds, and every other passing cause that predicts about as well (z < ``z_same``), with its own parameters
    agreeing across the folds, must remove the same part (then it is ambiguous with it) -- when several causes
    each take a different slice of a misfit that is mostly something else, naming one of them would be a guess.
    A drive-locked sinusoid with held-out evidence counts as such a rival: it shows misfit locked to the drive.
    Returns {"why": "" (specific), "z", "folds" or "rivals"; "rivals": their causes ("drive-locked" for such a
    sinusoid); "text": the reason in words}."""
    best = best or chosen
    pol = held.folds.policy
    if best.heldout["z"] < pol.z_pass:
        return {"why": "z", "rivals": [], "text": f"its block test gives z = {best.heldout['z']:.1f} < {pol.z_pass:g}"}
    if not identified(chosen, pol):
        return {"why": "folds", "rivals": [],
                "text": f"its parameters differ between the folds by more than {100 * pol.partial_se:.0f} %"}
    rivals = [c for c in candidates if c.cause != chosen.cause and passes(c, pol) and identified(c, pol)]  # admissible
    # a sinusoid locked to the drive is no cause, but with evidence it shows a drive-locked misfit of its own
    rivals += [c for c in candidates if c.limit == DRIVE_LOCKED and significant(c, pol)]
    close = [c for c in rivals if pairwise_z(held, chosen, c) < pol.z_same
             and (e_null is None or not same_slice(e_null, held.of(chosen), held.of(c), pol))]
    if close:
        names = sorted({"a misfit locked to the drive" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        rivals = sorted({"drive-locked" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        return {"why": "rivals", "rivals": rivals,
                "text": f"{', '.join(names)} predicts the held-out records about as well, removing another part"}
    return {"why": "", "rivals": [], "text": ""}


def specific_part(held: HeldOut, ok: Sequence[Candidate], partial: Candidate,
                  candidates: Sequence[Candidate], e_null: np.ndarray) -> Candidate | None:
    """When the best-predicting partial explanation is not specific (``not_specific``), another passing cause
    that is -- its own part passes the block test, its parameters agree across the folds, and no admissible
    rival predicting about as well removes another part -- is named with the rest as unexplained remainder:
    e.g. an interference on top of a misfit that an unstable relaxation predicts partly. The one predicting
    most among those; None if there is none, or with fewer than ``min_records_check`` records (two fold
    estimates that agree are too weak a check to name a cause that does not predict best)."""
    if held.folds.n_scored < held.folds.policy.min_records_check:
        return None
    for c in sorted(ok, key=lambda c: -c.heldout_gain):
        if c is not partial and c.cause != partial.cause and not not_specific(held, c, candidates, c, e_null):
            return c
    return None


def slow_relaxation_twin(screen, held: HeldOut, chosen: Candidate,
                         candidates: Sequence[Candidate]) -> Candidate | None:
    """Creep, when the named relaxation's slowest time constant is longer than the longest drive period and
    creep predicts the held-out records as well (z < ``z_same``), even with its own time scale at its limit
    (``creep_periods`` drive periods): under drives of one mean level a slow low-pass of the input and a
    drift since the start are nearly the same function."""
    pol = held.folds.policy
    kind = chosen.kind
    if kind.slow_twin is None or kind.slowest_time_s(chosen.estimates) < screen.creep_min / pol.creep_periods:
        return None
    twins = [c for c in candidates if c.cause == kind.slow_twin and significant(c, pol)
             and pairwise_z(held, chosen, c) < pol.z_same]
    return max(twins, key=lambda c: c.heldout_gain) if twins else None
