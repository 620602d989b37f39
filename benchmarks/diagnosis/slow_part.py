"""Creep in place of a named relaxation's slowest part (rule ``slow-part-twin``): a relaxation slower than every
drive period and a drift since the start are nearly the same function under these drives.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

from .candidates import Candidate
from .causes import CAUSES
from .heldout import HeldOut, pairwise_z, passes
from .policy import Policy
from .rule import Rule, Verdict, step
from .search import score_candidate
from .selection import slower_than_drive


def slow_part_composite(screen, held: HeldOut | None, chosen: Candidate | None, candidates, variants
                        ) -> Candidate | None:
    """The composite (relaxation without its slowest time constant) + creep, scored on held-out records
    (its out-of-fold residuals added to ``held``); None where the test does not apply."""
    if chosen is None or chosen.kind.slow_twin is None:
        return None
    twin = CAUSES[chosen.kind.slow_twin]
    taus = sorted(chosen.estimates["tau_s"])
    if len(taus) < 2 or not slower_than_drive(chosen, screen.creep_min, screen.policy):
        return None
    fewer = [v for v in variants if len(v.estimates["tau_s"]) == len(taus) - 1]
    creep = [c for c in candidates if c.cause == twin.name]
    if not fewer or not creep:
        return None
    fast = copy.copy(fewer[0])  # the faster time constants, and the named fit's base parameters
    fast.params = {**fewer[0].params, **{n: chosen.params[n] for n in screen.base_nl_names},
                   **{f"tau{i + 1}": t for i, t in enumerate(taus[:-1])}}
    slow = copy.copy(creep[0])  # creep starting at the slowest time constant, within creep's bounds
    lo, hi = screen.bounds_of(slow.model, twin.time_scale)
    slow.params = {**slow.params, twin.time_scale: min(max(taus[-1], 1.05 * lo), hi / 1.05)}
    comp = screen.composite(fast, slow)
    if comp is None:
        return None
    score_candidate(screen, held, comp, refit=True)
    return comp


@dataclass(frozen=True)
class SlowPart:
    """The slow-part composite (``slow_part_composite``) and how much better the named relaxation predicts
    the held-out records than it (``pairwise_z``; positive: the relaxation better)."""
    composite: Candidate
    z_named_better: float


def gather_slow_part(ctx, v: Verdict) -> SlowPart | None:
    """The composite for a named cause with a slow twin (a relaxation); recorded on the diagnosis."""
    if v.chosen is None or v.chosen.kind.slow_twin is None:
        return None
    ctx.say("the slowest time constant or creep")
    comp = slow_part_composite(ctx.diag.screen, ctx.held, v.chosen, ctx.diag.candidates,
                               ctx.diag.relaxation_variants)
    ctx.diag.slow_part = comp
    return None if comp is None else SlowPart(comp, pairwise_z(ctx.held, v.chosen, comp))


def decide_slow_part(ev: SlowPart, v: Verdict, policy: Policy) -> tuple[Verdict, dict]:
    comp, twin = ev.composite, v.chosen.kind.slow_twin
    as_well = passes(comp, policy) and ev.z_named_better < policy.z_same
    taken = {c.cause for c in (*v.ambiguous_with, *v.also)}
    ambiguous = as_well and twin not in taken
    entry = step("slow-part-twin", f"{twin} ambiguous" if ambiguous else f"{v.chosen.cause} alone",
                 composite=comp.label, gain=comp.heldout.get("gain"), z=comp.heldout.get("z"),
                 predicts_as_well=as_well, creep_already=sorted(taken & {twin}))
    if not ambiguous:
        return v, entry
    slowest = v.chosen.kind.slowest_time_s(v.chosen.estimates)
    return replace(v, ambiguous_with=(*v.ambiguous_with, comp), reason=(
        f"{v.reason}; its slowest time constant ({slowest:.3g} s) is longer than the longest drive period, and "
        f"the faster ones plus a drift since the start predict the held-out records as well (z < "
        f"{policy.z_same:g}): that part may be creep")), entry


SLOW_PART_TWIN = Rule("slow-part-twin", (
    "*Slow part.* A named relaxation of two or more time constants whose slowest is longer than the longest "
    "drive period (creep's least time scale / {creep_periods}): its faster time constants plus creep are scored; "
    "if that passes and the relaxation does not predict better by {z_same}, creep is listed as ambiguous with it "
    "(unless creep is already named, ambiguous or under `also`)."), decide_slow_part, gather_slow_part)
