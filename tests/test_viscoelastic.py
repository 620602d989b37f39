"""The ``viscoelastic`` model: interface, agreement with the data generator, batching,
regressors, bounds, and identification of its own simulated data."""

from __future__ import annotations

import numpy as np
import pytest

from hysbench.data import Dataset, Record
from hysbench.data import virtual_dea as vd
from hysbench.identification import identify
from hysbench.models import DataScale, ModelError, get_model, list_models

DT = 1e-3


@pytest.fixture(scope="module")
def model():
    return get_model("viscoelastic")


@pytest.fixture(scope="module")
def truth(model):
    return model.preset("virtual-dea")


def test_registered_with_its_parameters(model):
    assert "viscoelastic" in list_models()
    assert model.param_names == ("mu", "eta_v", "mu1", "mu2", "mu3", "tau1", "tau2", "tau3", "length", "offset")
    assert model.linear_names == ("length", "offset")
    assert model.has_linear_part
    assert get_model("viscoelastic", n_branches=2).n_params == 8
    assert get_model("viscoelastic", offset=False).linear_names == ("length",)


def test_preset_is_the_virtual_dea(model, truth):
    u = vd.command_voltage(0.4, 6000)
    np.testing.assert_allclose(model.simulate(u, DT, truth), vd.displacement_mm(u, DT), rtol=1e-13, atol=1e-13)
    assert [truth[f"tau{k + 1}"] for k in range(3)] == list(vd.TRUTH.tau_k)


def test_batched_equals_single(model, truth):
    u = vd.command_voltage(1.0, 3000)
    base = model.pack(truth)
    rng = np.random.default_rng(3)
    P = base * np.exp(rng.uniform(-0.3, 0.3, (5, base.size)))
    P[:, -1] = rng.uniform(-1, 1, 5)  # offsets
    Y = model.simulate_batch(u, DT, P)
    assert Y.shape == (5, u.size)
    for i in range(5):
        assert np.array_equal(Y[i], model.simulate(u, DT, P[i]))
    assert len({Y[i].tobytes() for i in range(5)}) == 5


def test_regressors_reproduce_the_output(model, truth):
    u = vd.command_voltage(0.2, 5000)
    nonlinear = {k: truth[k] for k in model.nonlinear_names}
    Phi = model.regressors(u, DT, nonlinear)
    theta = np.array([truth["length"], 0.37])
    np.testing.assert_allclose(Phi @ theta, model.simulate(u, DT, {**truth, "offset": 0.37}), rtol=1e-12, atol=1e-12)
    with pytest.raises(ModelError):
        model.regressors(u, DT, {"mu": 1.0})


def test_default_bounds_hold_the_truth_and_scale_with_the_data(model, truth):
    lo, hi = model.bounds(DataScale(u=2.5, y=14.0, time=1.0))
    p = model.pack(truth)
    assert np.all(lo <= p) and np.all(p <= hi)
    d = model.default_params(DataScale(u=2.5, y=14.0, time=1.0))
    assert all(lo[i] <= d[n] <= hi[i] for i, n in enumerate(model.param_names))
    names = model.param_names
    lo2, hi2 = model.bounds(DataScale(u=5.0, y=7.0, time=2.0))
    i_mu, i_eta, i_tau = names.index("mu"), names.index("eta_v"), names.index("tau1")
    assert hi2[i_mu] / hi[i_mu] == pytest.approx(4 * 2)  # stress ~ u^2 / y
    assert hi2[i_eta] / hi[i_eta] == pytest.approx(4 * 2 * 2)  # stress x time
    assert hi2[i_tau] / hi[i_tau] == pytest.approx(2)


def test_result_does_not_depend_on_the_sampling(model, truth):
    """A stiff parameter set (small dashpot, stiff branch) needs RK4 substeps; sampling at 1 ms
    and at 0.25 ms must agree."""
    lo, hi = model.bounds()
    stiff = {**truth, "eta_v": lo[1], "mu3": 0.5 * hi[4]}
    n = 4000
    u_fine = vd.command_voltage(1.0, 4 * n, DT / 4)
    y_fine = model.simulate(u_fine, DT / 4, stiff)[::4]
    y = model.simulate(u_fine[::4], DT, stiff)
    assert np.max(np.abs(y - y_fine)) < 1e-4 * np.ptp(y)


def test_infeasible_parameters_give_nan_not_an_exception(model, truth):
    lo, _ = model.bounds()
    soft = {**truth, "mu": lo[0], "mu1": lo[2], "mu2": lo[3], "mu3": lo[4]}
    y = model.simulate(np.full(3000, 6.0), DT, soft)  # pushed into the Gent limit
    assert np.isnan(y[-1]) and np.isfinite(y[0])


def test_bad_input_and_hyperparameters(model, truth):
    with pytest.raises(ModelError):
        get_model("viscoelastic", n_branches=-1)
    with pytest.raises(ModelError):
        get_model("viscoelastic", thickness=0.0)
    with pytest.raises(ModelError):
        model.simulate_batch(np.ones(10), DT, np.ones((2, 3)))
    with pytest.raises(ModelError):
        model.simulate(np.array([1.0, np.nan]), DT, truth)
    with pytest.raises(ModelError):
        get_model("viscoelastic", n_branches=2).preset("virtual-dea")


def test_identifies_its_own_simulated_data(model, truth):
    """``identify`` (varpro) on three short records with sensor-like noise: from 15-20 % off, every
    parameter back within 2 % and the residual at the noise."""
    records = [vd.command_voltage(f, int(T / DT)) for f, T in ((1.0, 6.0), (0.2, 15.0), (0.05, 60.0))]
    rng = np.random.default_rng(0)
    noise = 0.01
    ds = Dataset("own", [Record(f"r{i}.csv", np.arange(u.size) * DT, u,
                                model.simulate(u, DT, {**truth, "offset": 0.2}) + rng.normal(0, noise, u.size))
                         for i, u in enumerate(records)])
    names = model.nonlinear_names
    off = dict(zip(names, [1.2, 0.85, 1.15, 0.85, 1.2, 1.15, 0.85, 1.2]))
    fit = identify(model, ds, "varpro", seed=0, start={n: truth[n] * off[n] for n in names},
                   n_candidates=0, n_starts=1, max_nfev=100, tol=1e-10)
    assert fit.success
    for n in names:
        assert fit.params[n] == pytest.approx(truth[n], rel=0.02), n
    assert np.sqrt(fit.fitness / len(ds.records)) == pytest.approx(noise, rel=0.05)  # eq. 9: mean square per record
    assert fit.params["length"] == pytest.approx(truth["length"], rel=0.02)
    assert fit.params["offset"] == pytest.approx(0.2, abs=0.02)


def test_windowed_forms_equal_the_full_simulation(truth):
    model = get_model("viscoelastic", warmup_stride=1)  # exact: every sample interval integrated
    u = vd.command_voltage(0.4, 7000)
    rng = np.random.default_rng(5)
    P = model.pack(truth) * np.exp(rng.uniform(-0.2, 0.2, (3, model.n_params)))
    window = slice(4500, 6999)
    full = model.simulate_batch(u, DT, P)
    assert np.array_equal(model.simulate_window_batch(u, DT, P, window), full[:, window])
    n_nl = len(model.nonlinear_names)
    batch = model.windowed_regressors_batch(u, DT, P[:, :n_nl], window)
    assert batch.shape == (3, window.stop - window.start, 2)
    for i in range(3):
        nonlinear = dict(zip(model.nonlinear_names, P[i, :n_nl]))
        single = model.windowed_regressors(u, DT, nonlinear, window)
        assert np.array_equal(batch[i], single)
        assert np.array_equal(single, model.regressors(u, DT, nonlinear)[window])
        np.testing.assert_allclose(single @ P[i, n_nl:], full[i, window], rtol=1e-12, atol=1e-12)


def test_long_warmup_steps_change_the_window_negligibly(model, truth):
    """The identifiers' windowed forms (warm-up crossed in 5-sample steps) against the exact run,
    on the longest record of the default dataset, and the exact form against the full simulation."""
    assert model.warmup_stride == 5
    u = vd.command_voltage(0.02, 500_000)
    window = slice(450_000, 500_000)
    P = model.pack(truth)[None, :]
    fast = model.simulate_window_batch(u, DT, P, window)[0]
    exact = get_model("viscoelastic", warmup_stride=1).simulate_window_batch(u, DT, P, window)[0]
    full = model.simulate(u, DT, truth)[window]
    assert np.array_equal(exact, full)
    assert np.max(np.abs(fast - exact)) < 1e-5 * np.ptp(exact)
    assert not np.array_equal(fast, exact)  # the long steps were taken
