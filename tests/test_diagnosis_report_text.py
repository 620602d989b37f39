"""The verdict's and the trace's wording (``diagnosis.report``) on hand-made diagnoses: what each number is,
in which unit, and which parameter it belongs to. No diagnosis is run."""

from __future__ import annotations

from types import SimpleNamespace

from hysbench.benchmarks.diagnosis.cause import get_cause
from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.report import trace_lines, verdict_lines


def _diagnosis(uncertainty: dict, params: dict, **over) -> SimpleNamespace:
    """A named relaxation of two time constants; its time constants reported sorted, as ``estimates`` does."""
    chosen = SimpleNamespace(kind=get_cause("relaxation"), heldout={}, params=params,
                             model=SimpleNamespace(nonlinear_names=tuple(params)))
    screen = SimpleNamespace(base_nl_names=(), policy=Policy(), bounds_of=lambda model, name: (0.01, 1000.0))
    d = dict(dataset=SimpleNamespace(output_unit="mm"), cause="relaxation", chosen=chosen, screen=screen,
             verdict=SimpleNamespace(reason="r", partial=None, ambiguous_with=(), not_identified=()),
             parameters={"tau_s": sorted(params.values())}, uncertainty=uncertainty, extended_fit=None,
             extended_model="mrpim+relaxation", unexplained_check=None, experiments=[], also=[], also_check=None,
             noise_sd=0.01, structure={"F": 5.0, "records": ["a.csv"]}, gain=lambda: {}, warning="",
             base_fit=SimpleNamespace(diagnostics={}), one_drive_caution="", policy=Policy())
    return SimpleNamespace(**{**d, **over})


def _line(d, start: str) -> str:
    return next(line for line in verdict_lines(d) if line.startswith(start))


def test_each_time_constants_uncertainty_is_named_by_its_value_not_only_by_the_fits_order():
    # the fit's tau1 is the slow one; the report lists the time constants sorted, fast first
    d = _diagnosis({"tau1": {"relative_se": 0.017, "folds": [118.0, 121.0]},
                    "tau2": {"relative_se": 0.84, "folds": [0.5, 2.0]}}, {"tau1": 119.6, "tau2": 1.385})
    line = _line(d, "uncertainty")
    assert "tau1 (119.5 s) ±1.7 %" in line and "tau2 (1 s) ±84 %" in line, line


def test_a_parameter_at_a_search_bound_on_every_fold_is_not_identified_whatever_its_spread():
    d = _diagnosis({"tau1": {"relative_se": 0.01, "folds": [100.0, 102.0]},
                    "tau2": {"relative_se": 1e-10, "folds": [0.01, 0.01]}}, {"tau1": 101.0, "tau2": 0.0108})
    line = _line(d, "uncertainty")
    assert "tau2 (0.01 s): not identified (at a search bound on every fold)" in line and "±1e" not in line, line
    assert "tau1 (101 s) ±1 %" in line, line


def test_a_partial_candidates_share_of_the_misfit_is_a_percentage_and_left_out_when_not_computed():
    partial = SimpleNamespace(label="relaxation, 1 time constant", heldout_gain=0.5, heldout={"share_of_misfit": 0.4})
    verdict = SimpleNamespace(reason="r", partial=partial, ambiguous_with=(), not_identified=())
    d = _diagnosis({}, {"tau1": 1.0}, verdict=verdict)
    assert "(held-out gain 50.00 %, 40 % of the misfit beyond noise)" in _line(d, "best partial")
    partial.heldout = {}
    assert _line(d, "best partial").endswith("(held-out gain 50.00 %)")


def test_the_period_to_period_ratio_says_why_it_is_missing_and_the_separation_what_it_is():
    experiment = {"causes": ["relaxation", "creep"], "drive": "input held at 0.5 for 750 s", "separation": 2.5}
    d = _diagnosis({}, {"tau1": 1.0}, structure={"F": float("nan"), "records": []}, experiments=[experiment])
    assert _line(d, "measurement").endswith("F = - (no record repeats its drive period)")
    assert _line(d, "suggested").endswith("750 s (the two fits differ by 2.5 mm rms)")


def test_the_trace_shows_shares_in_percent_and_yes_or_no():
    best = {"cause": "delay", "label": "pure delay", "gain": 0.964, "z": 5.29, "share_of_misfit": 0.9}
    d = SimpleNamespace(trace=[
        {"rule": "simplest-as-good", "outcome": "delay", "inputs": {"best": best}},
        {"rule": "slow-part-twin", "outcome": "creep ambiguous", "inputs": {"predicts_as_well": True}},
        {"rule": "validation", "outcome": "confirmed", "inputs": {"explained_whole": 0.952, "z_whole": 146.0}}])
    lines = trace_lines(d)
    assert lines[0].endswith("(best delay: pure delay (gain 96.4 %, z 5.29))"), lines[0]
    assert lines[1].endswith("(predicts_as_well yes)") and lines[2].endswith("(explained_whole 95.2 %, z_whole 146)")


def test_diagnose_with_the_json_on_standard_output_prints_the_verdict_on_stderr(monkeypatch, capsys, tmp_path):
    import json

    from hysbench.benchmarks.cli import build_parser
    from hysbench.benchmarks.cli import diagnose as cli
    from hysbench.data.files import write_json

    monkeypatch.setattr(cli, "load_dataset", lambda path: "dataset")  # no diagnosis is run
    monkeypatch.setattr(cli, "output_scale", lambda dataset: 1.0)
    monkeypatch.setattr(cli, "diagnose", lambda *a, **k: "diag")
    monkeypatch.setattr(cli, "write_report", lambda diag, out, json_path, note="": write_json(json_path, {"a": 1}))
    monkeypatch.setattr(cli, "verdict", lambda diag: "cause: delay")
    args = build_parser().parse_args(["diagnose", "--json", "-", "--out", str(tmp_path), "--quiet"])
    assert cli.main(args) == 0
    out, err = capsys.readouterr()
    assert json.loads(out) == {"a": 1} and "cause: delay" in err


def test_a_damping_limit_outside_the_modes_search_range_is_refused_before_any_work():
    import pytest

    from hysbench.benchmarks.diagnosis.policy import PolicyError
    from hysbench.models.extended import DAMPING_BOUNDS

    lo, hi = DAMPING_BOUNDS
    for bad in (lo / 2, lo, 2 * hi):  # at or below the lower end the search has no range; above it, no effect
        with pytest.raises(PolicyError, match="max_damping"):
            Policy().with_overrides([f"max_damping={bad}"])
    assert Policy().with_overrides([f"max_damping={hi}"]).max_damping == hi
