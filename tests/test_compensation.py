"""The tracking benchmark: plant, references, a plant that is the model, PI loop, CLI."""

import json

import numpy as np
import pytest

from hysbench.benchmarks.cli import main as cli_main
from hysbench.benchmarks.compensation.controllers import ModelInverse
from hysbench.benchmarks.compensation.plant import DEAPlant, ModelPlant
from hysbench.benchmarks.compensation.references import references
from hysbench.benchmarks.compensation.run import compensate
from hysbench.data.dataset import Dataset, Record, load_dataset, save_dataset
from hysbench.data.dea_sensor import LaserSensor
from hysbench.data.metrics import e_rms
from hysbench.data.protocol import paper_voltage, protocol_time, role_of, simulated_dataset, weight_of
from hysbench.data.virtual_dea import command_voltage, default_dataset_path, displacement_mm
from hysbench.identification.api import identify
from hysbench.models import get_model
from hysbench.models import inverse as inverse_module
from hysbench.models.errors import HysbenchError

DT = 1e-3


def test_open_loop_plant_is_the_data_generator():
    u = command_voltage(1.0, 3000)
    plant = DEAPlant(seed=5)
    run = plant.run(np.zeros(u.size), u)
    x = displacement_mm(u)
    np.testing.assert_array_equal(run.x, x)
    np.testing.assert_array_equal(run.y, LaserSensor().measure(x, np.random.default_rng(5)))
    assert not run.clipped.any()


def test_plant_clips_and_counts_commands_outside_the_limits():
    ff = np.concatenate([np.full(10, 1.0), np.full(5, 3.0), np.full(5, 0.1)])
    run = DEAPlant().run(np.zeros(ff.size), ff)
    assert run.clipped.sum() == 10
    assert run.u.max() == 2.5 and run.u.min() == 0.5


def test_pi_loop_holds_a_constant_reference():
    n = 20000
    run = DEAPlant().run(np.full(n, 5.0), np.zeros(n), kp=0.1, ki=7.0)
    tail = run.y[-5000:]
    assert abs(tail.mean() - 5.0) < 0.01
    assert tail.std() < 0.03  # the sensor noise (0.01 mm) fed back, no oscillation


def test_compensating_a_plant_that_is_the_identified_model_leaves_only_the_noise():
    truth = get_model("classical-pi")
    rng = np.random.default_rng(2)
    params = {n: float(rng.uniform(0.2, 1.0)) for n in truth.param_names}
    ds = simulated_dataset(truth, params, n_periods=2, frequencies=(0.2, 1.0))
    for r in ds.records:
        r.role = "identification"
    fit = identify(truth, ds, method="varpro")
    model = fit.model_instance()
    noise = 0.01
    plant = ModelPlant(model, fit.params, fit.input_range, noise_sd=noise, seed=1)  # the plant IS the fitted model
    t = np.arange(8000) * DT
    ref = model.simulate(1.5 - 0.9 * np.cos(2 * np.pi * 0.5 * t), DT, fit.params, input_range=fit.input_range)
    inv = model.invert(ref, DT, fit.params, input_range=fit.input_range, input_limits=(0.5, 2.5))
    run = plant.run(ref, inv.u)
    assert inv.n_clipped == 0 and not run.clipped.any()
    err = run.y - ref
    assert np.sqrt(np.mean(err ** 2)) == pytest.approx(noise, rel=0.1)
    np.testing.assert_allclose(run.x, ref, atol=1e-8)  # the true output: exact up to the fit's rounding
    assert e_rms(run.y, ref) < 100 * 1.1 * noise / np.ptp(ref)


def test_references_span_the_stable_loops_and_start_at_rest():
    ds = load_dataset(default_dataset_path())
    refs = {r.name: r for r in references(ds, DT)}
    assert set(refs) == {f"sine-{f:g}Hz" for f in (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1)} | {"triangle", "multisine",
                                                                                           "random"}
    rec = next(r for r in ds.records if r.frequency_hz == 0.4)
    sine = refs["sine-0.4Hz"]
    assert sine.y.size == rec.u.size and sine.y[0] == 0.0
    scored = sine.y[sine.scored]
    loop = rec.y[rec.scored]
    margin = 0.05 * np.ptp(loop)  # the central 90 % of the stable loop's range
    assert scored.min() == pytest.approx(loop.min() + margin, abs=1e-3)
    assert scored.max() == pytest.approx(loop.max() - margin, abs=1e-3)
    assert refs["random"].scored.start * DT >= 430.0


def test_cli_bad_input_is_one_line_and_exit_2(capsys, tmp_path):
    assert cli_main(["compensate", str(default_dataset_path()), "--models", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown model 'nope'" in err[0]
    assert cli_main(["compensate", str(default_dataset_path()), "--bandwidth", "-1"]) == 2
    assert cli_main(["compensate", str(tmp_path / "missing"), "--model", "mrpim"]) == 2
    assert cli_main(["compensate", str(default_dataset_path()), "--references", "nope", "--model", "mrpim"]) == 2
    assert not (tmp_path / "compensation.md").exists()


def test_cli_writes_report_and_json(tmp_path, capsys):
    out = tmp_path / "res"
    code = cli_main(["compensate", str(default_dataset_path()), "--models", "classical-pi,mrpim+delay",
                     "--references", "sine-1Hz", "--out", str(out), "--quiet"])
    assert code == 0
    data = json.loads((out / "compensation.json").read_text())
    cell = data["references"]["sine-1Hz"]
    assert set(cell) == {"linear", "classical-pi", "pi", "pi+linear", "pi+classical-pi"}
    assert set(cell["classical-pi"]) >= {"e_rms", "e_m", "clipped"}
    assert "mrpim+delay" in data["not_invertible"]
    assert "mrpim+delay: cannot be inverted" in capsys.readouterr().out
    assert (out / "compensation.md").read_text().count("| sine-1Hz |") == 2


def small_dea_dataset(frequencies=(0.2, 0.4, 1.0), n_periods=2) -> Dataset:
    """The virtual DEA's physics (no noise) on the protocol's drive, two periods per record: short enough
    for a compensation run in seconds (references run as long as their records)."""
    records = []
    for f in frequencies:
        t = protocol_time(f, n_periods, DT)
        u = paper_voltage(t, f)
        records.append(Record(file=f"f{f:g}Hz.npz", t=t, u=u, y=displacement_mm(u), role=role_of(f),
                              frequency_hz=f, weight=weight_of(f)))
    return Dataset(name="small-dea", records=records, input_unit="kV", output_unit="mm")


def test_identifier_options_reach_the_fit_and_the_inverse_asked_for_runs():
    ds = small_dea_dataset()
    quiet = lambda msg: None  # noqa: E731
    stable, _ = compensate(ds, ["classical-pi", "mrpim"], method="varpro", reference_names=["sine-1Hz"], log=quiet,
                           identify_options={"stable_inverse": True}, inverse="exact")
    plain, _ = compensate(ds, ["mrpim"], method="varpro", reference_names=["sine-1Hz"], log=quiet)
    for name in ("classical-pi", "mrpim"):
        m = stable["models"][name]
        assert m["identify_options"] == {"stable_inverse": True}
        assert any("stable_inverse: linear solves constrained" in n for n in m["notes"])  # the fit ran it
        assert m["inverse"] == "numerical (exact)"
    assert not any("stable_inverse" in n for n in plain["models"]["mrpim"]["notes"])
    assert stable["inverse_option"] == "exact" and plain["inverse_option"] == "auto"
    assert plain["models"]["mrpim"]["inverse"] == "numerical (reference-driven)"  # auto: mrpim has rate terms
    inv = ModelInverse.identify("classical-pi", ds, method="varpro", inverse="exact", stable_inverse=True)
    assert inv.fit.options["varpro"]["stable_inverse"] is True and inv.causal_inverse == "exact"


def test_an_inverse_the_fit_cannot_run_is_reported_and_the_others_kept(monkeypatch):
    # the reference-driven inverse needs an increasing loading curve: the guide's gain made negative for a
    # model without rate terms (classical P-I), kept for one with them (MRPIM)
    guide_gain = inverse_module.guide_gain
    monkeypatch.setattr(inverse_module, "guide_gain", lambda s, r: guide_gain(s, r) if s.q != 0.0 else -1.0)
    result, runs = compensate(small_dea_dataset(), ["classical-pi", "mrpim"], method="varpro",
                              reference_names=["sine-1Hz"], log=lambda msg: None, inverse="reference-driven")
    assert "reference-driven inverse needs an increasing loading curve" in result["not_invertible"]["classical-pi"]
    assert list(result["models"]) == ["mrpim"] and "mrpim" in runs["sine-1Hz"]
    assert result["models"]["mrpim"]["inverse"] == "numerical (reference-driven)"
    with pytest.raises(HysbenchError, match="no model to compare: classical-pi cannot be inverted"):
        compensate(small_dea_dataset(), ["classical-pi"], method="varpro", reference_names=["sine-1Hz"],
                   log=lambda msg: None, inverse="reference-driven")


@pytest.mark.parametrize("extra, named", [
    (["--option", "nosuch=1"], "classical-pi: unknown option 'nosuch' for method 'varpro'"),
    (["--option", "stable_inverse"], "--option 'stable_inverse' is not KEY=VALUE"),
    (["--option", "stable_inverse=maybe"], "option stable_inverse must be true or false"),
    (["--models", "classical-pi,rate-dependent-pi", "--option", "stable_inverse=true"],
     "rate-dependent-pi: option stable_inverse: model 'rate-dependent-pi' does not state"),
    (["--method", "varpro+lsq", "--option", "stable_inverse=true"], "stage 'lsq' after 'varpro'"),
    (["--inverse", "inexact"], "argument --inverse: invalid choice: 'inexact'"),
])
def test_cli_refuses_bad_identifier_options_and_inverse_in_one_line_before_any_fit(extra, named, capsys, tmp_path,
                                                                                     monkeypatch):
    fitted = []
    monkeypatch.setattr(ModelInverse, "identify", classmethod(lambda *a, **k: fitted.append(a)))
    argv = ["compensate", str(default_dataset_path()), "--method", "varpro", "--out", str(tmp_path / "new")]
    argv += extra if "--models" in extra else ["--models", "classical-pi"] + extra
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0], err
    assert not fitted and not (tmp_path / "new").exists()
    with pytest.raises(HysbenchError, match="inverse must be one of auto, exact, reference-driven"):
        compensate(default_dataset_path(), ["classical-pi"], inverse="inexact", log=lambda m: None)


def test_cli_options_reach_the_report_and_its_command_line(tmp_path):
    data = save_dataset(small_dea_dataset(), tmp_path / "small")
    out = tmp_path / "res"
    assert cli_main(["compensate", str(data), "--model", "classical-pi", "--method", "varpro", "--references",
                     "sine-1Hz", "--option", "stable_inverse=true", "--option", "inverse_radius=0.99", "--inverse",
                     "exact", "--seed", "3", "--out", str(out), "--quiet"]) == 0
    result = json.loads((out / "compensation.json").read_text())
    assert result["seed"] == 3
    assert result["models"]["classical-pi"]["identify_options"] == {"stable_inverse": True, "inverse_radius": 0.99}
    assert result["models"]["classical-pi"]["inverse"] == "numerical (exact)"
    report = (out / "compensation.md").read_text()
    assert ("--option stable_inverse=true --option inverse_radius=0.99 --inverse exact --seed 3" in report
            and "| classical-pi | varpro (stable_inverse=True, inverse_radius=0.99) | numerical (exact) |" in report)


def test_closed_loop_kernel_is_the_pi_law_written_out():
    """run_loop against the module's timing and PI law in plain Python (conditional integration,
    clipping), the sensor as its docstring's formula, the actuator stepped by dea_physics."""
    from hysbench.models import dea_physics

    plant = DEAPlant(seed=3)
    n, dt, kp, ki = 400, plant.dt, 0.2, 9.0
    reference = np.concatenate([np.full(100, 2.0), np.full(100, 60.0), np.full(100, -5.0), np.full(100, 4.0)])
    feedforward = 1.0 + 0.3 * np.sin(np.arange(n) * 0.05)
    run = plant.run(reference, feedforward, kp=kp, ki=ki)

    rest_mm, mm_per_volt, full_scale_v, lsb_v, rest_code, lsb_mm = plant.sensor.constants()
    noise = plant.sensor.noise_volts(n, np.random.default_rng(3))
    phys, n_br = plant.params.vector(), plant.params.n_branches
    lo, hi = plant.u_limits
    state = dea_physics.initial_state(phys, n_br)
    u = [min(max(feedforward[0], lo), hi)]
    m = dea_physics.substeps(u[0], dt, phys, n_br)
    integral, y, clipped = 0.0, [], [u[0] != feedforward[0]]
    for k in range(n):
        x = 1e3 * phys[5] * (state[0] - phys[3])
        volts = min(max((rest_mm + x) / mm_per_volt + noise[k], 0.0), full_scale_v)
        y.append((round(volts / lsb_v) - rest_code) * lsb_mm)
        if k == n - 1:
            break
        e = reference[k] - y[k]
        wanted = feedforward[k + 1] + kp * e + integral + ki * dt * e
        if not ((wanted > hi and e > 0) or (wanted < lo and e < 0)):
            integral += ki * dt * e
        v = feedforward[k + 1] + kp * e + integral
        u.append(min(max(v, lo), hi))
        clipped.append(u[-1] != v)
        assert dea_physics.advance_sample(state, u[k], u[k + 1], dt, m, phys, n_br)
    assert run.clipped.sum() > 50 and not run.clipped.all()  # both the clipped and the free law are exercised
    np.testing.assert_allclose(run.u, u, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(run.y, y, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(run.clipped, clipped)


def test_the_summary_counts_the_sines_run_and_says_higher_when_the_inverse_is_worse():
    """The findings name how many sines were run (not always seven), a model worse than the linear gain as so
    many times higher, and a run without a sine as not ranked."""
    from hysbench.benchmarks.compensation.report import summary

    def cell(e):
        return {"e_rms": e, "e_m": e, "clipped": 0}

    by = {"linear": cell(10.0), "mrpim": cell(25.0), "pi": cell(3.0), "pi+linear": cell(2.0), "pi+mrpim": cell(2.5)}
    result = {"models": {"mrpim": {}}, "pi": {"bandwidth_hz": 5.0},
              "references": {"sine-0.2Hz": by, "sine-1Hz": by, "random": by}}
    text = summary(result)
    assert text.startswith("On the two sines the best open-loop inverse is mrpim's: mean e_rms 25 % against 10 % "
                           "for the static linear gain, 2.5x higher;"), text
    assert summary({**result, "references": {"random": by}}).startswith("No sine reference was run")
    result["references"] = {f"sine-{f}Hz": {**by, "mrpim": cell(2.0)} for f in range(7)}
    assert summary(result).startswith("On the seven sines the best open-loop inverse is mrpim's: mean e_rms 2 % "
                                      "against 10 % for the static linear gain, 5x lower; the goal (>= 5x) is reached")


def test_the_report_creates_the_json_files_folder(tmp_path):
    """``--json`` in a folder that does not exist yet (accepted by the check before any work) is written there,
    with the report beside it, not refused after the run with the report half-written."""
    from hysbench.benchmarks.compensation.report import write_report

    cell = {"e_rms": 1.0, "e_m": 2.0, "clipped": 0}
    result = {"seconds": 1.0, "invert_seconds": 0.5, "pi": {"bandwidth_hz": 5.0, "kp": 0.1, "ki": 7.0, "zero_s": 0.016},
              "plant": {"sensor": {"noise_sd_mm": 0.01}, "u_limits_kV": [0.5, 2.5]}, "dataset": "d",
              "dataset_hash": "0" * 12, "linear": {"gain": 4.0, "offset": 1.0}, "models": {}, "not_invertible": {},
              "references": {"sine-1Hz": {"linear": cell, "pi": cell, "pi+linear": cell}}}
    json_path = tmp_path / "new" / "folder" / "c.json"
    write_report(result, {}, tmp_path / "out", json_path)
    assert json.loads(json_path.read_text())["dataset"] == "d" and (tmp_path / "out" / "compensation.md").is_file()
