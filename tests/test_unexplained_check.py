"""An ``unexplained`` verdict claims structure that no cause explains; when the claim rests on a candidate's
held-out evidence alone (no period-to-period structure), that candidate must predict the validation records
too (rule ``unexplained-check``, ``validation``). The cases are draws of the accuracy benchmark's plans (``planted``: AR(1)
noise and a gain modulation, neither made with an extension's code)."""

from __future__ import annotations

from hysbench.benchmarks.diagnosis.report import verdict_lines
from hysbench.benchmarks.diagnosis.policy import Policy
from diagnosed_cases import diagnosed


def test_coloured_noise_whose_partial_evidence_fails_on_validation_is_none():
    """AR(1) noise (phi 0.95) on the Table 2 MRPIM: a two-time-constant relaxation predicts 11 % of the
    held-out identification records, too little to be named by itself, so the verdict on held-out records is
    ``unexplained``; fitted on the identification records it does not predict the validation records, and the
    verdict is ``none`` (``unexplained-check``)."""
    d, truth = diagnosed(("null-ar1",), "mrpim", "sines", 4200020)
    assert 0.9 <= truth["effects"]["null-ar1"]["ar1"] <= 0.99
    u = d.unexplained_check
    assert d.cause == "none", d.verdict.reason
    assert u is not None and u["checked"] and not u["borne_out"], u
    assert u["z_whole"] < Policy().z_confirm and d.verdict.partial is not None and u["cause"] == d.verdict.partial.cause
    steps = [(t["rule"], t["outcome"]) for t in d.trace]
    assert steps[-1] == ("unexplained-check", "none") and steps[-2][1] == "unexplained", steps
    assert d.confirmed is None and d.extended_fit is None and d.parameters == {}
    assert any("not borne out" in line for line in verdict_lines(d))
    assert d.to_json()["unexplained_check"]["borne_out"] is False


def test_an_unexplained_residual_whose_partial_evidence_holds_on_validation_stays_unexplained():
    """A slow gain modulation (out of vocabulary) on the virtual DEA under multisines: its residual does not
    repeat from period to period, and the relaxation that predicts part of it on held-out identification
    records (the physics' own) predicts the validation records as well."""
    d, _ = diagnosed(("gain-modulation",), "virtual-dea", "multisines", 4700083)
    u = d.unexplained_check
    assert d.cause == "unexplained", d.verdict.reason
    assert u is not None and u["checked"] and u["borne_out"], u
    assert u["z_whole"] >= Policy().z_confirm and u["explained_whole"] > 0 and u["explained_window"] > 0
    assert d.confirmed is None and d.extended_fit is None
    assert ("unexplained-check", "unexplained") in [(t["rule"], t["outcome"]) for t in d.trace]
    assert any("borne out: the verdict stays unexplained" in line for line in verdict_lines(d))  # the report says so


def test_a_residual_that_repeats_from_period_to_period_is_unexplained_without_the_check():
    """AR(1) noise on the virtual DEA: the residual (the physics' own misfit) repeats from period to period,
    which is evidence by itself; no candidate is checked."""
    d, _ = diagnosed(("null-ar1",), "virtual-dea", "sines", 4200050)
    assert d.cause == "unexplained" and d.structure["structured"], d.verdict.reason
    assert d.unexplained_check is None
