"""Secondary causes ("also"): forward selection on top of the named cause (the backward step: ``backward``).

A cause on top is scored on held-out records against what is kept, the kept part's parameters held; one with
evidence there is judged on its score with the parameters it adds refitted per fold. A line on top takes its
frequency per fold from the other records (``lines``).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import NamedTuple

from .candidates import OPEN_ENDED_NOTE, Candidate, bound_flags, own_nonlinear
from .lines import fold_frequencies, fold_tolerance_hz, frequencies_agree, joint_line, on_top, on_top_estimates
from .policy import Policy
from .heldout import (carried_by_one_record, evidence, fold_uncertainty, heldout_errors, passes, promising, score,
                      share_of_misfit)
from .rule import NONE, UNEXPLAINED, Rule, Verdict, step


def refit_errors(screen, folds, result: dict, c: Candidate):
    """A candidate's out-of-fold residuals with its own nonlinear parameters refitted per fold."""
    if c.heldout.get("refit_per_fold") and c in result["heldout"]:
        return result["heldout"].of(c)
    return heldout_errors(screen, folds, c, refit=True)[0]


@dataclass
class _Kept:
    """What is kept so far: the separable part (None: the base alone), its held-out errors with its parameters
    held and per fold its training residual, the reference the next cause is scored against (the line included),
    an interference's frequency per fold (None: no line kept) and the part's designs (None: a clip)."""

    part: Candidate | None
    errors: object
    train: list
    reference: object
    frequency: list | None = None
    designs: list | None = None

    def with_line(self, screen, folds, part_e, part_train, part_designs=None):
        """A part's held-out errors with the kept line fitted jointly with it per fold, or on top of a clip."""
        if self.frequency is None:
            return part_e
        if part_designs:
            return joint_line(screen, folds, lambda m: part_designs[m], self.frequency).errors
        return on_top(screen, folds, part_e, part_train, self.frequency)


class Tried(NamedTuple):
    """A cause tried on top of what is kept (its score in ``composite.heldout``), the part then kept (as ``_Kept``),
    the errors with what is kept held and those it is judged on (its added parameters refitted per fold)."""

    composite: Candidate
    part: Candidate | None
    part_errors: object
    part_train: list
    errors: object
    judged: object
    designs: list | None


def _start(screen, folds, chosen: Candidate) -> _Kept:
    """The named cause as what is kept (an interference: the base with its line jointly fitted per fold)."""
    train, designs = [], []
    if chosen.kind.disturbance:  # the base's errors and training residuals: those of its joint fit
        base = screen.design(screen.base, screen.base_nl)
        lines = joint_line(screen, folds, lambda m: base)
        return _Kept(None, lines.part_errors, lines.train_residuals, lines.errors, lines.frequencies_hz,
                     [base] * folds.n)
    e = heldout_errors(screen, folds, chosen, train_residuals=train, designs=designs)[0]
    return _Kept(chosen, e, train, e, designs=designs or None)


def _folds_disagree(screen, fold_f: list) -> str:
    """Why lines the folds found apart are not one interference ("" if they agree)."""
    if frequencies_agree(screen, fold_f):
        return ""
    return (f"the folds found it at {', '.join(f'{f:.4g}' for f in fold_f)} Hz, further apart than the "
            f"resolution {fold_tolerance_hz(screen):.3g} Hz: not one line")


def _line_on_top(screen, folds, c: Candidate, kept: _Kept) -> Tried:
    """An interference on top of what is kept, its frequency and amplitude chosen per fold on the other records."""
    comp = copy.copy(c)
    if kept.designs:  # each fold's frequency chosen without its held-out record
        lines = joint_line(screen, folds, lambda m: kept.designs[m])
        fold_f, e, comp.estimates = lines.frequencies_hz, lines.errors, lines.estimates()  # what was scored
    else:
        fold_f = fold_frequencies(screen, kept.train)
        e = on_top(screen, folds, kept.errors, kept.train, fold_f)
        comp.estimates = on_top_estimates(screen, folds, kept.errors, kept.train, fold_f)
    comp.limit = screen.limit_of(c.cause, comp.estimates) or _folds_disagree(screen, fold_f)
    comp.heldout = {**score(folds, kept.reference, e), "at_bound": [], "refit_per_fold": True,
                    "fold_frequencies_hz": fold_f}
    return Tried(comp, kept.part, kept.errors, kept.train, e, e, kept.designs)


def _cause_on_top(screen, folds, c: Candidate, kept: _Kept, fresh: bool) -> Tried | None:
    """Another cause composed with what is kept, scored with what is kept held; if it passes, judged with only the
    parameters it adds refitted per fold."""
    comp = copy.copy(c) if kept.part is None else c.kind.on_top(screen, kept.part, c, fresh)
    if comp is None:
        return None
    part_train, part_designs = [], []
    part_e = heldout_errors(screen, folds, comp, train_residuals=part_train, designs=part_designs)[0]
    e = judged = kept.with_line(screen, folds, part_e, part_train, part_designs)
    flags = bound_flags(screen, comp) if kept.part is not None else {"at_bound": [], "open_ended": []}
    comp.heldout = {**score(folds, kept.reference, e), **flags, "refit_per_fold": False}
    if passes(comp, folds.policy):  # the honest score: the added cause's parameters refitted per fold
        refit_train, refit_designs = [], []
        held = set(kept.part.model.nonlinear_names) if kept.part is not None else set()
        refit_e, fold_est = heldout_errors(screen, folds, comp, refit=True, train_residuals=refit_train,
                                           only=[n for n in own_nonlinear(screen, comp) if n not in held],
                                           designs=refit_designs)
        judged = kept.with_line(screen, folds, refit_e, refit_train, refit_designs)
        comp.heldout = {**score(folds, kept.reference, judged), **flags, "refit_per_fold": True}
        comp.uncertainty = fold_uncertainty(screen, fold_est)
    return Tried(comp, comp, part_e, part_train, e, judged, part_designs or None)


def _choose(screen, folds, tried: list[Tried], reference) -> tuple[Tried | None, list[Candidate]]:
    """Of the passing causes tried, the one with fewest parameters that the best does not beat by ``z_same`` and
    that removes ``explain_share`` of what is kept leaves (as ``selection.decide``), and the others as good."""
    pol = folds.policy
    ok = [t for t in tried if passes(t.composite, pol)]
    if not ok:
        return None, []
    best = max(ok, key=lambda t: t.composite.heldout["gain"])
    for t in ok:  # of what is kept leaves beyond noise
        h = t.composite.heldout
        h["share_of_misfit"] = share_of_misfit(screen, float(reference @ reference), h["sse"])
    same = [t for t in ok if t is best or (score(folds, t.judged, best.judged)["z"] < pol.z_same
                                           and t.composite.heldout["share_of_misfit"] >= pol.explain_share)]
    chosen = min(same, key=lambda t: (t.composite.k, -t.composite.heldout["gain"]))
    alike = [t.composite for t in same if t is not chosen]  # not told apart here
    chosen.composite.heldout["as_good"] = [c.cause for c in alike]
    return chosen, alike


@dataclass(frozen=True)
class Forward:
    """What the forward selection kept on top of ``on`` (in order), what it tried, and the alternatives."""

    on: Candidate
    kept: tuple
    tried: tuple
    alternatives: tuple  # (a kept composite, [those as good])

    def entry(self) -> dict:
        return step("also", ", ".join(c.cause for c in self.kept) or "nothing", on_top_of=self.on.cause,
                    tried=[c.cause for c in self.tried])


def forward(ctx, on: Candidate, taken: set) -> Forward:
    """Forward selection on top of ``on`` (rule ``also``), the causes in ``taken`` not tried; on short records or
    with ``thorough`` every cause is searched afresh (a second cause can show only once the first is accounted
    for). What it tried and the alternatives are recorded on the diagnosis."""
    diag, screen, folds = ctx.diag, ctx.diag.screen, ctx.folds
    pol = folds.policy
    fresh = screen.small or bool(diag.settings.get("thorough"))

    def near_pass(c: Candidate) -> bool:  # passed or nearly passed against the base alone
        return not c.limit and (promising(c, pol) or (c.heldout_gain > 0 and c.heldout.get("z", 0.0) >= pol.z_pass))

    pool = {c.cause: c for c in diag.candidates if c.cause not in taken
            and not (c.kind.disturbance and c.limit)  # a drive-locked or too slow sinusoid: no disturbance
            and (fresh or near_pass(c))}
    kept, also, tried_all, alternatives = _start(screen, folds, on), [], [], []
    while pool and len(also) < pol.max_secondary:
        ctx.say(f"trying {', '.join(sorted(pool))} on top of {' + '.join([on.cause, *(a.cause for a in also)])}")
        tried = []
        for c in pool.values():
            if c.kind.disturbance:
                t = _line_on_top(screen, folds, c, kept) if kept.frequency is None else None
            else:
                t = _cause_on_top(screen, folds, c, kept, fresh)
            if t is not None:
                tried_all.append(t.composite)
                tried.append(t)
        pick, alike = _choose(screen, folds, tried, kept.reference)
        if pick is None:
            break
        comp = pick.composite
        alternatives.append((comp, alike))
        also.append(comp)
        pool.pop(comp.cause)
        kept = _Kept(pick.part, pick.part_errors, pick.part_train, pick.errors,
                     comp.heldout["fold_frequencies_hz"] if comp.kind.disturbance else kept.frequency, pick.designs)
        if not comp.kind.carries_others:  # nothing composes on top of a clip; a disturbance still adds
            pool = {k: v for k, v in pool.items() if v.kind.disturbance}
    diag.secondary_tried.extend(tried_all)
    diag.also_alternatives.extend(alternatives)
    return Forward(on, tuple(also), tuple(tried_all), tuple(alternatives))


def gather_also(ctx, v: Verdict) -> Forward | None:
    """The forward selection on the named cause, its ambiguous causes not tried (not after a completion)."""
    if not ctx.extend or v.chosen is None or v.also:
        return None
    return forward(ctx, v.chosen, {v.chosen.cause, *(c.cause for c in v.ambiguous_with)})


def decide_also(ev: Forward, v: Verdict, policy: Policy) -> tuple[Verdict, dict]:
    return replace(v, also=ev.kept), ev.entry()


ALSO = Rule("also", (
    "*Also (forward selection).* Every other cause is tried on top of what is kept, scored against what is "
    "kept; one with evidence, keeping its meaning and off its bounds is scored again with its added parameters "
    "refitted per fold, and judged on that. Among those, the one with fewest parameters that the best predicts "
    "no better than by {z_same} and that removes at least {explain_share} of what is kept leaves is kept; "
    "repeated while something is kept, up to {max_secondary} causes. On short records (or with `--thorough`) "
    "every cause is tried and searched afresh; otherwise only those that passed or nearly passed (promising, "
    "or G > 0 with z >= {z_pass}) against the base alone."), decide_also, gather_also)


@dataclass(frozen=True)
class Completion:
    """A candidate with the forward selection on it and the share of the base's held-out misfit all that is kept
    removes (0: nothing kept); for a promising one their score, every parameter refitted, and whether one record
    carries it."""

    candidate: Candidate
    forward: Forward
    share: float
    alone: float = 0.0  # what the candidate removes by itself
    score: dict | None = None
    one_record: bool = False


def _completed(v: Verdict, ev: Completion, reason: str) -> Verdict:
    return replace(v, cause=ev.candidate.cause, chosen=ev.candidate, ambiguous_with=(), reason=reason, partial=None,
                   remainder=None, also=ev.forward.kept)


def gather_partial(ctx, v: Verdict) -> Completion | None:
    """The forward selection on an ``unexplained`` verdict's partial candidate that passes by itself."""
    p, pol = v.partial, ctx.policy
    if not ctx.extend or v.cause != UNEXPLAINED or p is None or not passes(p, pol):
        return None
    ctx.say(f"completing {p.cause}, which explains part of the misfit, with other causes on top")
    fwd = forward(ctx, p, {p.cause})
    null_sse = float(ctx.held.null @ ctx.held.null)
    share = share_of_misfit(ctx.diag.screen, null_sse, fwd.kept[-1].heldout["sse"]) if fwd.kept else 0.0
    alone = p.heldout.get("share_of_misfit", share_of_misfit(ctx.diag.screen, null_sse, p.heldout["sse"]))
    return Completion(p, fwd, share, alone)


def decide_partial(ev: Completion, v: Verdict, policy: Policy) -> tuple[Verdict, list]:
    p, kept = ev.candidate, ev.forward.kept
    named = ev.share >= policy.explain_share
    entries = [ev.forward.entry(), step("complete-partial", p.cause if named else UNEXPLAINED, partial=p.cause,
                                        kept=[c.cause for c in kept], share_of_misfit=ev.share)]
    if not named:
        more = ("" if not ev.forward.tried else
                f"; with other causes tried on top of {p.cause}, what is kept removes {100 * ev.share:.0f} % "
                f"(< {100 * policy.explain_share:.0f} %)")
        return replace(v, reason=v.reason + more), entries
    reason = (f"predicts the held-out identification records better than the base model refitted the same way (gain "
              f"{100 * p.heldout_gain:.2f} %, z = {p.heldout['z']:.1f}) but removes only {100 * ev.alone:.0f} % of "
              f"the base model's held-out misfit beyond white noise by itself ({v.reason}); with "
              f"{' + '.join(a.cause for a in kept)} on top, each predicting the held-out records better than what "
              f"was kept before it, {100 * ev.share:.0f} % (two causes at once)")
    return _completed(v, ev, reason), entries


COMPLETE_PARTIAL = Rule("complete-partial", (
    "*Two causes at once, partial.* An `unexplained` verdict whose best partial candidate passes: the forward "
    "selection (`also`) runs on top of it; if what is then kept removes at least {explain_share} of the "
    "misfit, the partial candidate is named with the kept causes under `also`."), decide_partial, gather_partial)


def gather_promising(ctx, v: Verdict) -> Completion | None:
    """The forward selection on a ``none`` verdict's best promising candidate off its bounds, all that is kept
    scored against the base with every parameter refitted per fold."""
    pol = ctx.policy
    pool = [c for c in ctx.diag.candidates if promising(c, pol) and not c.heldout.get("at_bound")]
    if not ctx.extend or v.cause != NONE or not pool:
        return None
    p = max(pool, key=lambda c: c.heldout_gain)
    ctx.say(f"completing {p.cause}, which predicts the held-out records better but short of evidence, with other "
            "causes on top")
    fwd = forward(ctx, p, {p.cause})
    if not fwd.kept:
        return Completion(p, fwd, 0.0)
    screen, folds, e_null = ctx.diag.screen, ctx.folds, ctx.held.null
    e = refit_errors(screen, folds, ctx.result, fwd.kept[-1])
    h = score(folds, e_null, e)
    return Completion(p, fwd, share_of_misfit(screen, float(e_null @ e_null), h["sse"]), score=h,
                      one_record=carried_by_one_record(folds, e_null, e))


def decide_promising(ev: Completion, v: Verdict, policy: Policy) -> tuple[Verdict, list]:
    p, kept, h = ev.candidate, ev.forward.kept, ev.score
    named = bool(kept) and evidence(h, policy) and ev.share >= policy.explain_share and not ev.one_record
    entries = [ev.forward.entry(), step(
        "complete-promising", p.cause if named else NONE, promising=p.cause, kept=[c.cause for c in kept],
        **({"gain": h["gain"], "z": h["z"], "share_of_misfit": ev.share} if kept else {}))]
    if not named:
        more = ("" if not ev.forward.tried else
                f"; with other causes tried on top of {p.cause}, no combination predicts the held-out records "
                "better with evidence that more than one record carries and removes "
                f"{100 * policy.explain_share:.0f} % of the misfit")
        return replace(v, reason=v.reason + more), entries
    h1 = p.heldout
    reason = (f"predicts the held-out identification records better than the base model refitted the same way (gain "
              f"{100 * h1['gain']:.2f} %, better in {h1['folds_improved']} of {h1['n_folds']} records) but short of "
              f"evidence by itself (z = {h1['z']:.1f}); with {' + '.join(a.cause for a in kept)} on top, each "
              f"predicting the held-out records better than what was kept before it, all of them with every "
              f"parameter refitted per fold predict them better than the base model (gain {100 * h['gain']:.2f} %, "
              f"z = {h['z']:.1f}) and remove {100 * ev.share:.0f} % of its held-out misfit beyond white noise (two "
              "causes at once)")
    return _completed(v, ev, reason), entries


COMPLETE_PROMISING = Rule("complete-promising", (
    "*Two causes at once, promising.* A `none` verdict with a *promising* candidate (G >= {min_explained} "
    "in more than half of the records, keeping its meaning, off its bounds): the "
    "forward selection runs on top of the best such; if everything kept, every parameter refitted per fold, is "
    "evidence against the base that does not rest on one record and removes at least {explain_share}, it is "
    "named with them under `also`; otherwise the verdict stays `none`."), decide_promising, gather_promising)


def not_identified(c: Candidate) -> str:
    """Why a kept cause's parameters are not identified ("" if they are): out of its meaning, or at a bound."""
    pinned, open_ = c.heldout.get("at_bound"), c.heldout.get("open_ended")
    if c.limit or pinned:
        return c.limit or f"{', '.join(pinned)} at its search bound"
    return f"{', '.join(open_)} {OPEN_ENDED_NOTE}" if open_ else ""
