"""The decision rules one at a time, on hand-made evidence (no diagnosis is run): each rule's outcome, the verdict
it returns (the one passed in unchanged) and its trace entry (rule id, outcome, inputs)."""

import dataclasses
import string
from types import SimpleNamespace

import numpy as np
import pytest

from hysbench.benchmarks.diagnosis.backward import DROP_REDUNDANT_PRIMARY, Option
from hysbench.benchmarks.diagnosis.candidates import Candidate
from hysbench.benchmarks.diagnosis.heldout import Folds, HeldOut
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.report import _inputs_text
from hysbench.benchmarks.diagnosis.rule import Verdict, apply, render
from hysbench.benchmarks.diagnosis.rules import AFTER_SELECTION, SELECTION, rule_text
from hysbench.benchmarks.diagnosis.secondary import ALSO, Forward
from hysbench.benchmarks.diagnosis.selection import UNDECIDED, Scores
from hysbench.benchmarks.diagnosis.slow_part import SLOW_PART_TWIN, SlowPart
from hysbench.benchmarks.diagnosis.validation import UNEXPLAINED_CHECK, VALIDATION, Validation
from hysbench.models import get_model

POLICY = Policy()


def candidate(cause: str, gain: float = 0.2, z: float = 5.0, **estimates) -> Candidate:
    c = Candidate(cause, f"{cause} fit", get_model("mrpim"), {}, 23, 1.0, 100, estimates=estimates)
    c.heldout = {"gain": gain, "z": z, "folds_improved": 3, "n_folds": 3, "at_bound": []}
    return c


def validation_gain(explained: float, z: float) -> dict:
    return {"records": ["v1.csv"], "explained_whole": explained, "explained_window": explained, "z_whole": z}


def only_entry(before: Verdict, after: Verdict) -> dict:
    assert after.trace[:len(before.trace)] == before.trace and len(after.trace) == len(before.trace) + 1
    return after.trace[-1]


def test_a_verdict_is_frozen_and_holds_tuples():
    v = Verdict("delay", None, ambiguous_with=[1], not_identified=["x"])
    assert v.ambiguous_with == (1,) and v.not_identified == ("x",)
    with pytest.raises(dataclasses.FrozenInstanceError):
        v.cause = "creep"


@pytest.mark.parametrize("z, borne", [(3.0, True), (1.0, False)])
def test_an_unexplained_verdict_resting_on_a_candidate_becomes_none_unless_validation_bears_it_out(z, borne):
    p = candidate("relaxation")
    v = Verdict("unexplained", None, reason="structured", partial=p)
    out = apply(UNEXPLAINED_CHECK, validation_gain(0.02, z), v, POLICY)
    entry = only_entry(v, out)
    assert (entry["rule"], entry["outcome"]) == ("unexplained-check", "unexplained" if borne else "none")
    assert entry["inputs"] == {"partial": "relaxation", "explained_whole": 0.02, "explained_window": 0.02,
                               "z_whole": z}
    assert (out.cause, out.partial) == ("unexplained" if borne else "none", p)
    assert v.cause == "unexplained" and v.trace == ()  # the verdict passed in is unchanged


def test_the_validation_rule_reports_confirmation_and_leaves_the_verdict():
    v = Verdict("delay", candidate("delay", delay_s=0.01))
    for g, outcome in ((validation_gain(0.1, 5.0), "confirmed"), (validation_gain(0.1, 1.0), "not confirmed"),
                       (validation_gain(-0.1, 5.0), "not confirmed"), ({}, "not confirmed")):
        out = apply(VALIDATION, Validation(g, {}), v, POLICY)
        entry = only_entry(v, out)
        assert (entry["rule"], entry["outcome"], entry["inputs"]["z_whole"]) == ("validation", outcome, g.get("z_whole"))
        assert dataclasses.replace(out, trace=()) == v
    line = Verdict("interference", candidate("interference"))
    for same, outcome in ((True, "confirmed"), (False, "not confirmed")):  # a line: by its amplitude, not z
        entry = apply(VALIDATION, Validation(validation_gain(0.1, 0.5), {"same_amplitude": same}), line,
                      POLICY).trace[-1]
        assert (entry["outcome"], entry["inputs"]["same_amplitude"]) == (outcome, same)


def test_the_forward_selection_rule_keeps_what_the_selection_kept():
    named, kept = candidate("relaxation", tau_s=[0.5]), candidate("delay")
    v = Verdict("relaxation", named)
    out = apply(ALSO, Forward(named, (kept,), (kept, candidate("creep")), ()), v, POLICY)
    assert out.also == (kept,) and v.also == ()
    assert only_entry(v, out) == {"rule": "also", "outcome": "delay",
                                  "inputs": {"on_top_of": "relaxation", "tried": ["delay", "creep"]}}
    entry = apply(ALSO, Forward(named, (), (), ()), v, POLICY).trace[-1]
    assert entry["outcome"] == "nothing"


def _option(z_without: float, z_base: float = 6.0, share: float = 0.8, flawed: bool = False, first=None) -> Option:
    h = {"gain": 0.3 if z_base >= 3 else 0.05, "z": z_base, "folds_improved": 3, "n_folds": 3}
    return Option(["delay"], [first], flawed, {"z": z_without}, h, share, first=first)


@pytest.mark.parametrize("option, dropped", [
    (dict(z_without=0.5), True),  # as good without the named cause
    (dict(z_without=-1.0), True),  # better without it
    (dict(z_without=2.5), False),  # with it better by z >= z_same
    (dict(z_without=0.5, share=0.3), False),  # alone they explain too little
    (dict(z_without=0.5, z_base=1.0), False),  # alone no evidence against the base (gain 5 %, z 1)
    (dict(z_without=0.5, flawed=True), False),  # a link outside its meaning or at a bound
])
def test_the_backward_step_drops_the_named_cause_only_when_those_on_top_do_as_well_alone(option, dropped):
    named, kept = candidate("creep", size=0.1, time_scale_s=30.0), candidate("delay", delay_s=0.01)
    first = candidate("delay", delay_s=0.011)
    v = Verdict("creep", named, reason="r", also=(kept,))
    out = apply(DROP_REDUNDANT_PRIMARY, [_option(first=first, **option)], v, POLICY)
    entry = only_entry(v, out)
    assert entry["rule"] == "drop-redundant-primary"
    if dropped:
        assert (entry["outcome"], entry["inputs"]["dropped"]) == ("delay", "creep")
        assert entry["inputs"]["z_together_over_without"] == option["z_without"]
        assert (out.cause, out.chosen, out.dropped, out.also) == ("delay", first, named, ())
    else:
        assert entry == {"rule": "drop-redundant-primary", "outcome": "creep", "inputs": {"also": ["delay"]}}
        assert dataclasses.replace(out, trace=()) == v


def test_the_backward_step_takes_the_first_option_it_accepts():
    named, first = candidate("relaxation", tau_s=[0.5, 40.0]), candidate("delay", delay_s=0.01)
    v = Verdict("relaxation", named, also=(candidate("delay"),))
    options = [_option(3.0, first=candidate("delay")), _option(0.1, first=first)]
    options[1].causes, options[1].standing_in = ["delay", "creep"], True
    entry = only_entry(v, out := apply(DROP_REDUNDANT_PRIMARY, options, v, POLICY))
    assert out.chosen is first and entry["inputs"]["also"] == ["creep"] and entry["inputs"]["creep_standing_in"]


@pytest.mark.parametrize("z, also, outcome", [(0.5, (), "creep ambiguous"), (3.0, (), "relaxation alone"),
                                              (0.5, ("creep",), "relaxation alone")])
def test_the_slow_part_rule_lists_creep_as_ambiguous_unless_the_relaxation_does_better_or_creep_is_kept(
        z, also, outcome):
    named, comp = candidate("relaxation", tau_s=[0.5, 40.0]), candidate("creep")
    v = Verdict("relaxation", named, also=tuple(candidate(c) for c in also))
    out = apply(SLOW_PART_TWIN, SlowPart(comp, z), v, POLICY)
    entry = only_entry(v, out)
    assert (entry["rule"], entry["outcome"], entry["inputs"]["creep_already"]) == (
        "slow-part-twin", outcome, list(also))
    assert out.ambiguous_with == ((comp,) if outcome == "creep ambiguous" else ())


def rule(rule_id: str):
    return next(r for r in (*SELECTION, *AFTER_SELECTION) if r.id == rule_id)


@pytest.mark.parametrize("structured, outcome", [(False, "none"), (True, "unexplained")])
def test_with_nothing_passing_the_verdict_is_unexplained_only_on_a_structured_residual(structured, outcome):
    weak = candidate("delay", gain=0.005, z=1.0)  # no evidence: it does not make the residual look structured
    ev = Scores(None, None, (weak,), (), structured)
    undecided = Verdict(UNDECIDED, None)
    out = apply(rule("nothing-passes"), ev, undecided, POLICY)
    assert only_entry(undecided, out) == {"rule": "nothing-passes", "outcome": outcome,
                                          "inputs": {"structured": structured, "evidence": []}}
    assert (out.cause, out.chosen, out.partial) == (outcome, None, None)
    decided = Verdict("creep", candidate("creep"))
    assert apply(rule("nothing-passes"), ev, decided, POLICY) == decided  # decided already: the rule is silent


def test_the_simplest_as_good_entry_lists_each_passing_candidate_by_its_label_with_its_score():
    named = candidate("relaxation", gain=0.9, z=6.0)
    named.label, named.heldout["sse"] = "relaxation, 2 time constants", 1.0
    weak = candidate("creep", gain=0.001, z=0.5)  # no evidence: not passing
    held = HeldOut(Folds(np.array([0, 5, 10]), policy=POLICY), np.ones(10))
    ev = Scores(SimpleNamespace(n_held_out_rows=10, noise_sd=0.0), held, (named, weak), (), True)
    out = apply(rule("simplest-as-good"), ev, Verdict(UNDECIDED, None), POLICY)
    entry = out.trace[-1]
    assert (entry["rule"], entry["outcome"], out.chosen) == ("simplest-as-good", "relaxation", named)
    assert [(s["label"], s["gain"], s["z"]) for s in entry["inputs"]["passing"]] == [
        ("relaxation, 2 time constants", 0.9, 6.0)]


def test_a_trace_entry_names_a_candidate_by_its_label_and_its_cause():
    text = _inputs_text({"as_good": [{"cause": "relaxation", "label": "relaxation, 3 time constants", "gain": 0.9},
                                     {"cause": "creep", "label": "slow drift since the start", "gain": 0.5}]})
    assert "relaxation, 3 time constants (gain" in text and "creep: slow drift since the start (gain" in text


def test_every_rule_has_its_own_id_and_states_itself_with_policy_fields_only():
    rules = [*SELECTION, *AFTER_SELECTION]
    assert len({r.id for r in rules}) == len(rules)
    fields = set(POLICY.as_dict())
    for r in rules:
        names = {name for _, name, _, _ in string.Formatter().parse(r.statement) if name}
        assert names <= fields, (r.id, names - fields)
    with pytest.raises(KeyError, match="z_passes"):
        render("z >= {z_passes}", POLICY)


def test_the_rule_text_shows_the_policys_values():
    assert "`z_pass` = 3 " in rule_text(POLICY) and "`z_pass` = 2.5 " in rule_text(Policy(z_pass=2.5))
    assert "`z_confirm` = 1.64" in rule_text(POLICY)
