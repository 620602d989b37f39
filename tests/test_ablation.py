"""The MRPIM ablation: planted truth, the history trim, shared regressors, AIC/BIC, the CLI.

Planted-truth data use the paper's seven-frequency protocol at a coarser step
(5 ms instead of 1 ms: 35,900 samples instead of 179,500) with white output
noise; "within noise" means within a tenth of the noise floor, the e_rms that
the noise alone gives (100 sd / peak-to-peak).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import norm

from hysbench.benchmarks.ablation import (
    PAPER,
    SharedColumns,
    Variant,
    compare,
    evaluate_variant,
    plan_variants,
    run_ablation,
    trim_history,
)
from hysbench.benchmarks.cli import main as cli_main
from hysbench.data.protocol import simulated_dataset
from hysbench.data.dataset import Dataset, Record, save_dataset
from hysbench.models import get_model

DT = 5e-3
NOISE_SD = 0.01
PAPER_MODEL = get_model("mrpim")
TABLE2 = PAPER_MODEL.preset("paper")


def coarse(model, params, seed):
    return simulated_dataset(model, params, n_periods=2, dt=DT, noise_sd=NOISE_SD, seed=seed, name="planted")


def noise_floor(ds) -> float:
    return float(np.mean([100.0 * NOISE_SD / np.ptp(r.y[r.scored]) for r in ds.records]))


def row(result, variant: Variant) -> dict:
    return next(r for r in result["variants"] if r["name"] == variant.name)


@pytest.fixture(scope="module")
def q_zero():
    """Table 2 MRPIM with q = 0 (envelopes as published)."""
    ds = coarse(PAPER_MODEL, {**TABLE2, "q": 0.0}, seed=3)
    return ds, run_ablation(ds, factors=("q_term", "envelopes"), grid=False, jobs=1)


@pytest.fixture(scope="module")
def table2():
    """Table 2 MRPIM as published: q and envelopes both matter (the controls)."""
    ds = coarse(PAPER_MODEL, TABLE2, seed=4)
    return ds, run_ablation(ds, factors=("q_term", "envelopes"), grid=False, jobs=1)


# --- planted truth ---------------------------------------------------------------------
def test_without_q_no_worse_when_truth_has_no_q(q_zero):
    ds, res = q_zero
    tol = 0.1 * noise_floor(ds)
    with_q, without_q = row(res, PAPER), row(res, PAPER.with_(q_term=False))
    assert without_q["validation_e_rms"] <= with_q["validation_e_rms"] + tol
    assert without_q["cv_e_rms"] <= with_q["cv_e_rms"] + tol
    assert res["verdicts"]["q_term"]["without"] != "worse"


def test_q_earns_its_keep_when_truth_has_q(table2):
    """Control: the same comparison separates when q matters."""
    ds, res = table2
    with_q, without_q = row(res, PAPER), row(res, PAPER.with_(q_term=False))
    assert without_q["cv_e_rms"] > with_q["cv_e_rms"] + 10 * noise_floor(ds)
    assert res["verdicts"]["q_term"]["without"] == "worse"


@pytest.mark.parametrize("which", ["q_zero", "table2"])
def test_removing_envelopes_costs_validation_accuracy(which, request):
    ds, res = request.getfixturevalue(which)
    floor = noise_floor(ds)
    with_env, without_env = row(res, PAPER), row(res, PAPER.with_(envelopes=False))
    assert without_env["validation_e_rms"] > with_env["validation_e_rms"] + 2 * floor
    assert without_env["cv_e_rms"] > with_env["cv_e_rms"] + 2 * floor
    assert res["verdicts"]["envelopes"]["without"] == "worse"
    assert with_env["validation_e_rms"] < 1.5 * floor  # the true structure fits to the noise


def test_orders_above_the_truth_do_not_improve_cv():
    model = get_model("mrpim", poly_order=2)
    params = {k: v for k, v in TABLE2.items() if k not in ("p3", "p4")}
    params["offset"] = 0.0
    ds = coarse(model, params, seed=5)
    tol = 0.1 * noise_floor(ds)
    res = run_ablation(ds, factors=("order",), grid=False, jobs=1)
    cv = {r["order"]: r["cv_e_rms"] for r in res["variants"]}
    assert sorted(cv) == list(range(7))
    for k in range(3, 7):
        assert cv[k] >= cv[2] - tol, (k, cv)
    assert cv[1] > cv[2] + 10 * noise_floor(ds)  # control: too low an order is visibly worse
    assert res["verdicts"]["order"]["enough"] == 2, res["verdicts"]


# --- the protocol's pieces -----------------------------------------------------------------
def test_plan_deduplicates_and_flags_the_paper():
    plan = plan_variants()
    variants = [v for v, _ in plan]
    assert len(variants) == len(set(variants)) == 33  # 7 x 2 x 2 grid + 5 further N
    fams = dict(plan)
    assert set(fams[PAPER]) == {"order", "q_term", "envelopes", "n_operators", "grid"}
    assert fams[Variant(4, True, True, 25)] == ["n_operators"]
    assert fams[Variant(0, False, False, 13)] == ["grid"]


def test_shared_columns_are_each_variants_regressors(q_zero):
    ds, _ = q_zero
    shared = SharedColumns(13, 6)
    in_range = (0.5, 2.5)
    for v in (Variant(0, False, False, 13), Variant(3, True, False, 13), Variant(6, False, False, 13)):
        m = v.model()
        got = shared.blocks(m, ds.records[:3], in_range)
        for r, X in zip(ds.records[:3], got):
            want = m.windowed_regressors_batch(r.u, r.dt, np.zeros((1, 0)), r.scored, in_range)[0]
            np.testing.assert_array_equal(X, want)


@given(period=st.integers(20, 120), before=st.integers(1, 5), n_ops=st.integers(1, 15),
       gamma=st.floats(-0.2, 0.2), lam=st.floats(-0.2, 0.2), seed=st.integers(0, 2**16))
def test_trimmed_history_gives_the_same_window_regressors(period, before, n_ops, gamma, lam, seed):
    """Whole periods of a periodic input dropped before the window: same regressors
    as running the model from the first sample (the slow, obvious reference)."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    n = (before + 1) * period
    j = np.arange(n)
    amp, phase = rng.uniform(0.1, 1.0, 3), rng.uniform(0, 2 * np.pi, 3)
    u = 1.5 + sum(a * np.sin(2 * np.pi * (k + 1) * j / period + p) for k, (a, p) in enumerate(zip(amp, phase)))
    t = j * dt
    rec = Record(file="r.npz", t=t, u=u, y=np.zeros(n), frequency_hz=1.0 / (period * dt))
    full = Dataset(name="x", records=[rec])
    trimmed, info = trim_history(full)
    assert info[0]["trimmed"] == (before >= 2)
    tr = trimmed.records[0]
    assert tr.n_scored == rec.n_scored == period
    model = get_model("mrpim", n_operators=n_ops, poly_order=2)
    in_range = (float(u.min()), float(u.max()))
    want = model.windowed_regressors(u, dt, {"gamma": gamma, "lambda": lam}, rec.scored, in_range)
    got = model.windowed_regressors(tr.u, tr.dt, {"gamma": gamma, "lambda": lam}, tr.scored, in_range)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_non_periodic_input_is_not_trimmed():
    dt, period = 0.01, 50
    j = np.arange(6 * period)
    u = 1.5 + np.sin(2 * np.pi * j / period) + 1e-3 * j / j.size  # slow drift
    rec = Record(file="d.npz", t=j * dt, u=u, y=np.zeros(j.size), frequency_hz=1.0 / (period * dt))
    trimmed, info = trim_history(Dataset(name="x", records=[rec]))
    assert not info[0]["trimmed"] and "not periodic" in info[0]["reason"]
    assert trimmed.records[0] is rec


def test_cross_validation_never_sees_the_left_out_record(q_zero):
    """Changing the left-out record's output changes its score, not its fold's fit."""
    ds, _ = q_zero
    left = ds.records[-1]
    moved = Dataset(name=ds.name, records=ds.records[:-1] + [
        Record(file=left.file, t=left.t, u=left.u, y=left.y + 0.5, role=left.role, frequency_hz=left.frequency_hz,
               weight=left.weight)])
    for v in (Variant(2, True, False, 5), Variant(2, True, True, 5)):
        a = evaluate_variant(v, ds, None, 0, {"n_candidates": 2}, {"n_candidates": 0})
        b = evaluate_variant(v, moved, None, 0, {"n_candidates": 2}, {"n_candidates": 0})
        fa, fb = a["cv_folds"][-1], b["cv_folds"][-1]
        assert fa["files"] == [left.file]
        assert fa["nonlinear"] == fb["nonlinear"]
        assert fb["e_rms"] > fa["e_rms"] + 1.0


def test_aic_bic_match_a_direct_gaussian_likelihood(q_zero):
    ds, res = q_zero
    recs = ds.identification
    n = sum(r.n_scored for r in recs)
    for r in res["variants"]:
        v = Variant(r["order"], r["q_term"], r["envelopes"], r["n_operators"])
        model = v.model()
        in_range = (min(float(x.u.min()) for x in recs), max(float(x.u.max()) for x in recs))
        resid = [(model.simulate(x.u, x.dt, r["params"], input_range=in_range) - x.y)[x.scored] for x in recs]
        f = sum(x.weight / x.n_scored * float(e @ e) for x, e in zip(recs, resid))
        assert f == pytest.approx(r["fitness"], rel=1e-6)
        sigma2 = f / n
        loglik = sum(float(np.sum(norm.logpdf(e, 0.0, math.sqrt(sigma2 * x.n_scored / x.weight))))
                     for x, e in zip(recs, resid))
        k = model.n_params + 1
        assert r["aic"] == pytest.approx(-2 * loglik + 2 * k, rel=1e-9)
        assert r["bic"] == pytest.approx(-2 * loglik + k * math.log(n), rel=1e-9)


def test_compare_counts_only_differences_beyond_noise():
    def fake(vals):
        return {"cv_e_rms": float(np.mean(vals)),
                "cv_folds": [{"left_out": str(i), "e_rms": x} for i, x in enumerate(vals)]}

    base = [1.0, 2.0, 3.0, 1.5, 2.5, 1.2, 4.0]
    assert compare(fake(base), fake([x + 0.5 for x in base]))["verdict"] == "worse"
    assert compare(fake(base), fake([x - 0.5 for x in base]))["verdict"] == "better"
    assert compare(fake(base), fake([x + 0.001 for x in base]))["verdict"] == "tie"  # below 2 %
    mixed = [x + (1.0 if i % 2 else -1.0) for i, x in enumerate(base)]
    assert compare(fake(base), fake(mixed))["verdict"] == "tie"  # within its standard error


def test_parallel_jobs_give_the_serial_result(q_zero):
    ds, _ = q_zero
    kw = dict(factors=("envelopes",), grid=False)
    one = run_ablation(ds, jobs=1, **kw)
    two = run_ablation(ds, jobs=2, **kw)
    for a, b in zip(one["variants"], two["variants"]):
        assert a["name"] == b["name"]
        assert a["cv_e_rms"] == pytest.approx(b["cv_e_rms"], rel=1e-6)
        assert a["validation_e_rms"] == pytest.approx(b["validation_e_rms"], rel=1e-6)


# --- the CLI -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ds") / "planted"
    save_dataset(coarse(PAPER_MODEL, TABLE2, seed=6), folder)
    return folder


def test_cli_writes_json_markdown_and_plot(dataset_dir, tmp_path, capsys):
    out, js = tmp_path / "out", tmp_path / "extra" / "abl.json"
    code = cli_main(["ablate", str(dataset_dir), "--out", str(out), "--json", str(js), "--orders", "3,4",
                     "--operators", "13", "--no-grid", "--jobs", "1", "--quiet"])
    assert code == 0
    data = json.loads(js.read_text())
    assert data == json.loads((out / "ablation.json").read_text())
    names = {r["name"] for r in data["variants"]}
    assert names == {"o3-q-env-N13", "o4-q-env-N13", "o4-env-N13", "o4-q-N13"}
    keys = {"name", "order", "q_term", "envelopes", "n_operators", "n_params", "identification_e_rms",
            "validation_e_rms", "cv_e_rms", "aic", "bic", "paper"}
    for r in data["variants"]:
        assert keys <= set(r)
        assert r["paper"] == (r["name"] == "o4-q-env-N13")
        assert len(r["cv_folds"]) == 7
    md = (out / "ablation.md").read_text()
    assert "What earns its keep" in md and data["conclusions"][0] in md
    assert (out / "ablation.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv, message", [
    (["ablate", "/no/such/folder"], "no such dataset"),
    (["ablate", "{ds}", "--jobs", "0"], "--jobs"),
    (["ablate", "{ds}", "--orders", "2,x"], "--orders"),
    (["ablate", "{ds}", "--orders", "13"], "--orders"),
    (["ablate", "{ds}", "--operators", "0"], "--operators"),
])
def test_cli_bad_input_is_one_line_and_exit_2(argv, message, dataset_dir, tmp_path, capsys):
    argv = [a.replace("{ds}", str(dataset_dir)) for a in argv] + ["--out", str(tmp_path / "o")]
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "o" / "ablation.json").exists()


def test_linear_shortcut_is_identifys_fit(q_zero):
    """Variants without envelopes skip identify(); they must get its result."""
    from hysbench.benchmarks.ablation import FullBounds, fit_once
    from hysbench.identification import identify

    ds, _ = q_zero
    for v in (Variant(4, True, False, 13), Variant(0, False, False, 5)):
        model = v.model()
        fit_on = [r.file for r in ds.records if r.frequency_hz != 0.2]
        bounds = FullBounds(ds)(model, fit_on)
        ours = fit_once(model, ds, fit_on, bounds, 0, None, {}, SharedColumns(v.n_operators, 6))
        ref = identify(model, ds, method="varpro", fit_on=fit_on)
        assert ours["fitness"] == pytest.approx(ref.fitness, rel=1e-7)
        for a, b in zip(ours["scores"], ref.records):
            assert (a.file, a.role) == (b.file, b.role)
            assert a.e_rms == pytest.approx(b.e_rms, rel=1e-6, abs=1e-9)
