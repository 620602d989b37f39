"""Secondary causes ("also"): forward selection on top of the named cause, then a backward step.

Every cause tried on top of what is kept is scored on held-out records
against what is kept, the kept part's parameters held as fitted on every
record on both sides. One that shows evidence there is scored again with
the parameters it adds (a time constant, a delay, a mode, a clip's level, a
line's frequency) refitted on each fold's training records, and judged on
that score: a secondary cause too is named only on records that took no
part in choosing its parameters, and the spread of its fold estimates is
their uncertainty. An interference on top takes its frequency per fold from
the other records, fitted there jointly with what is kept
(``interference.joint_line``; on top of a clip, on its residual:
``interference.fold_frequencies``), and is one line only if the folds agree
within their resolution; the causes tried on top of a named interference take
its frequency per fold too. The backward step names a new cause,
so it scores as the named cause's finalists are (``search.run_screen``):
every own nonlinear parameter refitted per fold.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Callable

from .candidates import Candidate
from .interference import (fold_frequencies, fold_tolerance_hz, frequencies_agree, joint_line, on_top,
                           on_top_estimates)
from .saturation import clip_on_top
from .policy import Policy
from .selection import (OPEN_ENDED_NOTE, Verdict, at_bound, bound_flags, carried_by_one_record, evidence,
                        fold_uncertainty, heldout_errors, own_nonlinear, passes, promising, score, share_of_misfit,
                        step)


def refit_errors(screen, folds, result: dict, c: Candidate):
    """A candidate's out-of-fold residuals with its own nonlinear parameters refitted per fold (those of
    ``search.run_screen`` when it was scored so there)."""
    if c.heldout.get("refit_per_fold") and id(c) in result["errors"]:
        return result["errors"][id(c)]
    return heldout_errors(screen, folds, c, refit=True)[0]


def _admissible(comp: Candidate, policy: Policy) -> bool:
    return evidence(comp.heldout, policy) and not comp.limit and not comp.heldout["at_bound"]


def added_names(screen, kept: Candidate | None, comp: Candidate) -> list[str]:
    """The nonlinear parameters a cause tried on top brings: the composite's own but not the kept part's."""
    held = set(kept.model.nonlinear_names) if kept is not None else set()
    return [n for n in own_nonlinear(screen, comp) if n not in held]


@dataclass
class _Kept:
    """What is kept so far: the separable part (None: the base alone), its held-out errors with its
    parameters held (per fold also its residual on the training rows, fitted on them alone), an
    interference's frequency per fold (None: no line kept), the reference the next cause is scored
    against (what is kept predicts, the line included), and per fold the stacked design of the separable part
    (None: a clip, not linear)."""

    part: Candidate | None
    errors: object
    train: list
    reference: object
    frequency: list | None = None
    designs: list | None = None

    def with_line(self, screen, folds, part_e, part_train, part_designs=None):
        """A part's held-out errors with the kept line (if one is kept): fitted jointly with the part on each
        fold's training records (``joint_line``), or on top of a clip's residual."""
        if self.frequency is None:
            return part_e
        if part_designs:
            return joint_line(screen, folds, lambda m: part_designs[m], self.frequency).errors
        return on_top(screen, folds, part_e, part_train, self.frequency)


def _start(screen, folds, chosen: Candidate) -> _Kept:
    """The named cause as what is kept; a named interference as the base with its line on top, its frequency
    per fold chosen on the other records as it was scored."""
    train, designs = [], []
    if chosen.cause == "interference":  # the base's errors and training residuals: those of its joint fit
        base = screen.design(screen.base, screen.base_nl)
        lines = joint_line(screen, folds, lambda m: base)
        return _Kept(None, lines.part_errors, lines.train_residuals, lines.errors, lines.frequencies_hz,
                     [base] * folds.n)
    e = heldout_errors(screen, folds, chosen, train_residuals=train, designs=designs)[0]
    return _Kept(chosen, e, train, e, designs=designs or None)


def _folds_disagree(screen, fold_f: list) -> str:
    """Why lines whose frequencies the folds chose apart are not one interference ("" if they agree)."""
    if frequencies_agree(screen, fold_f):
        return ""
    return (f"the folds found it at {', '.join(f'{f:.4g}' for f in fold_f)} Hz, further apart than the "
            f"resolution {fold_tolerance_hz(screen):.3g} Hz: not one line")


def _line_on_top(screen, folds, c: Candidate, kept: _Kept) -> tuple:
    """An interference on top of what is kept, its frequency and amplitude chosen per fold on the other
    records, from what is kept fitted on them alone, and checked at the frequencies scored."""
    comp = copy.copy(c)
    if kept.designs:  # each fold's frequency chosen without its held-out record
        lines = joint_line(screen, folds, lambda m: kept.designs[m])
        fold_f, e, comp.estimates = lines.frequencies_hz, lines.errors, lines.estimates()  # what was scored
    else:
        fold_f = fold_frequencies(screen, kept.train)
        e = on_top(screen, folds, kept.errors, kept.train, fold_f)
        comp.estimates = on_top_estimates(screen, folds, kept.errors, kept.train, fold_f)
    comp.limit = screen.limit_of("interference", comp.estimates) or _folds_disagree(screen, fold_f)
    comp.heldout = {**score(folds, kept.reference, e), "at_bound": [], "refit_per_fold": True,
                    "fold_frequencies_hz": fold_f}
    return comp, kept.part, kept.errors, kept.train, e, e, kept.designs


def _cause_on_top(screen, folds, c: Candidate, kept: _Kept, fresh: bool) -> tuple | None:
    """Another cause composed with what is kept (a clip: a clip of it), scored with what is kept held; if
    admissible, scored again with only the parameters it adds refitted per fold, and judged on that."""
    if c.cause == "saturation" and kept.part is not None:
        comp = clip_on_top(screen, kept.part)
    else:
        comp = copy.copy(c) if kept.part is None else screen.composite(kept.part, c, search=fresh)
    if comp is None:
        return None
    part_train, part_designs = [], []
    part_e = heldout_errors(screen, folds, comp, train_residuals=part_train, designs=part_designs)[0]
    e = judged = kept.with_line(screen, folds, part_e, part_train, part_designs)
    flags = bound_flags(screen, comp) if kept.part is not None else {"at_bound": [], "open_ended": []}
    comp.heldout = {**score(folds, kept.reference, e), **flags, "refit_per_fold": False}
    if _admissible(comp, folds.policy):  # the honest score: the added cause's parameters refitted per fold
        refit_train, refit_designs = [], []
        refit_e, fold_est = heldout_errors(screen, folds, comp, refit=True, train_residuals=refit_train,
                                           only=added_names(screen, kept.part, comp), designs=refit_designs)
        judged = kept.with_line(screen, folds, refit_e, refit_train, refit_designs)
        comp.heldout = {**score(folds, kept.reference, judged), **flags, "refit_per_fold": True}
        comp.uncertainty = fold_uncertainty(screen, fold_est)
    return comp, comp, part_e, part_train, e, judged, part_designs or None


def _choose(screen, folds, tried: list, reference) -> tuple[tuple | None, list[Candidate]]:
    """Of the admissible causes tried, the one with fewest parameters that the best does not beat by z >=
    ``z_same`` and that removes at least ``explain_share`` of what is kept leaves beyond noise (policy; as in
    ``selection.decide``), and the others as good (not told apart on these records; their names are listed
    with it)."""
    pol = folds.policy
    ok = [t for t in tried if _admissible(t[0], pol)]
    if not ok:
        return None, []
    best = max(ok, key=lambda t: t[0].heldout["gain"])
    for t in ok:  # of what is kept leaves beyond noise
        t[0].heldout["share_of_misfit"] = share_of_misfit(screen, float(reference @ reference), t[0].heldout["sse"])
    same = [t for t in ok if t is best or (score(folds, t[5], best[5])["z"] < pol.z_same
                                           and t[0].heldout["share_of_misfit"] >= pol.explain_share)]
    chosen = min(same, key=lambda t: (t[0].k, -t[0].heldout["gain"]))
    alike = [t[0] for t in same if t[0] is not chosen[0]]  # not told apart here
    chosen[0].heldout["as_good"] = [c.cause for c in alike]
    return chosen, alike


def secondary_causes(diag, result: dict, say: Callable[[str], None]) -> None:
    """``_forward`` (below), its outcome added to the trace."""
    tried = len(diag.secondary_tried)
    _forward(diag, result, say)
    diag.trace.append(step("also", ", ".join(c.cause for c in diag.also) or "nothing", on_top_of=diag.cause,
                           tried=[c.cause for c in diag.secondary_tried[tried:]]))


def _forward(diag, result: dict, say: Callable[[str], None]) -> None:
    """Forward selection on top of the named cause: in each round every other cause is added to what is
    kept so far (a composite whose added cause is searched afresh on top of it, ``Screen.composite``; an
    interference as a per-record sinusoid on top, ``_line_on_top``; a clip as a clip of what is kept,
    ``saturation.clip_on_top``, after which only an interference composes) and scored on held-out records
    against what is kept, the parameters of what is kept held on both sides as fitted on every record.
    Those with held-out evidence are scored again with the added cause's own nonlinear parameters (a
    clip's level, a line's frequency) refitted per fold, and judged on that score: the added cause's
    parameters are then chosen without the record they predict. Of those that still show evidence, within
    the cause's meaning and off their search bounds, one is kept ("also"; ``_choose``). On short records
    (``Screen.small``), or on any with ``diag.settings["thorough"]``, every cause is tried and searched afresh,
    not only those that predict better than the base alone: a second cause can show only once the first is
    accounted for (a delay or a mode under a plant's own relaxation). Otherwise, on long records (cost: about
    three times the diagnosis on the default dataset), only those are tried, from their own fits. At most the
    policy's ``max_secondary`` are kept."""
    screen, chosen = diag.screen, diag.chosen
    folds = result["folds"]
    pol = folds.policy
    taken = {chosen.cause, *(c.cause for c in diag.verdict.ambiguous_with)}
    fresh = screen.small or bool(diag.settings.get("thorough"))

    def near_pass(c: Candidate) -> bool:  # passed or nearly passed against the base alone
        return not c.limit and (promising(c, pol) or (c.heldout_gain > 0 and c.heldout.get("z", 0.0) >= pol.z_pass))

    pool = {c.cause: c for c in diag.candidates if c.cause not in taken
            and not (c.cause == "interference" and c.limit)  # a drive-locked or too slow sinusoid: no disturbance
            and (fresh or near_pass(c))}
    kept = _start(screen, folds, chosen)
    while pool and len(diag.also) < pol.max_secondary:
        say(f"trying {', '.join(sorted(pool))} on top of {' + '.join([chosen.cause, *(a.cause for a in diag.also)])}")
        tried = []  # (composite, separable part, its errors and training residuals held, errors held, judged)
        for cause, c in pool.items():
            if cause == "interference":
                t = _line_on_top(screen, folds, c, kept) if kept.frequency is None else None
            else:
                t = _cause_on_top(screen, folds, c, kept, fresh)
            if t is not None:
                diag.secondary_tried.append(t[0])
                tried.append(t)
        pick, alike = _choose(screen, folds, tried, kept.reference)
        if pick is None:
            return
        comp, part, part_e, part_train, e, _, designs = pick
        diag.also_alternatives.append((comp, alike))
        diag.also.append(comp)
        pool.pop(comp.cause)
        kept = _Kept(part, part_e, part_train, e,
                     comp.heldout["fold_frequencies_hz"] if comp.cause == "interference" else kept.frequency, designs)
        if comp.cause == "saturation":  # nothing composes on top of a clip; an interference still adds
            pool = {k: v for k, v in pool.items() if k == "interference"}


def _forward_on(diag, result: dict, say: Callable[[str], None], p: Candidate) -> int:
    """Name ``p`` for now and run the forward selection on top of it; the number of causes it tried."""
    diag.verdict = Verdict(p.cause, p, [], "", diag.verdict.not_identified)
    tried = len(diag.secondary_tried)
    secondary_causes(diag, result, say)
    return len(diag.secondary_tried) - tried


def complete_partial(diag, result: dict, say: Callable[[str], None]) -> bool:
    """An ``unexplained`` verdict whose best partial cause passes the held-out test by itself but removes less
    than ``explain_share`` of the base's held-out misfit beyond noise: the forward selection is run on top of it
    (``secondary_causes``, each added cause judged on held-out records against what is kept). If what is then
    kept removes at least ``explain_share``, the partial cause is named with those under "also" (two causes at
    once: neither explains the misfit alone). Otherwise the verdict stays ``unexplained``. True if named."""
    v = diag.verdict
    p = v.partial
    pol = result["folds"].policy
    if v.cause != "unexplained" or p is None or not passes(p, pol):
        return False
    say(f"completing {p.cause}, which explains part of the misfit, with other causes on top")
    tried = _forward_on(diag, result, say, p)
    e_null = result["errors"][id(diag.screen.null)]
    null_sse = float(e_null @ e_null)
    share = (share_of_misfit(diag.screen, null_sse, diag.also[-1].heldout["sse"]) if diag.also else 0.0)
    diag.trace.append(step("complete-partial", p.cause if share >= pol.explain_share else "unexplained",
                           partial=p.cause, kept=[c.cause for c in diag.also], share_of_misfit=share))
    if share < pol.explain_share:
        diag.verdict, diag.also = v, []
        v.reason += ("" if not tried else
                     f"; with other causes tried on top of {p.cause}, what is kept removes {100 * share:.0f} % "
                     f"(< {100 * pol.explain_share:.0f} %)")
        return False
    alone = p.heldout.get("share_of_misfit", share_of_misfit(diag.screen, null_sse, p.heldout["sse"]))
    diag.verdict.reason = (
        f"predicts the held-out identification records better than the base model refitted the same way (gain "
        f"{100 * p.heldout_gain:.2f} %, z = {p.heldout['z']:.1f}) but removes only {100 * alone:.0f} % of the "
        f"base model's held-out misfit beyond white noise by itself ({v.reason}); with "
        f"{' + '.join(a.cause for a in diag.also)} on top, each predicting the held-out records better than what "
        f"was kept before it, {100 * share:.0f} % (two causes at once)")
    diag.verdict.partial = None
    return True


def complete_promising(diag, result: dict, say: Callable[[str], None]) -> bool:
    """A ``none`` verdict whose best candidate is promising (a held-out gain in most folds, within its meaning
    and off its bounds) but short of evidence by itself: the forward selection is run on top of it
    (``secondary_causes``). Two causes at once can each fall short alone, e.g. a delay that only the fastest
    drive shows on a plant that also relaxes. The promising cause is named with those kept under "also" only if
    all of them together, every nonlinear parameter refitted per fold, show held-out evidence against the base
    model that more than one record carries (``selection.carried_by_one_record``) and remove at least
    ``explain_share`` of its held-out misfit beyond noise; otherwise the verdict stays ``none``. True if named."""
    v, screen, folds = diag.verdict, diag.screen, result["folds"]
    pol = folds.policy
    pool = [c for c in diag.candidates if promising(c, pol) and not c.heldout.get("at_bound")]
    if v.cause != "none" or not pool:
        return False
    p = max(pool, key=lambda c: c.heldout_gain)
    say(f"completing {p.cause}, which predicts the held-out records better but short of evidence, with other causes "
        "on top")
    tried = _forward_on(diag, result, say, p)
    e_null = result["errors"][id(screen.null)]
    named = False
    if diag.also:
        e = refit_errors(screen, folds, result, diag.also[-1])
        h = score(folds, e_null, e)
        share = share_of_misfit(screen, float(e_null @ e_null), h["sse"])
        named = evidence(h, pol) and share >= pol.explain_share and not carried_by_one_record(folds, e_null, e)
    diag.trace.append(step("complete-promising", p.cause if named else "none", promising=p.cause,
                           kept=[c.cause for c in diag.also],
                           **({"gain": h["gain"], "z": h["z"], "share_of_misfit": share} if diag.also else {})))
    if not named:
        diag.verdict, diag.also = v, []
        if tried:
            v.reason += (f"; with other causes tried on top of {p.cause}, no combination predicts the held-out "
                         "records better with evidence that more than one record carries and removes "
                         f"{100 * pol.explain_share:.0f} % of the misfit")
        return False
    h1 = p.heldout
    diag.verdict.reason = (
        f"predicts the held-out identification records better than the base model refitted the same way (gain "
        f"{100 * h1['gain']:.2f} %, better in {h1['folds_improved']} of {h1['n_folds']} records) but short of "
        f"evidence by itself (z = {h1['z']:.1f}); with {' + '.join(a.cause for a in diag.also)} on top, each "
        f"predicting the held-out records better than what was kept before it, all of them with every parameter "
        f"refitted per fold predict them better than the base model (gain {100 * h['gain']:.2f} %, z = "
        f"{h['z']:.1f}) and remove {100 * share:.0f} % of its held-out misfit beyond white noise (two causes at once)")
    return True


def _chain(screen, own: dict, causes: list[str]) -> list[Candidate] | None:
    """The causes composed in order, each searched on top of the ones before (None if one does not compose)."""
    kept, chain = own[causes[0]], [own[causes[0]]]
    for cause in causes[1:]:
        kept = screen.composite(kept, own[cause], search=screen.small)
        if kept is None:
            return None
        chain.append(kept)
    return chain


def _creep_time_unidentified(screen, c: Candidate) -> bool:
    """A creep (alone or in a composite) whose only flaw is its time scale at an end: the fastest its meaning
    allows (``creep_periods`` drive periods) or the slowest searched (a straight drift over these records).
    Replacing a relaxation slower than every drive period, whose own time constant these records do not pin
    down either, it is what that relaxation's slow part is: a drift since the start, its time scale not
    identified."""
    parts = getattr(c.model, "components", (c.cause,))
    return ("creep" in parts and (c.cause == "creep" or not c.limit)
            and set(at_bound(screen, c)) <= {"creep_time"})


def _creep_end(screen, chain: list[Candidate]) -> dict | None:
    """The first creep in ``chain`` whose time scale sits at an end (None if none does): ``end`` ``limit`` (the
    fastest its meaning allows) or ``search`` (open-ended, the slowest searched), ``alone`` (creep first, before
    the others were composed on top), ``creep_time_s``."""
    for c in chain:
        flags = bound_flags(screen, c)
        if "creep_time" in flags["at_bound"] + flags["open_ended"]:  # lower end: its limit; upper: open-ended
            return {"end": "limit" if "creep_time" in flags["at_bound"] else "search",
                    "alone": c is chain[0] and len(chain) > 1, "creep_time_s": float(c.params["creep_time"])}
    return None


def _pinned_creep(end: dict | None) -> str:
    """What the backward step says of a creep whose time scale sits at an end (``_creep_end``; "" if none)."""
    if end is None:
        return ""
    where = "its limit" if end["end"] == "limit" else "the end of its search"
    return (f"creep's time scale{' alone' if end['alone'] else ''} sits at {where}, {end['creep_time_s']:.3g} s: "
            "not identified")


def not_identified(c: Candidate) -> str:
    """Why a kept cause's parameters are not identified ("" if they are): out of its meaning, or at a bound."""
    if c.limit:
        return c.limit
    pinned = c.heldout.get("at_bound") or []
    if pinned:
        return f"{', '.join(pinned)} at its search bound"
    open_ = c.heldout.get("open_ended") or []
    return f"{', '.join(open_)} {OPEN_ENDED_NOTE}" if open_ else ""


def strongest_first(own: dict, causes: list[str]) -> list[str]:
    """The causes ordered by what each predicts of the held-out records against the base alone (its own
    held-out gain), the strongest first, as a forward selection would add them. The order they were kept in
    on top of the named cause is no guide without it, and each is searched with the ones before it held: a
    delay searched before a larger creep takes up part of the drift, which the composite's refinement does not
    undo."""
    gain = {c: own[c].heldout_gain for c in causes}
    return sorted(causes, key=lambda c: -gain[c] if math.isfinite(gain[c]) else math.inf)


def replacements(chosen: Candidate, own: dict, causes: list[str], creep_min: float,
                 policy: Policy) -> list[list[str]]:
    """The orders the backward step composes in place of the named cause: the secondary causes strongest first;
    for a named relaxation slower than every drive period (its slowest time constant at least ``creep_min`` /
    ``creep_periods``), also the same with creep after them, standing for that slow part."""
    options = [strongest_first(own, causes)]
    if slow_relaxation(chosen, creep_min, policy) and "creep" in own and "creep" not in causes:
        options.append([*options[0], "creep"])
    return options


def slow_relaxation(chosen: Candidate, creep_min: float, policy: Policy) -> bool:
    """A relaxation whose slowest time constant is at least ``creep_min`` / ``creep_periods`` (slower than every
    drive period): creep may stand for that slow part."""
    return chosen.cause == "relaxation" and max(chosen.estimates["tau_s"]) >= creep_min / policy.creep_periods


def drop_redundant_primary(diag, result: dict, say: Callable[[str], None]) -> None:
    """Backward step after the forward one: with secondary causes kept, the named cause is dropped if the secondary
    causes alone (a composite, each searched on top of the ones before, the strongest first: ``strongest_first``)
    predict the held-out records as well as all of them together (together not better by z >= ``z_same``), show
    held-out evidence against the base, remove at least ``explain_share`` of its held-out misfit beyond white
    noise (as a cause named without a remainder must, ``selection.decide``), and are within their meaning and off
    their search bounds: the first of them is named, the others stay under "also". A named relaxation whose
    slowest time constant is longer than the longest drive period may be creep there
    (``selection.slow_relaxation_twin``): if the secondary causes alone do not do, they are tried again,
    strongest first, with creep after them, creep standing for that slow part (the weaker claim, as in
    ``selection.decide``); for such a relaxation a creep, appended or kept, may have its time scale at an end
    (``_creep_time_unidentified``). Every score here with the nonlinear parameters refitted per fold, since it
    names a new cause. Only for a clean verdict (no ambiguity, no unexplained remainder) of causes that compose
    (not interference or saturation)."""
    v, screen, folds = diag.verdict, diag.screen, result["folds"]
    pol = folds.policy
    causes = [c.cause for c in diag.also]
    if (not causes or v.chosen is None or v.ambiguous_with or v.remainder is not None
            or {"interference", "saturation"} & {v.chosen.cause, *causes}):
        return
    say(f"is {v.chosen.cause} still needed beside {' + '.join(causes)}?")
    own = {c.cause: c for c in diag.candidates}
    options = replacements(v.chosen, own, causes, screen.creep_min, pol)
    creep_may_stand_in = slow_relaxation(v.chosen, screen.creep_min, pol)
    together = None  # all of them, scored once a replacement is worth comparing
    e_null = result["errors"][id(screen.null)]
    null_sse = float(e_null @ e_null)
    for replacement in options:
        chain = _chain(screen, own, replacement)
        standing_in = len(replacement) > len(causes)  # creep last, for the relaxation's slowest part

        def flawed(c: Candidate) -> bool:  # outside its meaning or at a bound (creep for a slow relaxation: above)
            if creep_may_stand_in and _creep_time_unidentified(screen, c):
                return False
            return bool(c.limit or at_bound(screen, c))

        if chain is None or any(flawed(c) for c in chain):
            continue
        if together is None:
            together = refit_errors(screen, folds, result, diag.also[-1])
        errors = [refit_errors(screen, folds, result, c) for c in chain]
        without = score(folds, errors[-1], together)  # how much better all together predict
        explains = share_of_misfit(screen, null_sse, float(errors[-1] @ errors[-1])) >= pol.explain_share
        if without["z"] < pol.z_same and evidence(score(folds, e_null, errors[-1]), pol) and explains:
            break
    else:
        diag.trace.append(step("drop-redundant-primary", v.chosen.cause, also=causes))
        return
    old, first, kept = v.chosen, copy.copy(chain[0]), chain[-1]
    first.params = {**first.params, **{n: kept.params[n] for n in first.model.nonlinear_names if n in kept.params}}
    also = []
    for i, c in enumerate(chain[1:], start=1):  # each scored against the ones before it
        c.heldout = {**score(folds, errors[i - 1], errors[i]), **bound_flags(screen, c), "refit_per_fold": True}
        also.append(c)
    diag.dropped = old
    diag.also = also
    end = _creep_end(screen, chain)
    diag.trace.append(step("drop-redundant-primary", first.cause, dropped=old.cause, also=list(replacement[1:]),
                           creep_standing_in=standing_in, creep_time_end=end, z_together_over_without=without["z"]))
    v.chosen, v.cause = first, first.cause
    pinned = _pinned_creep(end)
    slow = ""
    if standing_in:
        slow = (f", with creep standing for its time constant of {max(old.estimates['tau_s']):.3g} s (slower than "
                f"every drive period{'; ' + pinned if pinned else ''}),")
    elif pinned:
        slow = f" ({pinned}; it stands for a time constant of {max(old.estimates['tau_s']):.3g} s)"
    how = (f"better without it (with it worse, z = {without['z']:.1f})" if without["z"] < 0 else
           f"as well without it (with it better by z = {without['z']:.1f} < {pol.z_same:g})")
    v.reason = (f"{' + '.join(causes)}, kept on top of {old.cause}{slow} predict the held-out records {how}: "
                f"{old.cause} is not needed, and "
                f"{first.cause} is named with {', '.join(replacement[1:]) or 'nothing'} also (first named: "
                f"{old.label}, held-out gain {100 * old.heldout_gain:.2f} %)")
