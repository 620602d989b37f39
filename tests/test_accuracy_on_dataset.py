"""The accuracy study on a user's dataset (``hysbench accuracy run --on DATASET``): effects planted on its records
as they are, judged against its own verdict."""

import json

import numpy as np
import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis_accuracy import accuracy, pooled, rows as row_file
from hysbench.benchmarks.diagnosis_accuracy.planted import RECORDED, planted_case
from hysbench.data.dataset import Dataset, Record, load_dataset, save_dataset
from hysbench.data.protocol import paper_voltage
from hysbench.models import get_model

DT = 5e-3
ROLES = {0.5: "identification", 1.0: "validation", 2.0: "identification"}


def _user_dataset(folder, identification=ROLES):
    """A small dataset as a user would bring it: the Table 2 MRPIM under the paper's sines, two periods each."""
    model = get_model("mrpim")
    params = model.preset("paper")
    records = []
    for f, role in identification.items():
        t = np.arange(int(round(2 / f / DT))) * DT
        u = paper_voltage(t, f)
        y = model.simulate(u, DT, params, input_range=(0.5, 2.5))
        y = y + np.random.default_rng(int(10 * f)).normal(0.0, 1e-3 * np.ptp(y), y.size)
        records.append(Record(file=f"sine_{f:g}Hz.npz", t=t, u=u, y=y, role=role, frequency_hz=f))
    return save_dataset(Dataset(name="bench-user", records=records, input_unit="kV", output_unit="mm"), folder)


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory):
    return _user_dataset(tmp_path_factory.mktemp("user") / "bench_user")


def test_an_effect_planted_on_a_dataset_keeps_its_records_and_adds_only_the_effect(user_folder):
    src = load_dataset(user_folder)
    ds, truth = planted_case(("delay",), seed=3, dataset=user_folder, effects={"delay": {"delay_s": 0.05}})
    assert truth["base"] == "bench-user" and truth["drive"] == RECORDED
    for a, b in zip(src.records, ds.records):
        assert (a.file, a.role, a.frequency_hz, a.start, a.stop) == (b.file, b.role, b.frequency_hz, b.start, b.stop)
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.u, b.u)
        # no noise added to a recording: the output changes by the effect alone
        np.testing.assert_allclose(b.y - a.y, truth["signals"]["delay"][a.file], atol=1e-12)
        # slow reference: the delayed output is the recorded one interpolated 50 ms (10 samples) earlier
        k = np.arange(40, a.t.size - 40)
        np.testing.assert_allclose(b.y[k], np.interp(a.t[k] - 0.05, a.t, a.y), atol=2e-3 * np.ptp(a.y))
    assert truth["strength_pct"] > 0


def test_a_null_planted_on_a_dataset_adds_noise_of_the_drawn_size(user_folder):
    src = load_dataset(user_folder)
    ds, truth = planted_case(("null-white",), seed=4, dataset=user_folder)
    added = np.concatenate([b.y - a.y for a, b in zip(src.records, ds.records)])
    assert truth["noise_sd"] > 0
    assert abs(np.std(added) / truth["noise_sd"] - 1.0) < 0.1


@pytest.mark.parametrize("kinds, verdict, also, own, right", [
    (("delay",), "delay", [], "relaxation", True),
    (("delay",), "relaxation", ["delay"], "relaxation", True),  # its own cause named, the planted one on top
    (("delay",), "relaxation", [], "relaxation", False),
    (("delay",), "none", [], "none", False),
    (("delay",), "unexplained", ["delay"], "unexplained", False),  # "also" counts only under a named own cause
    (("delay", "creep"), "relaxation", ["creep"], "relaxation", True),
    (("null-ar1",), "relaxation", [], "relaxation", True),
    (("null-ar1",), "unexplained", [], "none", True),
    (("null-ar1",), "delay", [], "relaxation", False),
    (("dead-zone",), "none", [], "unexplained", True),
    (("dead-zone",), "saturation", [], "none", False),
])
def test_a_verdict_on_a_dataset_is_judged_against_its_own_verdict(kinds, verdict, also, own, right):
    assert accuracy.judge({"kinds": list(kinds), "base": "bench-user"}, verdict, also, own) is right


def test_the_study_runs_on_a_dataset_and_its_report_states_the_dataset_own_verdict(user_folder, tmp_path):
    path, report = tmp_path / "rows.jsonl.gz", tmp_path / "r.md"
    assert hysbench(["accuracy", "run", "--on", str(user_folder), "--cases", "2", "--seed", "1", "--jobs", "1",
                     "--rows", str(path), "--report", str(report)]) == 0
    plans = row_file.read_plans(path)
    assert list(plans) == ["on-bench-user-1"]
    on = plans["on-bench-user-1"]["meta"]["on"]
    assert on["name"] == "bench-user" and on["model"] == "mrpim"
    assert json.loads(report.with_suffix(".json").read_text())["summary"]["on"] == on
    own = on["own"]["verdict"]
    assert own in ("none", "unexplained", *accuracy.VOCABULARY)
    rows = plans["on-bench-user-1"]["rows"]
    assert [r["kinds"] for r in rows] == [list(k) for k in accuracy.PATTERN[:2]]
    for r in rows:
        assert r["base"] == "bench-user" and r["drive"] == RECORDED and r["own"] == own
        assert r["right"] == accuracy.judge(r, r["verdict"], r["also"], own)
    text = report.read_text()
    assert f"--on {user_folder}" in text and f"verdict **{own}**" in text
    # pooled: the dataset is a base of its own, its drive the recorded one
    p = pooled.pool(row_file.plan_rows(plans, ["on-bench-user-1"]))
    assert p["bases"] == ["bench-user"] and list(p["by_base_and_drive"]["bench-user"]) == [RECORDED]


def test_a_dataset_the_diagnosis_cannot_use_gets_one_line_and_exit_2_and_nothing_written(tmp_path, capsys):
    one = _user_dataset(tmp_path / "one_ident", {0.5: "identification", 1.0: "validation"})
    path, report = tmp_path / "rows.jsonl.gz", tmp_path / "r.md"
    for argv in (["--on", str(tmp_path / "missing")], ["--on", str(one)],
                 ["--on", str(one), "--model", "no-such-model"], ["--model", "mrpim"]):
        assert hysbench(["accuracy", "run", *argv, "--cases", "1", "--jobs", "1", "--rows", str(path),
                         "--report", str(report)]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "error: " in err[0], err
        assert not path.exists() and not report.exists()


def test_a_run_stopped_by_a_case_keeps_the_cases_before_it(user_folder, tmp_path, monkeypatch, capsys):
    done = {"kinds": ["relaxation"], "base": "bench-user", "drive": RECORDED, "seed": 0, "strength_pct": 1.0,
            "effects": {}, "verdict": "relaxation", "confirmed": False, "also": [], "ambiguous_with": [],
            "remainder": None, "parameters": {}, "parameter_errors": {}, "parameters_within": False,
            "right": True, "seconds": 1.0, "own": "none"}

    def run_case(case):
        if case["seed"] % accuracy.PLAN_STRIDE:
            raise accuracy.HysbenchError("a record went non-finite")
        return dict(done)

    monkeypatch.setattr(accuracy, "run_case", run_case)
    monkeypatch.setattr(accuracy, "own_verdict", lambda *a: {"verdict": "none", "also": [], "reason": "r",
                                                             "confirmed": None})
    path = tmp_path / "rows.jsonl.gz"
    assert hysbench(["accuracy", "run", "--on", str(user_folder), "--cases", "3", "--seed", "0", "--jobs", "1",
                     "--rows", str(path), "--report", str(tmp_path / "r.md")]) == 2
    assert capsys.readouterr().err.strip() == "hysbench accuracy: error: a record went non-finite"
    plan = row_file.read_plans(path)["on-bench-user-0"]
    assert len(plan["rows"]) == 1
    assert plan["meta"]["note"] == "Stopped after 1 of 3 cases: a record went non-finite"


def test_a_mode_planted_on_a_long_record_solves_its_ode(monkeypatch):
    """Beyond ``ADAPTIVE_MODE_SAMPLES`` the mode is integrated by fixed-step RK4; reference: scipy's DOP853 at
    tight tolerances on the same ODE, the input linear between samples."""
    from scipy.integrate import solve_ivp

    from hysbench.benchmarks.diagnosis_accuracy import planted

    monkeypatch.setattr(planted, "ADAPTIVE_MODE_SAMPLES", 2000)  # a shorter record takes the same branch
    dt, n, fn, zeta = 1e-3, 5000, 8.0, 0.1
    t = np.arange(n) * dt
    y = np.sin(2 * np.pi * 0.7 * t) + 0.3 * np.abs(np.sin(2 * np.pi * 0.23 * t))  # kinks at the sign changes
    w = 2 * np.pi * fn
    ref = solve_ivp(lambda s, q: [q[1], w * w * (np.interp(s, t, y) - q[0]) - 2 * zeta * w * q[1]], (0, t[-1]),
                    [y[0], 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12, max_step=dt).y[0]
    x = planted.mode_ode(y, dt, fn, zeta)
    assert np.max(np.abs(x - ref)) < 1e-5 * np.ptp(y)
