"""A mode is identified by its frequency (``selection.identified``): a partial cause is named only if its
parameters agree across the folds, and for a mode above the drive band that is its natural frequency; the
damping ratio, which such drives barely show, is reported with its fold spread. The planted case is a draw
of the accuracy benchmark's plan (``planted``: a second-order filter on a real piezo recording, not made with
the extension's code)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from hysbench.benchmarks.diagnosis_accuracy.accuracy import parameter_errors
from hysbench.benchmarks.diagnosis_accuracy.planted import piezo_available
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.selection import agrees, identified, loose_note
from diagnosed_cases import diagnosed

POLICY = Policy()
PARTIAL_SE = POLICY.partial_se


def _candidate(cause: str, **spread) -> SimpleNamespace:
    """A candidate with the relative fold spread (jackknife se) s of each named parameter."""
    uncertainty = {n: {"relative_se": s, "folds": [1.0, 1.0]} for n, s in spread.items()}
    return SimpleNamespace(cause=cause, uncertainty=uncertainty)


@pytest.mark.parametrize("frequency_se, damping_se, expected", [
    (0.05, 0.05, True), (0.05, 0.6, True), (0.6, 0.05, False), (0.6, 0.6, False)])
def test_a_mode_is_identified_by_its_frequency_alone(frequency_se, damping_se, expected):
    c = _candidate("resonance", natural_frequency=frequency_se, damping_ratio=damping_se)
    assert identified(c, POLICY) is expected


def test_other_causes_need_every_fold_refitted_parameter_to_agree():
    assert identified(_candidate("relaxation", tau1=0.05, tau2=0.05), POLICY)
    assert not identified(_candidate("relaxation", tau1=0.05, tau2=2 * PARTIAL_SE), POLICY)
    assert not identified(_candidate("resonance"), POLICY)  # nothing refitted per fold: agreement not shown


def test_the_reason_says_when_a_mode_s_damping_is_not_identified_and_claims_agreement_only_where_it_holds():
    assert loose_note(_candidate("resonance", natural_frequency=0.05, damping_ratio=0.1), POLICY) == ""
    note = loose_note(_candidate("resonance", natural_frequency=0.05, damping_ratio=0.6), POLICY)
    assert "damping_ratio (fold spread ±60 %) not identified" in note and "agree on natural_frequency" in note
    note = loose_note(_candidate("resonance", natural_frequency=0.6, damping_ratio=0.6), POLICY)
    assert "not identified" in note and "agree" not in note  # a mode named whole: its frequency was not checked
    assert loose_note(_candidate("delay", delay=0.9), POLICY) == ""


def test_a_mode_on_the_piezo_recording_is_named_although_its_damping_differs_between_the_folds():
    """A 7.9 Hz mode (damping 0.15, 1.5 % of the output's range) planted on the piezo recording: the mode
    removes 40 % of the base's held-out misfit (the recording's own misfit is most of the rest); its frequency
    agrees across the two folds within 4 %, its damping ratio does not (0.14 and 0.06). A mode is identified
    by its frequency: it is named, its damping reported as not identified."""
    if not piezo_available():
        pytest.skip("the piezo recordings are not present")
    d, truth = diagnosed(("resonance",), "piezo", "sines", 4500007)
    assert d.cause == "resonance", d.verdict.reason
    assert d.verdict.remainder is not None and d.verdict.remainder > 0.5  # said, not hidden
    u = d.chosen.uncertainty
    assert u["natural_frequency"]["relative_se"] <= PARTIAL_SE < u["damping_ratio"]["relative_se"], u
    assert parameter_errors(truth, "resonance", d.parameters)["natural_frequency_hz"] <= 0.25
    assert identified(d.chosen, POLICY) and not agrees(u["damping_ratio"], POLICY)
    assert loose_note(d.chosen, POLICY) in d.verdict.reason  # the reason says the damping is not identified
    assert d.confirmed  # the mode predicts the validation record too
