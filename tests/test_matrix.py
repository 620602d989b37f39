"""`hysbench run`: resume after a kill, determinism by seed, Dask, bad input, measured data."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dataclasses import replace

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.matrix import cells as cells_module
from hysbench.benchmarks.matrix import execute as execute_module
from hysbench.benchmarks.matrix.cells import method_options, plan_cells, run_cell
from hysbench.benchmarks.matrix.execute import run_matrix
from hysbench.benchmarks.matrix.report import TIMING_COLUMNS, matrix_rows, paper_layout, seconds_per_cell
from hysbench.benchmarks.matrix.store import CellStore
from hysbench.data import load_dataset
from hysbench.identification import Fit
from hysbench.models import HysteresisModel, Parameter
from hysbench.models import registry as model_registry
from hysbench.data.protocol import simulated_dataset
from hysbench.data import save_dataset
from hysbench.models import get_model
from measured_data import piezo_dataset, pzt_dataset

CLI = [sys.executable, "-m", "hysbench.benchmarks.cli"]
FAST = ["--models", "mrpim,classical-pi", "--methods", "varpro,lsq", "--option", "lsq.max_nfev=60"]


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory) -> Path:
    """Table-2 MRPIM on three of the protocol's frequencies, with noise."""
    model = get_model("mrpim")
    ds = simulated_dataset(model, model.preset("paper"), n_periods=1.5, noise_sd=0.01, seed=5,
                           frequencies=(0.4, 0.8, 1.0), name="small")
    return save_dataset(ds, tmp_path_factory.mktemp("data") / "small")


def run(args, **kw):
    return subprocess.run(CLI + ["run", "--quiet"] + args, capture_output=True, text=True, **kw)


def refusal(capsys, args) -> tuple[int, str]:
    """(exit status, stderr) of `hysbench run --quiet ARGS` run in this process."""
    status = hysbench(["run", "--quiet", *args])
    return status, capsys.readouterr().err


def read_matrix(path: Path, drop_timing=True):
    with open(path / "matrix.csv") as fh:
        rows = list(csv.DictReader(fh))
    if drop_timing:
        for r in rows:
            for c in TIMING_COLUMNS:
                r.pop(c)
    return rows


def test_matrix_columns_and_report(small_dataset, tmp_path):
    proc = run([str(small_dataset), "--out", str(tmp_path), "--jobs", "2", *FAST])
    assert proc.returncode == 0, proc.stderr
    rows = read_matrix(tmp_path, drop_timing=False)
    needed = {"dataset", "model", "method", "record", "frequency_hz", "role", "e_m", "e_rms", "fitness",
              "fit_seconds", "simulate_seconds", "n_params", "seed"}
    assert needed <= set(rows[0])
    assert {(r["model"], r["method"]) for r in rows} == {
        ("mrpim", "varpro"), ("mrpim", "lsq"), ("classical-pi", "varpro"), ("classical-pi", "lsq")}
    assert len(rows) == 4 * 3
    assert all(np.isfinite(float(r["e_rms"])) for r in rows)
    report = (tmp_path / "report.md").read_text()
    assert "rank" in report and "Table 3" in report and "Table 4" in report
    assert list(tmp_path.glob("loops_*.png")) and list(tmp_path.glob("erms_*.png"))
    # the generating model, identified exactly, is ranked first
    first = report.split("| 1 |")[1].split("|")[0].strip()
    assert first == "mrpim"


def test_same_seed_gives_identical_matrix(small_dataset, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        proc = run([str(small_dataset), "--out", str(out), "--jobs", "1", "--seed", "3", *FAST])
        assert proc.returncode == 0, proc.stderr
    assert read_matrix(a) == read_matrix(b)  # all but the wall-clock columns


def test_resume_after_kill(small_dataset, tmp_path):
    args = CLI + ["run", "--quiet", str(small_dataset), "--out", str(tmp_path), "--jobs", "1",
                  "--models", "mrpim,classical-pi", "--methods", "mpso,lsq",
                  "--option", "mpso.iterations=15", "--option", "lsq.max_nfev=80"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    cells = tmp_path / "cells"
    deadline = time.time() + 240
    while time.time() < deadline and not (cells.is_dir() and list(cells.glob("*.json"))):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = {p.name: (p.stat().st_mtime_ns, p.read_text()) for p in cells.glob("*.json")}
    assert finished, "no cell finished before the kill"
    for name, (_, text) in finished.items():
        json.loads(text)  # complete, parseable
    proc2 = subprocess.run(args[:4] + args[5:], capture_output=True, text=True)  # not quiet: prints the summary
    assert proc2.returncode == 0, proc2.stderr
    assert f"{len(finished)} reused" in proc2.stdout
    for name, (mtime, text) in finished.items():
        p = cells / name
        assert p.stat().st_mtime_ns == mtime and p.read_text() == text  # not recomputed
    assert not [p for p in tmp_path.rglob(".*") if p.is_file()]  # no temporary or partial file
    assert len(read_matrix(tmp_path)) == 4 * 3
    # a rerun with nothing changed computes nothing
    proc3 = subprocess.run(args[:4] + args[5:], capture_output=True, text=True)
    assert "0 computed, 4 reused" in proc3.stdout


def test_dask_cluster_gives_the_same_matrix(small_dataset, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    local = tmp_path / "local"
    proc = run([str(small_dataset), "--out", str(local), "--jobs", "1", *FAST])
    assert proc.returncode == 0, proc.stderr
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        on_dask = tmp_path / "dask"
        proc = run([str(small_dataset), "--out", str(on_dask), "--dask", cluster.scheduler_address,
                    *FAST])
        assert proc.returncode == 0, proc.stderr
    assert read_matrix(local) == read_matrix(on_dask)


@pytest.mark.parametrize("args,message", [
    (["--models", "mrpim,nosuch"], "unknown model 'nosuch'"),
    (["--methods", "gradient-descent"], "unknown method 'gradient-descent'"),
    (["--jobs", "0"], "argument --jobs: expected an integer >= 1"),
    (["--seed", "-4"], "argument --seed: expected an integer >= 0"),
    (["--jobs", "many"], "argument --jobs: expected an integer >= 1, got 'many'"),
    (["--models", ","], "--models needs at least one name"),
    (["--option", "mpso-max=3"], "expected METHOD.KEY=VALUE"),
    (["--methods", "varpro", "--option", "mpso.iterations=3"], "not being run"),
    (["--methods", "mpso", "--option", "mpso.warp_speed=3"], "unknown option 'warp_speed'"),
    (["--methods", "mpso", "--option", "mpso.iterations=-3"], "must be an integer"),
])
def test_bad_options(small_dataset, tmp_path, capsys, args, message):
    out = tmp_path / "out"
    status, err = refusal(capsys, [str(small_dataset), "--out", str(out), *args])
    assert status == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()  # nothing written


def test_refused_dataset(tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "dataset.toml").write_text('name = "x"\n')
    status, err = refusal(capsys, [str(bad), "--out", str(tmp_path / "out")])
    assert status == 2 and "missing key(s)" in err and err.count("\n") == 1


def test_unwritable_output(small_dataset, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    status, err = refusal(capsys, [str(small_dataset), "--out", str(blocker / "out"), *FAST])
    assert status == 2 and "cannot create output folder" in err
    assert err.count("\n") == 1


# --- real measured data (read in place, never copied): see measured_data.py ---------


def test_measured_data_matrix(shared_datasets, tmp_path):
    piezo = piezo_dataset(shared_datasets, tmp_path / "piezo")
    pzt = pzt_dataset(shared_datasets, tmp_path / "pzt")
    out = tmp_path / "out"
    proc = run([str(piezo), str(pzt), "--out", str(out), "--jobs", "2",
                "--models", "mrpim,classical-pi,preisach", "--methods", "varpro"])
    assert proc.returncode == 0, proc.stderr
    rows = read_matrix(out)
    assert {r["dataset"] for r in rows} == {"piezo-sindy-1hz", "pzt-ceramic"}
    assert {r["model"] for r in rows} == {"mrpim", "classical-pi", "preisach"}
    errors = np.array([float(r["e_rms"]) for r in rows])
    assert np.all(np.isfinite(errors))
    # a fitted hysteresis model must beat predicting each window's mean by far
    from hysbench.data.metrics import e_rms
    from hysbench.data import load_dataset

    for folder in (piezo, pzt):
        ds = load_dataset(folder)
        for rec in ds.records:
            ya = rec.y[rec.scored]
            constant = e_rms(np.full_like(ya, ya.mean()), ya)
            best = min(float(r["e_rms"]) for r in rows if r["dataset"] == ds.name and r["record"] == rec.file)
            assert best < 0.5 * constant, (ds.name, rec.file, best, constant)


def test_the_matrix_budget_reaches_the_identifier(small_dataset):
    """mpso at the matrix budget spends 20 particles x (19 + 1) = 400 model evaluations, lsq at most 20
    residual evaluations (plus one Jacobian batch of n_params sets per iteration)."""
    options = method_options(["mpso", "lsq"], {}, False)
    ds = load_dataset(small_dataset)
    cells = plan_cells([(small_dataset, ds)], ["classical-pi"], ["mpso", "lsq"], seed=0, method_options=options)
    by_method = {c.method: run_cell(c) for c in cells}
    assert by_method["mpso"]["status"] == "ok"
    assert by_method["mpso"]["n_evaluations"] == 400
    n_params = by_method["lsq"]["n_params"]
    assert 0 < by_method["lsq"]["n_evaluations"] <= 20 * (1 + n_params)
    # a user option overrides the budget
    fewer = method_options(["mpso"], {"mpso": {"iterations": 4}}, False)
    cell = plan_cells([(small_dataset, ds)], ["classical-pi"], ["mpso"], seed=0, method_options=fewer)[0]
    assert run_cell(cell)["n_evaluations"] == 20 * 5


def test_a_cell_key_changes_with_the_code_and_the_hyperparameters(small_dataset, monkeypatch):
    ds = load_dataset(small_dataset)
    cell = plan_cells([(small_dataset, ds)], ["mrpim"], ["varpro"], seed=0)[0]
    key = cell.key
    assert plan_cells([(small_dataset, ds)], ["mrpim"], ["varpro"], seed=0)[0].key == key
    assert replace(cell, hyperparameters='{"n_operators": 5}').key != key
    assert plan_cells([(small_dataset, ds)], ["mrpim"], ["varpro"], seed=1)[0].key != key
    monkeypatch.setattr(cells_module, "code_fingerprint", lambda: "other code")
    assert cell.key != key


def test_code_fingerprint_follows_the_source(tmp_path, monkeypatch):
    before = cells_module.code_fingerprint()
    fake = tmp_path / "hysbench_extra.py"
    fake.write_text("x = 1\n")
    cells_module.code_fingerprint.cache_clear()
    monkeypatch.setattr(cells_module, "__file__", str(fake))
    changed = cells_module.code_fingerprint()
    cells_module.code_fingerprint.cache_clear()
    monkeypatch.undo()
    assert changed != before and cells_module.code_fingerprint() == before


def test_stored_cells_of_other_code_or_format_are_recomputed(small_dataset, tmp_path):
    ds = load_dataset(small_dataset)
    cell = plan_cells([(small_dataset, ds)], ["classical-pi"], ["varpro"], seed=0)[0]
    store = CellStore(tmp_path)
    result = run_cell(cell)
    store.put(result)
    assert store.get(cell.key) == json.loads(json.dumps(result))
    assert Fit.from_dict(store.get(cell.key)["fit"]).params == result["params"]  # the Fit itself is stored
    store.put({**result, "format": "hysbench-cell/1"})
    assert store.get(cell.key) is None
    store.put({**result, "key": "0" * 20})
    assert store.get(cell.key) is None


@pytest.mark.parametrize("content", [b"\xff\xfe", b"[1]", b"[" * 100000, b"1" * 5000, b"{\"key\": "])
def test_a_damaged_cell_file_is_computed_again(tmp_path, content):
    store = CellStore(tmp_path)
    store.path("k").write_bytes(content)
    assert store.get("k") is None


def test_run_matrix_reuses_a_cell_of_the_same_code_and_recomputes_after_a_code_change(small_dataset, tmp_path,
                                                                                     monkeypatch):
    ds = load_dataset(small_dataset)
    store = CellStore(tmp_path)
    computed = []

    def plan():
        return plan_cells([(small_dataset, ds)], ["classical-pi"], ["varpro"], seed=0)

    run_matrix(plan(), store, jobs=1, on_result=computed.append, quiet=True)
    assert len(computed) == 1
    run_matrix(plan(), store, jobs=1, on_result=computed.append, quiet=True)
    assert len(computed) == 1  # same code: the stored cell is reused, nothing runs
    monkeypatch.setattr(cells_module, "code_fingerprint", lambda: "edited code")
    results = run_matrix(plan(), store, jobs=1, on_result=computed.append, quiet=True)
    assert len(computed) == 2 and computed[1]["key"] != computed[0]["key"]  # other code: recomputed
    assert list(results) == [computed[1]["key"]]


def test_run_matrix_starts_the_cells_expected_to_take_longest_first(small_dataset, tmp_path, monkeypatch):
    ds = load_dataset(small_dataset)
    cells = plan_cells([(small_dataset, ds)], ["classical-pi", "mrpim"], ["varpro", "lsq"], seed=0)
    names = [c.name for c in cells]
    started = []

    def run(cell):
        started.append(cell.name)
        return {"key": cell.key, "status": "failed"}

    monkeypatch.setattr(execute_module, "run_cell", run)
    expected = {names[0]: 1.0, names[1]: 5.0, names[2]: 3.0}  # the last cell has no figure: it starts first
    run_matrix(cells, CellStore(tmp_path), jobs=1, quiet=True, expected_seconds=expected)
    assert started == [names[3], names[1], names[2], names[0]]
    started.clear()
    run_matrix(cells, CellStore(tmp_path), jobs=1, quiet=True)
    assert started == names  # without figures: the plan's order


def test_a_cells_expected_seconds_are_its_fit_and_simulation_in_an_earlier_matrix_csv(tmp_path):
    path = tmp_path / "matrix.csv"
    rows = ["dataset,model,method,record,fit_seconds,simulate_seconds",
            "d,mrpim,varpro,a.csv,2.5,0.5", "d,mrpim,varpro,b.csv,2.5,0.5", "d,bouc-wen,lsq,a.csv,nan,0.1"]
    path.write_text("\n".join(rows) + "\n")
    assert seconds_per_cell(path) == {"d/mrpim/varpro": 3.0}  # a non-finite figure is no figure
    assert seconds_per_cell(tmp_path / "absent.csv") == {}
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    assert seconds_per_cell(tmp_path / "other.csv") == {}


class _NaNModel(HysteresisModel):
    """A test model whose output is NaN: the matrix must report it, not rank it."""

    name = "test-nan-model"

    def __init__(self):
        pass

    def declare_parameters(self, scale):
        return [Parameter("gain", 1.0, 0.0, 2.0)]

    def simulate_batch(self, u, dt, param_sets, input_range=None):
        P = self._check_param_sets(param_sets)
        return np.full((P.shape[0], np.size(u)), np.nan)


def _non_finite_cell(small_dataset, monkeypatch):
    """The test model is registered for this test only: tests over every registered model must not see it."""
    monkeypatch.setitem(model_registry._REGISTRY, _NaNModel.name, _NaNModel)
    monkeypatch.setattr(model_registry, "_NOT_IN_MATRIX", model_registry._NOT_IN_MATRIX | {_NaNModel.name})
    ds = load_dataset(small_dataset)
    cell = plan_cells([(small_dataset, ds)], ["test-nan-model"], ["lsq"], seed=0)[0]
    return ds, cell, run_cell(cell)


def test_a_model_with_non_finite_output_is_reported_not_scored(small_dataset, tmp_path, monkeypatch):
    ds, _, result = _non_finite_cell(small_dataset, monkeypatch)
    assert result["status"] == "nonfinite"
    assert set(result["nonfinite_records"]) == {r.file for r in ds.records}
    assert "non-finite" in result["error"]
    assert matrix_rows([result]) == []  # not in the ranked table


def test_a_non_finite_cell_is_stored_as_strict_json_and_read_back(small_dataset, tmp_path, monkeypatch):
    _, cell, result = _non_finite_cell(small_dataset, monkeypatch)
    assert not np.isfinite(result["records"][0]["e_rms"])
    store = CellStore(tmp_path)
    path = store.put(result)

    def refuse(constant):
        raise ValueError(f"non-strict JSON constant {constant}")

    stored = json.loads(path.read_text(), parse_constant=refuse)  # NaN / Infinity refused
    assert stored["records"][0]["e_rms"] is None
    again = store.get(cell.key)
    assert again is not None and again["status"] == "nonfinite"
    assert matrix_rows([again]) == []


def test_an_unreachable_dask_scheduler_leaves_no_output_folder(small_dataset, tmp_path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "new"
    proc = run([str(small_dataset), *FAST, "--dask", "tcp://127.0.0.1:1", "--out", str(out)])
    assert proc.returncode == 2 and "cannot connect to the Dask scheduler" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_an_abandoned_pool_is_stopped_at_once_and_leaves_no_thread_to_race_the_exit():
    """On SIGINT the run kills its workers and does not wait for their cells; the pool's manager thread is
    over when it returns, so Python's exit has no pipe of it left to write to while it closes."""
    import multiprocessing
    import threading
    import time as clock
    from concurrent.futures import ProcessPoolExecutor

    from hysbench.benchmarks.matrix.execute import _abandon

    pool = ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn"))
    futures = [pool.submit(clock.sleep, 60) for _ in range(3)]
    workers = list(pool._processes.values())
    manager = pool._executor_manager_thread
    t0 = clock.monotonic()
    _abandon(pool)
    assert clock.monotonic() - t0 < 2.0
    assert not manager.is_alive() and manager not in threading.enumerate()
    for w in workers:
        w.join(2.0)
        assert not w.is_alive()
    assert all(f.done() for f in futures)


def test_a_ranked_cell_at_a_bound_or_with_notes_says_so_in_the_report():
    """A score whose fit stopped at a search bound (or carries another note) is not shown bare."""
    from hysbench.benchmarks.matrix.report import dataset_section

    def cell(model, e_rms, at_bounds, notes):
        return {"dataset": "d", "model": model, "method": "lsq", "status": "ok", "n_params": 3, "fitness": 1.0,
                "fit_seconds": 1.0, "simulate_seconds": 0.1,
                "records": [{"file": "v", "frequency_hz": 1.0, "role": "validation", "e_m": 2 * e_rms, "e_rms": e_rms}],
                "fit": {"diagnostics": {"at_bounds": at_bounds}, "notes": notes}}

    bounded = cell("elliptical", 1.0, ["gamma"], ["parameters at their bounds: gamma (upper 0.01); the optimum ..."])
    free = cell("mrpim", 2.0, [], [])
    text = "\n".join(dataset_section("d", [bounded, free], [], {}))
    rows = {ln.split(" | ")[1]: ln for ln in text.splitlines() if ln.startswith("| 1 |") or ln.startswith("| 2 |")}
    assert rows["elliptical"].endswith("| gamma |") and rows["mrpim"].endswith("| – |")
    assert "- elliptical / lsq: parameters at their bounds: gamma (upper 0.01)" in text
    assert "- mrpim / lsq" not in text


def test_the_report_states_the_learners_training_budget(small_dataset):
    """A learner's budget is its hyperparameters (no identifier option bounds it): the report says them."""
    from hysbench.benchmarks.cli.run import budget_lines

    ds = load_dataset(small_dataset)
    cells = plan_cells([(small_dataset, ds)], ["mrpim", "narx-mlp"], None, 0, method_options(None, {}, False))
    text = "\n".join(budget_lines(method_options(None, {}, False), cells, False))
    assert "lsq.max_nfev=20" in text
    assert 'narx-mlp {' in text and '"max_epochs": 200' in text and '"max_rows": 50000' in text
    only_structured = [c for c in cells if c.method != "native"]
    assert "Learners" not in "\n".join(budget_lines({}, only_structured, False))



def test_paper_tables_tell_apart_records_of_one_frequency():
    """Rows are keyed by frequency; records that share one (e.g. two amplitudes at 1 Hz) are named by file."""
    recs = [{"file": f, "role": "identification", "frequency_hz": hz, "e_m": em, "e_rms": em / 2}
            for f, hz, em in (("a.csv", 1.0, 1.0), ("b.csv", 1.0, 3.0), ("c.csv", 0.5, 5.0), ("d.csv", None, 7.0))]
    rows = paper_layout([({"model": "m", "method": "varpro", "records": recs}, {})], "identification")[2:]
    assert rows == ["| 1 (a.csv) | 1.00 / 0.50 |", "| 1 (b.csv) | 3.00 / 1.50 |", "| 0.5 | 5.00 / 2.50 |",
                    "| d.csv | 7.00 / 3.50 |"]


@pytest.mark.parametrize("roles", [("identification",), ("identification", "validation")])
def test_a_ranking_on_fitted_data_says_so(roles):
    from hysbench.benchmarks.matrix.report import dataset_section
    recs = [{"file": f"{r}.csv", "role": r, "frequency_hz": 1.0, "e_m": 2.0, "e_rms": 1.0} for r in roles]
    cell = {"dataset": "d", "model": "classical-pi", "method": "varpro", "status": "ok", "records": recs,
            "n_params": 15, "fitness": 1.0, "fit_seconds": 0.1, "simulate_seconds": 0.01}
    text = "\n".join(dataset_section("d", [cell], [], {}))
    assert ("No validation records: every score is on the data its model was fitted to" in text) == (len(roles) == 1)


def test_a_long_note_is_cut_at_a_clause_and_says_where_the_rest_is():
    from hysbench.benchmarks.matrix.report import _shortened

    long = "varpro: linear solve regularised: " + "; ".join(f"-1.00*w{k}_1 +0.5*w{k}_2 (s/s_max 1e-16)" for k in range(40))
    short = _shortened(long)
    assert len(short) < 380 and short.startswith("varpro: linear solve regularised: ")
    assert short.endswith("... (the whole note: the cell's file in cells/)") and long.startswith(short.split(" ... ")[0])
    assert _shortened("parameters at their bounds: gamma (upper 0.1)") == "parameters at their bounds: gamma (upper 0.1)"


def test_cells_are_ranked_by_mean_validation_error_then_worst_and_each_models_best_is_its_first():
    """The order of the ranking table: validation e_rms mean, ties broken by the worst record; a failed cell is
    not ranked; the table shows the worst e_rms and the worst e_m of the records ranked on."""
    from hysbench.benchmarks.matrix.report import best_per_model, ranking

    def cell(model, method, val, ide=(9.0,), status="ok"):
        recs = [{"file": f"v{k}", "role": "validation", "frequency_hz": 1.0, "e_rms": e, "e_m": 3 * e}
                for k, e in enumerate(val)]
        recs += [{"file": f"i{k}", "role": "identification", "frequency_hz": 1.0, "e_rms": e, "e_m": 3 * e}
                 for k, e in enumerate(ide)]
        return {"dataset": "d", "model": model, "method": method, "status": status, "records": recs}

    cells = [cell("a", "lsq", [1.0, 5.0]),  # mean 3, worst 5
             cell("b", "lsq", [4.0, 4.0]),  # mean 4, worst 4
             cell("a", "varpro", [2.0, 4.0]),  # mean 3, worst 4: ahead of a / lsq
             cell("c", "lsq", [0.1, 0.1], status="failed")]
    ranked = ranking(cells, "d")
    assert [(r["model"], r["method"]) for r, _ in ranked] == [("a", "varpro"), ("a", "lsq"), ("b", "lsq")]
    top = ranked[0][1]
    assert (top["val_mean"], top["val_worst"], top["val_em_worst"], top["id_mean"]) == (3.0, 4.0, 12.0, 9.0)
    assert [(r["model"], r["method"]) for r, _ in best_per_model(ranked)] == [("a", "varpro"), ("b", "lsq")]
