"""Choosing the cause from the held-out scores of records that took no part in fitting it (``heldout``).

``decide`` applies the rules of ``SELECTION`` in order; their statements are the rule's text (``rules.rule_text``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from .candidates import DRIVE_LOCKED, OPEN_ENDED_NOTE, Candidate
from .heldout import HeldOut, carried_by_one_record, evidence, pairwise_z, passes, share_of_misfit
from .policy import Policy
from .rule import NONE, UNEXPLAINED, Rule, Verdict, apply, step

UNDECIDED = ""  # no rule has decided yet


def _score_of(c: Candidate) -> dict:
    h = c.heldout
    return {"cause": c.cause, "label": c.label, "gain": h.get("gain"), "z": h.get("z"),
            "share_of_misfit": h.get("share_of_misfit")}


def none_reason(candidates: Sequence[Candidate], policy: Policy) -> str:
    """Why nothing is named, said of the best candidate with its score."""
    best = max(candidates, key=lambda c: c.heldout_gain, default=None)
    if best is None or not best.heldout_gain > 0:
        return "no candidate predicts the held-out records better than the base model"
    h = best.heldout
    why = (f"outside its meaning ({best.limit})" if best.limit else
           "carried by one held-out record" if evidence(h, policy) else
           f"not evidence (z = {h['z']:.1f}, better in {h['folds_improved']} of {h['n_folds']} held-out records)")
    return (f"no candidate predicts the held-out records better than the base model with evidence and within its "
            f"meaning; the best, {best.label} (held-out gain {100 * best.heldout_gain:.2f} %), is {why}")


@dataclass(frozen=True)
class Scores:
    """What the cause is chosen on: the held-out residuals (its folds carry the policy), every candidate and
    relaxation variant once, the variants alone and whether the base's residual repeats from period to period."""

    screen: object
    held: HeldOut
    candidates: tuple
    variants: tuple
    structured: bool

    @property
    def e_null(self) -> np.ndarray:
        return self.held.null

    def share(self, c: Candidate) -> float:
        """The share of the base's held-out misfit beyond white noise that ``c`` removes."""
        return share_of_misfit(self.screen, float(self.e_null @ self.e_null), c.heldout["sse"])

    def passing(self, policy: Policy) -> list[Candidate]:
        return [c for c in self.candidates if passes(c, policy)]

    def best(self, policy: Policy) -> Candidate:
        return max(self.passing(policy), key=lambda c: c.heldout_gain)


def decide(screen, held: HeldOut, candidates: Sequence[Candidate], variants: Sequence[Candidate],
           structured: bool) -> Verdict:
    """``SELECTION`` applied in order (every variant competes, not only the best), with ``held.folds.policy``;
    the share of the misfit is recorded on every passing candidate."""
    pol = held.folds.policy
    ev = Scores(screen, held, tuple({id(c): c for c in [*candidates, *variants]}.values()), tuple(variants),
                structured)
    for c in ev.passing(pol):
        c.heldout["share_of_misfit"] = ev.share(c)
    v = Verdict(UNDECIDED, None, not_identified=unidentified(ev.candidates))
    for rule in SELECTION:
        v = apply(rule, ev, v, pol)
    if v.chosen is None and v.partial is not None and ev.passing(pol):  # a partial cause named first
        v.partial.heldout.setdefault("share_of_misfit", ev.share(v.partial))
    if v.chosen is not None:
        v.chosen.heldout.setdefault("share_of_misfit", ev.share(v.chosen))
        v = replace(v, reason=v.reason + loose_note(v.chosen, pol))
    return v


def unidentified(candidates: Sequence[Candidate]) -> list[str]:
    """The candidates that would predict something with a parameter at a search bound or open-ended."""
    out = [f"{c.cause}: {', '.join(c.heldout['at_bound'])} (at bound)" for c in candidates
           if c.heldout.get("at_bound") and c.heldout_gain > 0]
    out += [f"{c.cause}: {', '.join(c.heldout['open_ended'])} ({OPEN_ENDED_NOTE})" for c in candidates
            if c.heldout.get("open_ended") and not c.heldout.get("at_bound") and c.heldout_gain > 0]
    return list(dict.fromkeys(out))  # relaxation variants may repeat a line


def _predicts(c: Candidate) -> str:
    return (f"predicts the held-out identification records better than the base model refitted the same way "
            f"(gain {100 * c.heldout_gain:.2f} %, z = {c.heldout['z']:.1f})")


def _named_reason(c: Candidate, best: Candidate, policy: Policy) -> str:
    return _predicts(c) + (f"; simpler than {best.label}, which does not predict better by z >= {policy.z_same:g}"
                           if c is not best else "")


def nothing_passes(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if v.cause != UNDECIDED or ev.passing(pol):
        return v, None
    held = ev.held
    shown = [c for c in ev.candidates if (evidence(c.heldout, pol) or c.heldout_gain >= pol.strong_gain)
             and not carried_by_one_record(held.folds, ev.e_null, held.of(c))]  # partly predicted
    seen = {"structured": ev.structured, "evidence": [c.cause for c in shown]}
    if not (ev.structured or shown):
        return replace(v, cause=NONE, reason=none_reason(ev.candidates, pol)), step("nothing-passes", NONE, **seen)
    partial = max(shown, key=lambda c: c.heldout_gain) if shown else None
    why = ("the residual is structured (it repeats from period to period)" if ev.structured else
           f"{partial.label} predicts part of it on held-out records, but not consistently over the records "
           "or not within its meaning")
    return (replace(v, cause=UNEXPLAINED, partial=partial,
                    reason=why + "; no cause's extension predicts it on held-out records"),
            step("nothing-passes", UNEXPLAINED, **seen))


def simplest_as_good(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if v.cause != UNDECIDED:
        return v, None
    held, ok, best = ev.held, ev.passing(pol), ev.best(pol)
    # as good as the best: not worse by z >= z_same, and explaining enough of the misfit to be a verdict itself
    same = [c for c in ok if c is best or (pairwise_z(held, best, c) < pol.z_same and ev.share(c) >= pol.explain_share)]
    if ev.share(best) < pol.explain_share:  # a partial explanation: rivals for the same slice of it
        same += [c for c in ok if c is not best and pairwise_z(held, best, c) < pol.z_same
                 and same_slice(ev.e_null, held.of(best), held.of(c), pol) and identified(c, pol)]
    chosen = min(same, key=lambda c: (c.k, -c.heldout_gain))
    others = {}
    for c in same:
        if c.cause != chosen.cause and (c.cause not in others or c.heldout_gain > others[c.cause].heldout_gain):
            others[c.cause] = c
    return (replace(v, cause=chosen.cause, chosen=chosen, ambiguous_with=tuple(others.values()),
                    reason=_named_reason(chosen, best, pol)),
            step("simplest-as-good", chosen.cause, best=_score_of(best), as_good=[_score_of(c) for c in same],
                 passing=[_score_of(c) for c in ok]))


def merge_duplicates(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if v.chosen is None or v.remainder is not None:
        return v, None
    merged = v.chosen.kind.merged(v.chosen, ev.variants, ev.held)
    if merged is v.chosen:
        return v, None
    return (replace(v, chosen=merged, reason=_named_reason(merged, ev.best(pol), pol)),
            step("merge-duplicates", merged.label, named=v.chosen.label, tau_s=v.chosen.estimates["tau_s"]))


def slow_relaxation_twin(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    chosen = v.chosen
    if chosen is None or v.remainder is not None or not slower_than_drive(chosen, ev.screen.creep_min, pol):
        return v, None
    slowest = chosen.kind.slowest_time_s(chosen.estimates)
    twins = [c for c in ev.candidates if c.cause == chosen.kind.slow_twin and evidence(c.heldout, pol)
             and pairwise_z(ev.held, chosen, c) < pol.z_same]
    if not twins:
        return v, None
    twin = max(twins, key=lambda c: c.heldout_gain)
    # the weaker claim: a drift since the start, not a dependence on the input
    reason = (_predicts(twin) + f"; named rather than relaxation: the relaxation's slowest time constant "
              f"({slowest:.3g} s) is longer than the longest drive period, so these records do not show that it "
              f"depends on the input, and a drift since the start predicts them as well (z < {pol.z_same:g})")
    ambiguous = (chosen, *(c for c in v.ambiguous_with if c.cause != twin.cause))
    return (replace(v, cause=twin.cause, chosen=twin, ambiguous_with=ambiguous, reason=reason),
            step("slow-relaxation-twin", twin.cause, relaxation=_score_of(chosen), creep=_score_of(twin),
                 slowest_tau_s=slowest))


def slower_than_drive(c: Candidate, creep_min: float, policy: Policy) -> bool:
    """A cause with a slow twin, slower than every drive period: its twin may stand for that slow part."""
    kind = c.kind
    return kind.slow_twin is not None and kind.slowest_time_s(c.estimates) >= creep_min / policy.creep_periods


def _partial(ev: Scores, v: Verdict, pol: Policy) -> bool:  # and no partial rule has decided yet
    return v.chosen is not None and v.remainder is None and ev.share(v.chosen) < pol.explain_share


def _why_not(ev: Scores, v: Verdict, pol: Policy) -> dict:
    return why_not_specific(ev.held, v.chosen, ev.candidates, ev.best(pol), ev.e_null)


def partial_specific(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if not _partial(ev, v, pol) or _why_not(ev, v, pol)["text"]:
        return v, None
    share = ev.share(v.chosen)
    return (replace(v, remainder=1.0 - share, reason=(
        f"{v.reason}; it removes {100 * share:.0f} % of the base model's held-out misfit beyond white noise: "
        f"the other {100 * (1.0 - share):.0f} % is unexplained")),
        step("partial-specific", v.chosen.cause, share_of_misfit=share))


def specific_part_named(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if not _partial(ev, v, pol) or ev.held.folds.n_scored < pol.min_records_check:
        return v, None
    rivals = [c for c in sorted(ev.passing(pol), key=lambda c: -c.heldout_gain)
              if c is not v.chosen and c.cause != v.chosen.cause]
    other = next((c for c in rivals if not why_not_specific(ev.held, c, ev.candidates, c, ev.e_null)["text"]), None)
    if other is None:
        return v, None
    verdict_on, share = _why_not(ev, v, pol), ev.share(other)
    reason = (f"{_predicts(other)}; it removes {100 * share:.0f} % of the base model's held-out misfit beyond "
              f"white noise: the other {100 * (1 - share):.0f} % is unexplained ({v.chosen.label} predicts more "
              f"of it, but {verdict_on['text']})")
    return (replace(v, cause=other.cause, chosen=other, ambiguous_with=(), reason=reason, remainder=1.0 - share),
            step("specific-part", other.cause, partial=_score_of(v.chosen), named=_score_of(other),
                 not_specific={k: verdict_on[k] for k in ("why", "rivals")}))


def partial_not_specific(ev: Scores, v: Verdict, pol: Policy) -> tuple[Verdict, dict | None]:
    if not _partial(ev, v, pol):
        return v, None
    verdict_on, p = _why_not(ev, v, pol), v.chosen
    return (replace(v, cause=UNEXPLAINED, chosen=None, ambiguous_with=(), partial=p, reason=(
        f"the best-predicting cause ({p.cause}) removes only {100 * ev.share(p):.0f} % of the base model's "
        f"held-out misfit beyond white noise, and {verdict_on['text']}")),
        step("partial-not-specific", UNEXPLAINED, partial=_score_of(p),
             not_specific={k: verdict_on[k] for k in ("why", "rivals")}))


SELECTION = (
    Rule("nothing-passes", (
        "If nothing passes: the verdict is `unexplained` if the residual is structured (period-to-period F > "
        "{structure_f}) or some candidate has evidence or G >= {strong_gain} that does not rest on one record "
        "(with {min_records_check} or more records, it is still evidence without the record it improves most); "
        "otherwise `none`."), nothing_passes),
    Rule("simplest-as-good", (
        "Let *best* be the passing candidate with the highest G. The candidates *as good* are best and every "
        "passing candidate that predicts as well as best and removes at least {explain_share} of the misfit; if "
        "best removes less, also every passing candidate that predicts as well, removes the same part "
        "(improvements e_r - e with cosine >= {same_slice}) and is identified. The one with fewest parameters is "
        "named (ties: higher G); the as-good candidates of other causes are *ambiguous with* it."),
        simplest_as_good),
    Rule("merge-duplicates", (
        "A named relaxation with two time constants closer than the larger of a factor {duplicate_tau_ratio} "
        "and twice their fold spread gives way to the variant with one fewer, if that passes and predicts as "
        "well."), merge_duplicates),
    Rule("slow-relaxation-twin", (
        "A named relaxation whose slowest time constant is longer than the longest drive period (creep's least "
        "time scale / {creep_periods}) gives way to creep if creep has evidence and predicts as well; the "
        "relaxation is then ambiguous with it."), slow_relaxation_twin),
    Rule("partial-specific", (
        "If the named cause removes less than {explain_share} of the misfit it is named, with the rest as "
        "*unexplained remainder*, only if it is *specific*: the best predictor of that part has z >= {z_pass}, "
        "it is identified, and no rival that predicts as well removes another part (cosine < {same_slice}). "
        "Rivals: passing, identified candidates of other causes, and a drive-locked sinusoid with evidence."),
        partial_specific),
    Rule("specific-part", (
        "If it is not specific, the passing candidate with the highest G that is specific is named with the "
        "remainder (only with {min_records_check} or more records)."), specific_part_named),
    Rule("partial-not-specific", (
        "Otherwise the verdict is `unexplained`, with the named cause as the best partial candidate."),
        partial_not_specific),
)


def identified(c: Candidate, policy: Policy) -> bool:
    """The fold estimates of every identifying parameter (``Cause.identifying``) agree; not refitted per fold: no."""
    if not c.uncertainty:
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
    """What the reason says of a named cause's non-identifying parameters whose fold estimates do not agree."""
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
    """Two candidates remove the same part of the base's held-out misfit (their improvements' cosine)."""
    d_a, d_b = e_null - e_a, e_null - e_b
    norm = float(np.linalg.norm(d_a) * np.linalg.norm(d_b))
    return norm > 0 and float(d_a @ d_b) / norm >= policy.same_slice


def why_not_specific(held: HeldOut, chosen: Candidate, candidates: Sequence[Candidate], best: Candidate,
                     e_null: np.ndarray) -> dict:
    """Why a partial cause is not specific (rule ``partial-specific``): {"why": "" (specific), "z", "folds" or
    "rivals"; "rivals": their causes ("drive-locked": a sinusoid locked to the drive); "text": "" if specific}."""
    pol = held.folds.policy
    if best.heldout["z"] < pol.z_pass:
        return {"why": "z", "rivals": [], "text": f"its block test gives z = {best.heldout['z']:.1f} < {pol.z_pass:g}"}
    if not identified(chosen, pol):
        return {"why": "folds", "rivals": [],
                "text": f"its parameters differ between the folds by more than {100 * pol.partial_se:.0f} %"}
    rivals = [c for c in candidates if c.cause != chosen.cause and passes(c, pol) and identified(c, pol)]  # admissible
    # a sinusoid locked to the drive is no cause, but with evidence it shows a drive-locked misfit of its own
    rivals += [c for c in candidates if c.limit == DRIVE_LOCKED and evidence(c.heldout, pol)]
    close = [c for c in rivals if pairwise_z(held, chosen, c) < pol.z_same
             and not same_slice(e_null, held.of(chosen), held.of(c), pol)]
    if close:
        names = sorted({"a misfit locked to the drive" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        rivals = sorted({"drive-locked" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        return {"why": "rivals", "rivals": rivals,
                "text": f"{', '.join(names)} predicts the held-out records about as well, removing another part"}
    return {"why": "", "rivals": [], "text": ""}

