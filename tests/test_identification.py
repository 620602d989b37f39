"""Identifiers: recovery on data simulated from the paper's Table 2 MRPIM, the
linear solve against slow references, determinism, errors, the Fit and the CLI.

Data: the paper's protocol (eq. 1, Table 1 weights) with two periods per
frequency at 1 ms for varpro; the mpso and determinism tests use a coarser
5 ms step (same protocol, same model; 5x fewer samples) to stay fast.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from hysbench.benchmarks.cli import main as cli_main
from hysbench.data.protocol import dataset_fitness, simulated_dataset
from hysbench.data.dataset import Dataset, Record, save_dataset
from hysbench.identification import (
    METHODS,
    Fit,
    IdentificationError,
    Problem,
    SeparableProblem,
    applicable_methods,
    identify,
)
from hysbench.identification.mpso import reflect
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel, Parameter

NOISE_SD = 0.01  # mm, on outputs of about 5 mm peak-to-peak


@pytest.fixture(scope="module")
def paper_model():
    return get_model("mrpim", offset=False)  # the paper's 20 parameters


@pytest.fixture(scope="module")
def paper(paper_model):
    return paper_model.preset("paper")


@pytest.fixture(scope="module")
def clean(paper_model, paper):
    return simulated_dataset(paper_model, paper)


@pytest.fixture(scope="module")
def noisy(paper_model, paper):
    return simulated_dataset(paper_model, paper, noise_sd=NOISE_SD, seed=1)


@pytest.fixture(scope="module")
def coarse(paper_model, paper):
    return simulated_dataset(paper_model, paper, noise_sd=NOISE_SD, seed=2, dt=5e-3)


@pytest.fixture(scope="module")
def varpro_noisy(paper_model, noisy):
    return identify(paper_model, noisy, "varpro", seed=0)


# --- a model with no linear part, known to the identifiers only by its interface
class TanhModel(HysteresisModel):
    """y = gain * tanh(slope * (u - centre)): no linear parameter, no regressors."""

    name = "test-tanh"

    def __init__(self):
        pass

    def parameters(self, scale=None):
        return (
            Parameter("gain", 1.0, 0.1, 10.0),
            Parameter("slope", 1.0, 0.1, 5.0),
            Parameter("centre", 0.0, -3.0, 3.0),
        )

    def simulate_batch(self, u, dt, param_sets, input_range=None):
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        return P[:, :1] * np.tanh(P[:, 1:2] * (u[None, :] - P[:, 2:3]))


class ExpModel(HysteresisModel):
    """y = a exp(k u) + c: linear in a and c, nonlinear in k; overflows for large k.
    Uses the base class's windowed methods (no overrides)."""

    name = "test-exp"

    def __init__(self):
        pass

    def parameters(self, scale=None):
        return (Parameter("k", 0.0, -1.0, 400.0), Parameter("a", 1.0, -10.0, 10.0, True),
                Parameter("c", 0.0, -10.0, 10.0, True))

    def simulate_batch(self, u, dt, param_sets, input_range=None):
        P = self._check_param_sets(param_sets)
        with np.errstate(over="ignore", invalid="ignore"):
            return P[:, 1:2] * np.exp(P[:, :1] * self._check_input(u, dt)[None, :]) + P[:, 2:3]

    def regressors(self, u, dt, nonlinear, input_range=None):
        u = self._check_input(u, dt)
        with np.errstate(over="ignore"):
            return np.column_stack([np.exp(nonlinear["k"] * u), np.ones_like(u)])


# --- the model interface used by the identifiers --------------------------
def _test_input(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    u = 1.5 + sum(rng.uniform(0.1, 0.6) * np.sin(2 * np.pi * t / rng.uniform(40, 400) + rng.uniform(0, 6))
                  for _ in range(3))
    return u + 0.01 * rng.normal(size=n)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    gamma=st.floats(-0.05, 0.05),
    lam=st.floats(-0.05, 0.05),
    start=st.integers(0, 600),
    length=st.integers(2, 600),
    variant=st.sampled_from([
        {}, {"offset": False}, {"q_term": False, "poly_order": 2}, {"derivative": "smoothed"},
        {"envelopes": False, "n_operators": 5},
    ]),
)
def test_windowed_regressors_are_rows_of_the_full_matrix(seed, gamma, lam, start, length, variant):
    model = get_model("mrpim", **variant)
    u = _test_input(seed, 1300)
    dt = 1e-3
    window = slice(start, start + length)
    nl = {"gamma": gamma, "lambda": lam} if model.envelopes else {}
    full = model.regressors(u, dt, nl, input_range=(0.0, 3.0))[window]
    got = model.windowed_regressors(u, dt, nl, window, input_range=(0.0, 3.0))
    np.testing.assert_allclose(got, full, rtol=1e-12, atol=1e-12)
    sets = np.array([[gamma, lam], [lam, gamma], [0.0, 0.0]])[:, : len(model.nonlinear_names)]
    batch = model.windowed_regressors_batch(u, dt, sets, window, input_range=(0.0, 3.0))
    for row, B in zip(sets, batch):
        one = model.regressors(u, dt, dict(zip(model.nonlinear_names, row)), input_range=(0.0, 3.0))[window]
        np.testing.assert_allclose(B, one, rtol=1e-12, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), start=st.integers(0, 600), length=st.integers(1, 600),
       derivative=st.sampled_from(["backward", "smoothed"]))
def test_windowed_simulation_is_the_window_of_the_full_output(seed, start, length, derivative):
    model = get_model("mrpim", derivative=derivative)
    rng = np.random.default_rng(seed)
    lo, hi = model.bounds()
    P = lo + rng.random((3, lo.size)) * (hi - lo)
    u = _test_input(seed, 1300)
    window = slice(start, start + length)
    full = model.simulate_batch(u, 1e-3, P)[:, window]
    np.testing.assert_allclose(model.simulate_window_batch(u, 1e-3, P, window), full, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(model.simulate_window_batch(u, 1e-3, P[:1], window), full[:1], rtol=1e-12, atol=1e-9)


# --- the linear solve against slow references -----------------------------
def _reference_system(model, records, nonlinear, in_range):
    """Weighted stacked rows built the obvious way from the full regressor matrix."""
    rows, rhs = [], []
    for r in records:
        Phi = model.regressors(r.u, r.dt, nonlinear, input_range=in_range)[r.scored]
        w = math.sqrt(r.weight / r.n_scored)
        rows.append(w * Phi)
        rhs.append(w * r.y[r.scored])
    return np.vstack(rows), np.concatenate(rhs)


def test_linear_solve_equals_weighted_least_squares(noisy):
    model = get_model("mrpim", n_operators=4)  # thresholds below the input span: full rank
    problem = Problem.build(model, noisy.identification)
    sep = SeparableProblem(problem)
    nl = {"gamma": 0.02, "lambda": -0.01}
    sol = sep.solve(nl)
    assert not sol.regularised and sol.condition_number < 1e6
    A, b = _reference_system(model, noisy.identification, nl, problem.input_range)
    ref = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(sol.linear, ref, rtol=1e-7, atol=1e-9)
    assert sol.condition_number == pytest.approx(np.linalg.cond(A / np.linalg.norm(A, axis=0)), rel=1e-6)
    fast = sep.solve(nl, accurate=False)  # the search's normal-equation path
    np.testing.assert_allclose(fast.linear, ref, rtol=1e-6, atol=1e-8)
    # the linear least squares is eq. 9 exactly
    params = model.unpack(sep.full_vector(np.array([0.02, -0.01]), sol.linear))
    assert sol.fitness == pytest.approx(dataset_fitness(model, params, noisy.identification, problem.input_range),
                                        rel=1e-9)


def test_a_model_without_nonlinear_parameters_is_one_linear_solve(noisy):
    model = get_model("classical-pi", n_operators=4, poly_order=0)  # a1 = u already: no p1
    fit = identify(model, noisy, "varpro")
    assert fit.n_evaluations == 1
    problem = Problem.build(model, noisy.identification)
    A, b = _reference_system(model, noisy.identification, {}, problem.input_range)
    ref = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(model.pack(fit.params), ref, rtol=1e-7, atol=1e-9)


def test_linear_solve_keeps_the_bounds_of_linear_parameters(noisy):
    model = get_model("classical-pi", n_operators=4, poly_order=0)
    bounds = {"a1": [0.0, 1.0], "a3": [0.5, 50.0], "offset": [-0.5, 0.5]}  # all three active
    fit = identify(model, noisy, "varpro", bounds=bounds)
    assert fit.diagnostics["varpro"]["bounded_linear_solve"]
    assert any("lsq_linear" in n for n in fit.notes)
    problem = Problem.build(model, noisy.identification, bounds)
    A, b = _reference_system(model, noisy.identification, {}, problem.input_range)
    D = np.linalg.norm(A, axis=0)
    ref = lsq_linear(A / D, b, bounds=(problem.lower * D, problem.upper * D), method="bvls", tol=1e-12).x / D
    got = model.pack(fit.params)
    assert np.all(got >= problem.lower) and np.all(got <= problem.upper)
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-7)
    unconstrained = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.any(unconstrained < problem.lower) and np.any(unconstrained > problem.upper)  # active bounds


def test_directions_the_scored_data_do_not_determine_are_fixed_and_named(noisy, paper):
    # In the scored (stable) period, operators 12 and 13 (thresholds above the 2 kV input span) hold
    # constants that move only through the envelopes, by a fraction of a percent: next to an output
    # offset their weights trade with it. They are fixed at 0 and named; the offset carries the level.
    model = get_model("mrpim")
    start = {"gamma": paper["gamma"], "lambda": paper["lambda"]}
    fit = identify(model, noisy, "varpro", start=start, n_candidates=0, n_starts=1)
    d = fit.diagnostics["varpro"]
    assert fit.undetermined == ["a12", "a13"] and fit.params["a12"] == 0.0 and fit.params["a13"] == 0.0
    assert set(d["undetermined"]) == {"a12", "a13"} and d["condition_number"] < 1e6 and not d["regularised"]
    assert any("nearly constant" in n and "a12, a13" in n for n in fit.notes)
    assert "undetermined by the scored data (fixed): a12 = 0, a13 = 0" in fit.summary()
    assert Fit.from_dict(fit.to_dict()).undetermined == ["a12", "a13"]
    # what they carried in the scored windows was a level: the fit stays near the noise floor
    assert fit.fitness <= 1.05 * dataset_fitness(get_model("mrpim", offset=False), paper, noisy.identification)


def test_paper_model_weights_a12_a13_are_nearly_collinear(varpro_noisy):
    # Without offset the two columns differ only through the small rate
    # dependence of the constants they hold: well above 1e3, not regularised.
    d = varpro_noisy.diagnostics["varpro"]
    assert 1e3 < d["condition_number"] < 1e6 and not d["regularised"] and not varpro_noisy.notes


# --- recovery ---------------------------------------------------------------------
def test_varpro_recovers_gamma_and_lambda_without_noise(paper_model, paper, clean):
    fit = identify(paper_model, clean, "varpro", seed=0)
    for name in ("gamma", "lambda"):
        assert abs(fit.params[name] - paper[name]) <= 0.01 * abs(paper[name]), (name, fit.params[name])
    assert max(s.e_rms for s in fit.records) < 0.1  # percent, validation records included
    assert fit.fitness < 1e-5


def test_varpro_reaches_the_noise_floor(paper_model, paper, noisy, varpro_noisy):
    fit = varpro_noisy
    truth = dataset_fitness(paper_model, paper, noisy.identification, fit.input_range)
    floor = sum(r.weight for r in noisy.identification) * NOISE_SD**2  # expected eq. 9 of the noise alone
    assert truth == pytest.approx(floor, rel=0.05)
    assert fit.fitness <= truth * (1 + 1e-9)  # as good as the true parameters
    assert fit.fitness >= 0.98 * truth  # and not fitting the noise
    for name in ("gamma", "lambda"):
        assert abs(fit.params[name] - paper[name]) <= 0.02 * abs(paper[name])


def test_a_search_reaching_an_earlier_optimum_stops_there(noisy):
    """With a merge radius of the whole bound width every later search is in the first one's basin and
    must stop at once with its optimum; with a vanishing radius none may stop early."""
    merged = identify("mrpim", noisy, "varpro", seed=0, n_starts=2, merge_radius=1.0)
    first, second = merged.diagnostics["varpro"]["local_searches"]
    assert first["status"] != -2
    assert second["status"] == -2 and second["end"] == first["end"]
    assert second["n_evaluations"] < first["n_evaluations"]
    apart = identify("mrpim", noisy, "varpro", seed=0, n_starts=2, merge_radius=1e-12)
    assert [s["status"] for s in apart.diagnostics["varpro"]["local_searches"]].count(-2) == 0


def test_fitness_is_eq9_and_scores_are_per_record(paper_model, noisy, varpro_noisy):
    fit = varpro_noisy
    assert fit.fitness == pytest.approx(
        dataset_fitness(paper_model, fit.params, noisy.identification, fit.input_range), rel=1e-9)
    assert [s.file for s in fit.records] == [r.file for r in noisy.records]
    assert [s.role for s in fit.records] == [r.role for r in noisy.records]
    assert fit.fitted_on == [r.file for r in noisy.identification]
    assert fit.n_params == 20 and fit.method == "varpro"


def test_mpso_over_all_20_parameters(paper_model, coarse, capsys):
    fit = identify(paper_model, coarse, "mpso", seed=0, swarm_size=30, iterations=60)
    d = fit.diagnostics["mpso"]
    assert fit.n_params == 20 and fit.n_evaluations == 30 * 61
    lo, hi = paper_model.bounds(Problem.build(paper_model, coarse.identification).scale)
    x = paper_model.pack(fit.params)
    assert np.all(x >= lo) and np.all(x <= hi) and d["positions_in_bounds"]
    assert fit.history[0][1] == d["initial_best_fitness"]
    assert all(b[1] <= a[1] for a, b in zip(fit.history, fit.history[1:]))
    assert fit.fitness * 10 <= d["initial_best_fitness"]
    vp = identify(paper_model, coarse, "varpro", seed=0)
    with capsys.disabled():
        print(f"\nmpso (30 x 61 evaluations) fitness {fit.fitness:.4g} vs varpro {vp.fitness:.4g} "
              f"(mpso initial best {d['initial_best_fitness']:.4g})")


@pytest.mark.parametrize("method", METHODS)
def test_same_seed_same_fit(method, paper_model, coarse):
    opts = {"mpso": {"swarm_size": 12, "iterations": 8}, "lsq": {"max_nfev": 15},
            "varpro": {"n_candidates": 6, "max_nfev": 12}}
    options = {}
    for stage in method.split("+"):
        options.update({(f"{stage}.{k}" if "+" in method else k): v for k, v in opts[stage].items()})
    a = identify(paper_model, coarse, method, seed=7, **options).to_dict()
    b = identify(paper_model, coarse, method, seed=7, **options).to_dict()
    a.pop("fit_seconds"), b.pop("fit_seconds")
    assert a == b


def test_the_seed_matters_for_mpso(paper_model, coarse):
    a = identify(paper_model, coarse, "mpso", seed=1, swarm_size=12, iterations=5)
    b = identify(paper_model, coarse, "mpso", seed=2, swarm_size=12, iterations=5)
    assert a.params != b.params


def test_lsq_polish_does_not_worsen_varpro(paper_model, noisy, varpro_noisy):
    fit = identify(paper_model, noisy, "varpro+lsq", seed=0)
    assert fit.fitness <= varpro_noisy.fitness * (1 + 1e-9)
    assert {"varpro", "lsq"} <= set(fit.diagnostics)


def test_lsq_and_mpso_fit_a_model_without_linear_part():
    model = TanhModel()
    truth = {"gain": 3.0, "slope": 1.7, "centre": 1.2}
    t = np.arange(2000) * 1e-3
    records = []
    for f, role in ((1.0, "identification"), (2.0, "identification"), (1.5, "validation")):
        u = 1.5 + np.sin(2 * np.pi * f * t)
        records.append(Record(file=f"{f}.npz", t=t, u=u, y=model.simulate(u, 1e-3, truth), role=role,
                              frequency_hz=f))
    data = Dataset("tanh", records)
    fit = identify(model, data, "lsq", start={"gain": 1.0, "slope": 1.0, "centre": 0.5})
    for k, v in truth.items():
        assert fit.params[k] == pytest.approx(v, rel=1e-6)
    assert identify(model, data, "auto").method == "lsq"
    assert applicable_methods(model) == ["mpso", "lsq", "mpso+lsq"]
    mp = identify(model, data, "mpso", swarm_size=20, iterations=30)
    assert mp.fitness < mp.diagnostics["mpso"]["initial_best_fitness"]


def test_varpro_on_a_generic_partly_linear_model_survives_overflow(noisy):
    model = ExpModel()
    truth = {"k": 0.8, "a": 2.0, "c": -1.0}
    records = [Record(file=r.file, t=r.t, u=r.u, y=model.simulate(r.u, r.dt, truth), role=r.role,
                      frequency_hz=r.frequency_hz, weight=r.weight) for r in noisy.records]
    fit = identify(model, Dataset("exp", records), "varpro", seed=0)  # some candidates overflow to inf
    for k, v in truth.items():
        assert fit.params[k] == pytest.approx(v, rel=1e-6)
    assert fit.fitness < 1e-12


# --- errors ---------------------------------------------------------------------
def test_varpro_on_a_model_without_linear_part_names_both(noisy):
    with pytest.raises(IdentificationError, match=r"varpro.*test-tanh|test-tanh.*varpro"):
        identify(TanhModel(), noisy, "varpro")
    with pytest.raises(IdentificationError, match=r"varpro\+lsq.*test-tanh"):
        identify(TanhModel(), noisy, "varpro+lsq")


def test_a_dataset_without_identification_records_is_refused(noisy):
    only_validation = Dataset("val-only", noisy.validation)
    with pytest.raises(IdentificationError, match="val-only.*no identification records.*mrpim"):
        identify("mrpim", only_validation, "varpro")


@pytest.mark.parametrize("method, options, message", [
    ("newton", {}, "unknown method 'newton'"),
    ("varpro", {"swarm_size": 3}, "unknown option 'swarm_size'"),
    ("mpso", {"swarm_size": 0}, "swarm_size must be an integer >= 1"),
    ("mpso", {"v_max": "fast"}, "v_max must be a finite number"),
    ("varpro+lsq", {"mpso.iterations": 3}, "unknown option 'mpso.iterations'"),
    ("varpro", {"fit_on": ["nope.npz"]}, "no record"),
    ("varpro", {"bounds": {"zeta": [0, 1]}}, "no parameter 'zeta'"),
    ("varpro", {"bounds": {"gamma": [1, 0]}}, "not <= high"),
    ("lsq", {"start": {"zeta": 1.0}}, "no parameter 'zeta'"),
    ("mpso", {"bounds": {"gamma": [-np.inf, 0.1]}}, "finite bounds"),
])
def test_bad_methods_and_options_are_refused(noisy, method, options, message):
    with pytest.raises(IdentificationError, match=message):
        identify("mrpim", noisy, method, **options)


def test_identification_errors_reach_the_cli_as_one_line(tmp_path, capsys):
    """An identifier's refusal is a HysbenchError: the CLI prints one line and exits 2."""
    code = cli_main(["fit", str(tmp_path / "missing"), "--model", "mrpim", "--method", "varpro"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "error" in err


# --- the Fit ------------------------------------------------------------------------
def test_fit_round_trips_through_json_and_simulates(paper_model, noisy, varpro_noisy):
    fit = varpro_noisy
    again = Fit.from_dict(json.loads(json.dumps(fit.to_dict())))
    assert again.to_dict() == fit.to_dict()
    r = noisy.validation[0]
    expected = paper_model.simulate(r.u, r.dt, fit.params, input_range=fit.input_range)
    np.testing.assert_array_equal(again.simulate(r.u, r.dt), expected)
    assert [s.as_dict() for s in again.score(noisy.validation)] == [
        s.as_dict() for s in fit.records if s.role == "validation"]
    with pytest.raises(IdentificationError):
        Fit.from_dict({"format": "something else"})


def test_the_linear_solve_around_a_fit_reproduces_it(noisy, varpro_noisy):
    fit = varpro_noisy  # what the posterior builds on: the optimum and the solve given gamma, lambda
    sep = SeparableProblem(Problem.for_fit(fit, noisy))
    sol = sep.solve({"gamma": fit.params["gamma"], "lambda": fit.params["lambda"]})
    np.testing.assert_allclose(sol.linear, [fit.params[n] for n in sep.linear_names], rtol=1e-10, atol=1e-12)
    assert sol.fitness == pytest.approx(fit.fitness, rel=1e-9)
    blocks = sep.record_designs({"gamma": fit.params["gamma"], "lambda": fit.params["lambda"]})
    assert [b[0].shape for b in blocks] == [(r.n_scored, len(sep.linear_names)) for r in noisy.identification]


def test_parameters_left_at_their_bounds_are_named(paper_model, coarse):
    fit = identify(paper_model, coarse, "varpro", bounds={"gamma": [0.0, 0.01]}, n_candidates=4)
    assert fit.params["gamma"] == pytest.approx(0.01) and fit.diagnostics["at_bounds"] == ["gamma"]
    assert any("at their bounds: gamma (upper 0.01)" in n for n in fit.notes)


def test_fit_on_a_subset_of_records(paper_model, noisy):
    held_out = "f0.2Hz.npz"
    files = [r.file for r in noisy.records if r.file != held_out]
    fit = identify(paper_model, noisy, "varpro", fit_on=files, n_starts=1)
    roles = {s.file: s.role for s in fit.records}
    assert roles[held_out] == "validation" and sum(v == "identification" for v in roles.values()) == 6
    assert fit.fitted_on == files


def _split_recording(y_after_scale: float) -> Dataset:
    """One 1 Hz recording of four periods: periods 2-3 identify, period 4 validates; the validation
    window's output is multiplied by ``y_after_scale``."""
    t = np.arange(4000) * 1e-3
    u = 1.5 - np.cos(2 * np.pi * t)
    y = u**2 + 0.3 * np.sin(2 * np.pi * t)
    y[3000:] *= y_after_scale
    return Dataset(name="split", records=[
        Record(file="rec.csv#1", t=t, u=u, y=y, role="identification", frequency_hz=1.0, window=(1.0, 3.0)),
        Record(file="rec.csv#2", t=t, u=u, y=y, role="validation", frequency_hz=1.0, window=(3.0, 4.0))])


def test_bounds_and_start_see_no_output_of_the_validation_window():
    """The data scale that sets default bounds and starts reads no output of another record's window: another
    output in the validation window (the same recording's last period) leaves the problem unchanged."""
    model = get_model("classical-pi", n_operators=4)
    same, other = (Problem.build(model, ds.identification, others=ds.validation)
                   for ds in (_split_recording(k) for k in (1.0, 3.0)))
    assert same.scale == other.scale
    assert np.array_equal(same.lower, other.lower) and np.array_equal(same.upper, other.upper)
    assert np.array_equal(same.start_vector(None), other.start_vector(None))
    rec = same.records[0]
    inside = Problem.build(model, [Record(file="r", t=rec.t, u=rec.u, y=3.0 * rec.y, frequency_hz=1.0, window=(1.0, 3.0))])
    assert not np.array_equal(inside.upper, same.upper)  # the scale does follow the outputs inside the window


def test_the_posteriors_prior_sees_no_output_of_the_validation_window():
    from hysbench.identification.posterior import LogPosterior

    model = get_model("classical-pi", n_operators=4)
    same, other = (LogPosterior(model, ds.identification, others=ds.validation).problem
                   for ds in (_split_recording(k) for k in (1.0, 3.0)))
    assert same.scale == other.scale and np.array_equal(same.upper, other.upper)


# --- the command line -------------------------------------------------------------
def test_cli_fit_writes_the_json(tmp_path, noisy, capsys):
    folder = save_dataset(noisy, tmp_path / "data")
    out = tmp_path / "fit.json"
    rc = cli_main(["fit", str(folder), "--model", "classical-pi", "--method", "varpro", "--json", str(out),
                   "--hyper", "n_operators=6"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "fitness" in printed and "f0.05Hz.npz" in printed
    d = json.loads(out.read_text())
    for key in ("model", "method", "params", "fitness", "fit_seconds", "n_evaluations", "records"):
        assert key in d
    assert d["model"] == "classical-pi" and d["method"] == "varpro" and len(d["params"]) == 8
    assert len(d["records"]) == 7
    assert set(d["records"][0]) == {"file", "frequency_hz", "role", "e_m", "e_rms"}


@pytest.mark.parametrize("args, message", [
    (["--model", "nope"], "unknown model 'nope'"),
    (["--model", "mrpim", "--method", "newton"], "unknown method"),
    (["--model", "mrpim", "--option", "n_starts"], "is not KEY=VALUE"),
    (["--model", "mrpim", "--option", "n_starts=-1"], "n_starts must be"),
    (["--model", "mrpim", "--hyper", "n_operators=0"], "n_operators"),
    (["--model", "mrpim", "--hyper", "n_operatorz=9"], "unknown hyperparameter 'n_operatorz' for model 'mrpim'"),
    (["--model", "mrpim", "--seed", "-3"], "--seed"),
    (["--model", "mrpim", "--json", "/proc/hysbench-no/fit.json"], "cannot create output folder"),
])
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, noisy, capsys, args, message):
    folder = save_dataset(noisy, tmp_path / "data")
    rc = cli_main(["fit", str(folder)] + args)
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and message in err


def test_cli_refuses_a_missing_dataset(tmp_path, capsys):
    assert cli_main(["fit", str(tmp_path / "none"), "--model", "mrpim"]) == 2
    assert "no such dataset" in capsys.readouterr().err


# --- mpso's bound handling ------------------------------------------------------------
@given(st.lists(st.floats(-1.0, 2.0), min_size=1, max_size=20), st.floats(-1.0, 1.0))
def test_reflection_keeps_positions_inside(zs, v):
    z = np.array(zs)
    vel = np.full_like(z, v)
    z2, v2 = reflect(z, vel)
    assert np.all((z2 >= 0.0) & (z2 <= 1.0))
    moved = (z < 0) | (z > 1)
    assert np.all(np.abs(v2[moved]) == pytest.approx(0.5 * abs(v)))
    np.testing.assert_array_equal(z2[~moved], z[~moved])


def test_varpro_searches_log_scale_parameters_in_log_coordinates():
    """A relaxation time of 0.05 s in bounds [0.01, 1000] x T: log-scale candidates and steps find it
    from the model's default start (tau1 = T); the start and end of each search are reported in z."""
    model = get_model("mrpim+relaxation")
    assert [p.name for p in model.parameters() if p.log_scale] == ["tau1"]
    # a12, a13 (plays above the input span, nearly constant in the scored windows) at 0: varpro fixes them
    truth = {**get_model("mrpim").preset("paper"), "a12": 0.0, "a13": 0.0, "tau1": 0.05, "c1": 0.8}
    ds = simulated_dataset(model, truth, frequencies=(0.2, 0.4, 1.0), n_periods=2)
    fit = identify(model, ds, method="varpro", seed=0)
    assert fit.params["tau1"] == pytest.approx(0.05, rel=0.01)
    for s in fit.diagnostics["varpro"]["local_searches"]:
        lo, hi = fit.bounds["tau1"]
        assert lo <= s["start"][model.nonlinear_names.index("tau1")] <= hi


@pytest.mark.parametrize("method", ["varpro", "lsq"])
def test_fit_records_that_all_weigh_zero_are_refused(method):
    """eq. 9 with every k_m = 0 has nothing to fit: varpro divided by zero, lsq 'succeeded' on nothing."""
    model = get_model("mrpim")
    ds = simulated_dataset(model, model.preset("paper"), n_periods=1.5, seed=1, frequencies=(0.4, 1.0),
                           name="zero-weights")
    for r in ds.records:
        r.weight = 0.0
    with pytest.raises(IdentificationError, match="weight 0"):
        identify(model, ds, method=method, seed=0)


def test_more_parameters_than_scored_samples_are_refused():
    """A model with more parameters than the fit records' scored samples is refused in one message when the
    problem is built, before any search runs."""
    model = get_model("classical-pi", n_operators=60)
    ds = simulated_dataset(get_model("mrpim"), get_model("mrpim").preset("paper"), n_periods=1.5, seed=1,
                           frequencies=(1.0,), dt=0.025, name="short")
    assert sum(r.n_scored for r in ds.identification) < model.n_params
    with pytest.raises(IdentificationError, match="more than the .* scored samples"):
        identify(model, ds, method="varpro", seed=0)


def test_the_report_says_varpro_fixes_operators_it_lists_as_undetermined_and_which_configuration_has_an_offset():
    from types import SimpleNamespace

    from hysbench.benchmarks.reports.identification import collinear_operators
    from hysbench.models import get_model

    def fit(offset: bool, undetermined: list[str]):
        params = {"a12": 0.0 if undetermined else 1.8, "a13": 0.0 if undetermined else 12.8,
                  **({"offset": 0.1} if offset else {})}
        return SimpleNamespace(method="varpro", model="mrpim", input_range=(0.5, 2.5), params=params,
                               undetermined=undetermined, model_instance=lambda: get_model("mrpim", offset=offset),
                               diagnostics={"varpro": {"condition_number": 3e3, "regularised": False}})

    with_offset, without = collinear_operators([("with", [fit(True, ["a12", "a13"])]), ("without", [fit(False, [])])])
    assert "fixes them at 0" in with_offset and "has none" not in with_offset
    assert "a12 = 1.800" in without and "(this configuration has none)" in without
