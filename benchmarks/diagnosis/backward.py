"""The backward step after the forward one (``secondary``): is the named cause still needed beside the causes
kept on top of it? Scored as the named cause was: every own nonlinear parameter refitted per fold.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

from .candidates import Candidate, at_bound, bound_flags
from .causes import CAUSES, cause_of_parameter
from .heldout import evidence, score, share_of_misfit
from .policy import Policy
from .secondary import refit_errors
from .rule import Rule, Verdict, step
from .selection import slower_than_drive


def _chain(screen, own: dict, causes: list[str]) -> list[Candidate] | None:
    """The causes composed in order, each searched on top of the ones before (None if one does not compose)."""
    kept, chain = own[causes[0]], [own[causes[0]]]
    for cause in causes[1:]:
        kept = screen.composite(kept, own[cause], search=screen.small)
        if kept is None:
            return None
        chain.append(kept)
    return chain


def _time_unidentified(screen, c: Candidate, twin) -> bool:
    """A slow twin (alone or in a composite) whose only flaw is its time scale at an end: standing for a
    relaxation slower than every drive period, whose time constant these records do not pin down either, no flaw."""
    parts = getattr(c.model, "components", (c.cause,))
    return (twin.name in parts and (c.cause == twin.name or not c.limit)
            and set(at_bound(screen, c)) <= {twin.time_scale})


def _time_scale_end(screen, chain: list[Candidate]) -> tuple[str, dict | None]:
    """The first open-ended time scale in ``chain`` at an end, in words and as traced ("", None if none): ``end``:
    ``limit`` (the fastest its meaning allows) or ``search`` (the slowest searched), ``alone`` (before the others
    were composed on top), ``<parameter>_s``."""
    for c in chain:
        flags = bound_flags(screen, c)
        for n in (n for kind in CAUSES.values() for n in kind.open_ended):
            if n in flags["at_bound"] + flags["open_ended"]:  # lower end: its limit; upper: open-ended
                end = {"end": "limit" if n in flags["at_bound"] else "search",
                       "alone": c is chain[0] and len(chain) > 1, f"{n}_s": float(c.params[n])}
                where = "its limit" if end["end"] == "limit" else "the end of its search"
                return (f"{cause_of_parameter(n).name}'s time scale{' alone' if end['alone'] else ''} sits at "
                        f"{where}, {end[f'{n}_s']:.3g} s: not identified"), end
    return "", None


def slow_part_clause(old: Candidate, standing_in: bool, pinned: str) -> str:
    """What the reason says of the dropped cause's slow part: creep standing for it, or the time scale at an end."""
    slowest = old.kind.slowest_time_s(old.estimates)
    if standing_in:
        return (f", with creep standing for its time constant of {slowest:.3g} s (slower than "
                f"every drive period{'; ' + pinned if pinned else ''}),")
    if not pinned:
        return ""
    return f" ({pinned}; it stands for a time constant of {slowest:.3g} s)" if slowest is not None else f" ({pinned})"


def strongest_first(own: dict, causes: list[str]) -> list[str]:
    """The causes strongest first by their own held-out gain (a delay searched before a larger creep, with the
    ones before it held, would take up part of the drift)."""
    gain = {c: own[c].heldout_gain for c in causes}
    return sorted(causes, key=lambda c: -gain[c] if math.isfinite(gain[c]) else math.inf)


def replacements(chosen: Candidate, own: dict, causes: list[str], creep_min: float,
                 policy: Policy) -> list[list[str]]:
    """The orders composed in place of the named cause: the secondary causes strongest first, and for a cause
    slower than every drive period the same with its slow twin after them."""
    options = [strongest_first(own, causes)]
    twin = chosen.kind.slow_twin
    if slower_than_drive(chosen, creep_min, policy) and twin in own and twin not in causes:
        options.append([*options[0], twin])
    return options


@dataclass
class Option:
    """Causes tried in place of the named one, composed (``chain``; None: they do not compose); if no link is
    ``flawed``, scored with every parameter refitted per fold: ``without`` (all together against it; positive:
    together better), ``against_base``, ``share``. If accepted: the cause named (``first``), those kept with it
    (``also``) and the time scale at an end (``pinned``, ``end``: ``_time_scale_end``)."""

    causes: list
    chain: list | None
    flawed: bool = True
    without: dict | None = None
    against_base: dict | None = None
    share: float = 0.0
    standing_in: bool = False
    first: Candidate | None = None
    also: tuple = ()
    pinned: str = ""
    end: dict | None = None


def accepts(o: Option, policy: Policy) -> bool:
    return (not o.flawed and o.without["z"] < policy.z_same and evidence(o.against_base, policy)
            and o.share >= policy.explain_share)


def gather_backward(ctx, v: Verdict) -> list[Option] | None:
    """The replacements of a clean verdict of separable causes, scored in order until one is accepted."""
    causes = [c.cause for c in v.also]
    if (not ctx.extend or not causes or v.chosen is None or v.ambiguous_with or v.remainder is not None
            or not all(CAUSES[c].separable for c in (v.chosen.cause, *causes))):
        return None
    screen, folds, pol = ctx.diag.screen, ctx.folds, ctx.policy
    ctx.say(f"is {v.chosen.cause} still needed beside {' + '.join(causes)}?")
    own = {c.cause: c for c in ctx.diag.candidates}
    creep_may_stand_in = slower_than_drive(v.chosen, screen.creep_min, pol)
    e_null = ctx.held.null
    together, out = None, []  # all of them, scored once a replacement is worth comparing

    def flawed(c: Candidate) -> bool:  # outside its meaning or at a bound (creep for a slow relaxation: above)
        if creep_may_stand_in and _time_unidentified(screen, c, CAUSES[v.chosen.kind.slow_twin]):
            return False
        return bool(c.limit or at_bound(screen, c))

    for replacement in replacements(v.chosen, own, causes, screen.creep_min, pol):
        chain = _chain(screen, own, replacement)
        o = Option(replacement, chain, chain is None or any(flawed(c) for c in chain),
                   standing_in=len(replacement) > len(causes))  # creep last, for the relaxation's slowest part
        out.append(o)
        if o.flawed:
            continue
        if together is None:
            together = refit_errors(screen, folds, ctx.result, v.also[-1])
        errors = [refit_errors(screen, folds, ctx.result, c) for c in chain]
        o.without, o.against_base = score(folds, errors[-1], together), score(folds, e_null, errors[-1])
        o.share = share_of_misfit(screen, float(e_null @ e_null), float(errors[-1] @ errors[-1]))
        if accepts(o, pol):
            o.first = copy.copy(chain[0])
            o.first.params = {**o.first.params, **{n: chain[-1].params[n] for n in o.first.model.nonlinear_names
                                                   if n in chain[-1].params}}
            for i, c in enumerate(chain[1:], start=1):  # each scored against the ones before it
                c.heldout = {**score(folds, errors[i - 1], errors[i]), **bound_flags(screen, c), "refit_per_fold": True}
            o.also = tuple(chain[1:])
            o.pinned, o.end = _time_scale_end(screen, chain)
            break
    return out


def decide_backward(options: list[Option], v: Verdict, policy: Policy) -> tuple[Verdict, dict]:
    causes = [c.cause for c in v.also]
    o = next((o for o in options if accepts(o, policy)), None)
    if o is None:
        return v, step("drop-redundant-primary", v.chosen.cause, also=causes)
    old, first, z = v.chosen, o.first, o.without["z"]
    entry = step("drop-redundant-primary", first.cause, dropped=old.cause, also=list(o.causes[1:]),
                 creep_standing_in=o.standing_in, creep_time_end=o.end, z_together_over_without=z)
    slow = slow_part_clause(old, o.standing_in, o.pinned)
    how = (f"better without it (with it worse, z = {z:.1f})" if z < 0 else
           f"as well without it (with it better by z = {z:.1f} < {policy.z_same:g})")
    reason = (f"{' + '.join(causes)}, kept on top of {old.cause}{slow} predict the held-out records {how}: "
              f"{old.cause} is not needed, and {first.cause} is named with {', '.join(o.causes[1:]) or 'nothing'} "
              f"also (first named: {old.label}, held-out gain {100 * old.heldout_gain:.2f} %)")
    return replace(v, chosen=first, cause=first.cause, also=o.also, dropped=old, reason=reason), entry


DROP_REDUNDANT_PRIMARY = Rule("drop-redundant-primary", (
    "*Backward step.* With causes under `also`, a clean verdict (no ambiguity, no remainder, neither cause an "
    "interference or a clip) drops the named cause if those causes alone (composed strongest first; for a "
    "relaxation slower than every drive period, also with creep after them) predict as well as all of them "
    "together (together not better by {z_same}), are evidence against the base, remove at least "
    "{explain_share}, and keep their meaning off their bounds (creep standing for a slow relaxation may have "
    "its time scale at an end); the first of them is named, the others stay under `also`."),
    decide_backward, gather_backward)
