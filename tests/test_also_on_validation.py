"""The causes kept under "also" checked on the validation records (``validation.check_also``): each on top of
what was kept before it, as a named cause is confirmed. Reported, the verdict unchanged. The cases are planted
(``planted``, no extension code)."""

from __future__ import annotations

import pytest

from hysbench.benchmarks.diagnosis.report import verdict_lines
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis_accuracy.shares import also_on_validation
from diagnosed_cases import diagnosed


def test_an_unplanted_cause_kept_under_also_that_fails_on_validation_is_said_to():
    """A 2nd-order mode planted on the Table 2 MRPIM under triangles: the mode is named and confirmed; a
    two-time-constant relaxation kept on top of it on the held-out identification records makes the validation
    records' residual many times larger."""
    d, _ = diagnosed(("resonance",), "mrpim", "triangles", 5300068)
    assert d.cause == "resonance" and d.confirmed
    assert [a["cause"] for a in d.also_check] == [c.cause for c in d.also]
    check = next(a for a in d.also_check if a["cause"] == "relaxation")
    assert check["checked"] and not check["borne_out"] and check["explained_whole"] < 0, check
    also_line = next(line for line in verdict_lines(d) if line.startswith("also:"))
    assert "NOT borne out" in also_line
    assert d.to_json()["also_on_validation"] == d.also_check


# the cases of two pinned cases (tests/test_diagnosis.py), read in the process that diagnosed them
@pytest.mark.parametrize("kinds,base,drive,seed,effects,named,kept", [
    pytest.param(("delay", "creep"), "mrpim", "sines", 3800177, None, "creep", "delay",
                 marks=pytest.mark.xdist_group("relaxation-dropped-creep-alone-at-its-limit"),
                 id="composite-extension-on-top"),
    pytest.param(("interference",), "virtual-dea", "sines", 4,
                 {"interference": {"frequency_hz": 13.7, "amplitude": 0.08}}, "relaxation", "interference",
                 marks=pytest.mark.xdist_group("line-on-top-of-the-physics-relaxation"),
                 id="line-on-top-phase-per-record"),
])
def test_a_planted_cause_kept_under_also_is_borne_out_on_validation(kinds, base, drive, seed, effects, named, kept):
    d, _ = diagnosed(kinds, base, drive, seed, effects)
    assert d.cause == named and kept in [c.cause for c in d.also]
    check = next(a for a in d.also_check if a["cause"] == kept)
    assert check["checked"] and check["borne_out"], check
    assert check["explained_whole"] > 0 and check["z_whole"] >= Policy().z_confirm
    if kept == "interference":
        assert check["interference_check"]["same_amplitude"]


def test_the_counts_split_planted_and_unplanted_causes_and_skip_rows_without_the_check():
    def row(kinds, checks):
        return {"kinds": kinds, "also_on_validation": [
            {"cause": c, "checked": ok is not None, "borne_out": ok} for c, ok in checks]}
    rows = [row(["delay", "creep"], [("delay", True)]), row(["resonance"], [("relaxation", False)]),
            row(["relaxation"], [("delay", True), ("saturation", None)]), {"kinds": ["creep"], "also": ["delay"]}]
    assert also_on_validation(rows) == {"planted": {"borne_out": 1, "checked": 1},
                                        "not_planted": {"borne_out": 1, "checked": 2}, "not_checked": 1}
    assert also_on_validation([{"kinds": ["creep"], "also": ["delay"]}]) is None
