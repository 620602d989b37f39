"""The causes as plug-ins (``diagnosis.causes``) and the held-out residuals' one home (``heldout.HeldOut``)."""

import copy
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.diagnosis.candidates import Candidate
from hysbench.benchmarks.diagnosis.causes import CAUSES, Cause, cause_of_parameter, get_cause
from hysbench.benchmarks.diagnosis.heldout import Folds, HeldOut
from hysbench.models import CAUSES as EXTENSIONS
from hysbench.models import ExtendedModel, get_model

ROOT = Path(__file__).resolve().parents[1]


def test_every_extension_is_a_registered_cause_in_the_same_order():
    assert list(CAUSES) == list(EXTENSIONS)
    assert all(isinstance(c, Cause) and c.name == name for name, c in CAUSES.items())


def test_an_unknown_cause_is_named_with_the_known_ones():
    with pytest.raises(KeyError, match="unknown cause 'backlash'; known: relaxation, delay"):
        get_cause("backlash")


@pytest.mark.parametrize("name", list(EXTENSIONS))
def test_each_cause_owns_the_nonlinear_parameters_its_extension_adds(name):
    base = set(get_model("mrpim").param_names)
    added = [n for n in ExtendedModel("mrpim", (name,)).nonlinear_names if n not in base]
    assert added and all(cause_of_parameter(n) is CAUSES[name] for n in added), added


def test_no_branch_on_a_cause_name_outside_the_cause_classes():
    found = subprocess.run(["git", "grep", "-n", "-e", 'cause == "', "-e", 'cause != "', "-e", 'cause in ("',
                            "--", "benchmarks/diagnosis/"], cwd=ROOT, capture_output=True, text=True).stdout
    assert [line for line in found.splitlines() if not line.startswith("benchmarks/diagnosis/causes/")] == []


def _candidate(cause="delay"):
    return Candidate(cause, cause, ExtendedModel("mrpim", (cause,)), {}, 1, 1.0, 10)


def test_held_out_residuals_belong_to_the_candidate_scored_not_to_a_copy():
    folds = Folds(np.array([0, 2, 4]))
    c = _candidate()
    held = HeldOut(folds, np.zeros(4), [(c, np.arange(4.0))])
    assert c in held and np.array_equal(held.of(c)[folds.test(1)], [2.0, 3.0])
    twin = copy.copy(c)
    assert twin not in held
    with pytest.raises(KeyError, match="no held-out score"):
        held.of(twin)


@pytest.mark.parametrize("name, estimates, standing_in, expected", [
    ("delay", {"delay_s": 0.02}, False, " (creep's time scale sits at its limit, 40 s: not identified)"),
    ("relaxation", {"tau_s": [0.1, 30.0]}, False,
     " (creep's time scale sits at its limit, 40 s: not identified; it stands for a time constant of 30 s)"),
    ("relaxation", {"tau_s": [0.1, 30.0]}, True, ", with creep standing for its time constant of 30 s (slower than "
     "every drive period; creep's time scale sits at its limit, 40 s: not identified),"),
])
def test_the_backward_steps_reason_names_a_slow_time_only_for_a_cause_that_has_one(name, estimates, standing_in,
                                                                                  expected):
    from types import SimpleNamespace

    from hysbench.benchmarks.diagnosis.backward import slow_part_clause
    old = SimpleNamespace(kind=get_cause(name), estimates=estimates)
    pinned = "creep's time scale sits at its limit, 40 s: not identified"
    assert slow_part_clause(old, standing_in, pinned) == expected
    assert slow_part_clause(old, False, "") == ""


def test_the_documented_rule_is_the_rule_text_of_the_default_policy():
    """docs/diagnosis.md's numbered rule is generated from the rules' statements (``rules.rule_text``), and its
    table of trace ids lists every rule's id in the order the rules are applied."""
    import re

    from hysbench.benchmarks.diagnosis.policy import Policy
    from hysbench.benchmarks.diagnosis.rules import AFTER_SELECTION, SELECTION, rule_text

    doc = (ROOT / "docs" / "diagnosis.md").read_text()
    section = doc.split("<!-- rule_text(Policy()) begins -->")[1].split("<!-- rule_text(Policy()) ends -->")[0]
    assert section.strip() == rule_text(Policy()), "docs/diagnosis.md: put rules.rule_text(Policy()) between the markers"
    table = re.findall(r"^\| `([a-z-]+)` \|", doc.split("| trace id | outcome |")[1].split("\n\n")[0], re.M)
    assert table == [r.id for r in (*SELECTION, *AFTER_SELECTION)]
