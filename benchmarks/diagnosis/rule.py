"""A rule of the diagnosis's decision: an id, its statement and a pure decision on gathered evidence.

``Rule.gather`` computes what the rule decides on and decides nothing; ``Rule.decide`` is pure: it returns a
new ``Verdict`` and the trace entry it leaves, so a rule can be tested on hand-made evidence. The ordered
rules and their text: ``rules``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

from .candidates import Candidate
from .policy import Policy

NONE, UNEXPLAINED = "none", "unexplained"  # the verdicts that name no cause


@dataclass(frozen=True)
class Verdict:
    """The verdict so far; a rule returns a new one. Sequences are tuples."""

    cause: str  # none, unexplained or a vocabulary cause
    chosen: Candidate | None
    ambiguous_with: tuple = ()  # candidates of other causes that predict the held-out records as well
    reason: str = ""
    not_identified: tuple = ()  # "cause: parameter (at bound)"
    partial: Candidate | None = None  # the best candidate when the verdict is unexplained
    remainder: float | None = None  # share of the held-out misfit (beyond noise) the named cause leaves
    also: tuple = ()  # causes kept on top of the named one, in the order kept
    dropped: Candidate | None = None  # the first named cause, if the causes kept on top made it redundant
    trace: tuple = ()  # the entries of the rules that decided or changed it, in order (``step``)

    def __post_init__(self):
        for name in ("ambiguous_with", "not_identified", "also", "trace"):
            object.__setattr__(self, name, tuple(getattr(self, name)))


def step(rule: str, outcome: str, **inputs) -> dict:
    """One trace entry: the rule's id, what it decided (a cause, ``none``, ``unexplained``, what it changed) and
    the inputs it decided on."""
    return {"rule": rule, "outcome": outcome, "inputs": inputs}


@dataclass(frozen=True)
class Rule:
    """``statement``: one paragraph, a policy field written ``{field}`` (``render``). ``decide``: (evidence,
    verdict, policy) -> (verdict, trace entry, a list of them, or None). ``gather``: (context, verdict) -> the
    evidence, None where the rule does not apply (no ``gather``: ``selection.decide`` gives it the scores).
    ``timing``: the key its gathering is timed under."""

    id: str
    statement: str
    decide: Callable
    gather: Callable | None = None
    timing: str = "secondary"


@dataclass
class Context:
    """What the gathering steps work on: the diagnosis being made (they record their evidence on it), the
    screen's result (``search.run_screen``), the progress callback and whether the named cause is extended."""

    diag: object
    result: dict
    say: Callable[[str], None]
    extend: bool = True

    @property
    def folds(self):
        return self.result["folds"]

    @property
    def held(self):
        return self.result["heldout"]

    @property
    def policy(self) -> Policy:
        return self.diag.screen.policy


def apply(rule: Rule, evidence, verdict: Verdict, policy: Policy) -> Verdict:
    """The verdict ``rule`` decides on ``evidence``, with the rule's trace entries appended."""
    verdict, entries = rule.decide(evidence, verdict, policy)
    if isinstance(entries, dict):
        entries = [entries]
    return dataclasses.replace(verdict, trace=verdict.trace + tuple(entries or ()))


def render(statement: str, policy: Policy) -> str:
    """A statement with every ``{field}`` shown as "`field` = value" (a name that is no policy field: KeyError)."""
    return statement.format_map({k: f"`{k}` = {v:{'.3g' if k == 'z_confirm' else '.4g'}}"
                                 for k, v in policy.as_dict().items() if k != "version"})
