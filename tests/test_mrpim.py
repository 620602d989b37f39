"""MRPIM (eq. 5-8) with Table 2 against a slow, obvious per-sample implementation."""

import numpy as np
import pytest

from hysbench.data.protocol import paper_voltage, protocol_time
from hysbench.models import PAPER_TABLE2, ModelError, get_model


def mrpim_reference(V, T, p, n_ops=13, w0=0.0, rates=None):
    """Eq. 6-8 written out sample by sample, as in the paper. ``rates``: (dV, ddV) given per sample
    in place of the backward differences (the smoothed derivative); p's "offset", if any, is added."""
    norm = max(abs(v) for v in V)
    r = [(i - 1) / n_ops * norm for i in range(1, n_ops + 1)]
    W = [w0] * n_ops
    y = []
    for k in range(len(V)):
        v_prev = V[k - 1] if k >= 1 else V[0]
        v_prev2 = V[k - 2] if k >= 2 else V[0]
        dV = (V[k] - v_prev) / T
        ddV = (V[k] - 2 * v_prev + v_prev2) / T**2
        if rates is not None:
            dV, ddV = rates[0][k], rates[1][k]
        h_l = V[k] - p["gamma"] * abs(dV)
        h_r = V[k] + p["lambda"] * abs(dV)
        for i in range(n_ops):
            W[i] = max(h_l - r[i], min(h_r, W[i]))
        g = p["p1"] * V[k] + p["p2"] * V[k] ** 2 + p["p3"] * V[k] ** 3 + p["p4"] * V[k] ** 4
        y.append(g + p["q"] * ddV + sum(p[f"a{i + 1}"] * W[i] for i in range(n_ops)) + p.get("offset", 0.0))
    return np.array(y)


def random_sets(model, n_sets, seed):
    """Parameter sets drawn uniformly within the model's bounds, as dicts and as rows."""
    rng = np.random.default_rng(seed)
    lo, hi = model.bounds()
    P = lo + (hi - lo) * rng.random((n_sets, model.n_params))
    return [dict(zip(model.param_names, row)) for row in P], P


def wandering_voltage(n, seed):
    """A short random input with reversals and minor loops: a random walk, smoothed, in 0.5..2.5."""
    rng = np.random.default_rng(seed)
    walk = np.convolve(np.cumsum(rng.normal(size=n + 9)), np.ones(10) / 10, mode="valid")
    return 0.5 + 2.0 * (walk - walk.min()) / np.ptp(walk)


@pytest.mark.parametrize("f,n_periods", [(1.0, 2), (0.4, 1.5), (0.1, 0.3)])
def test_table2_matches_reference(f, n_periods):
    model = get_model("mrpim")
    params = model.preset("paper")
    t = protocol_time(f, n_periods)
    V = paper_voltage(t, f)
    y = model.simulate(V, 1e-3, params)
    ref = mrpim_reference(list(V), 1e-3, PAPER_TABLE2)
    np.testing.assert_allclose(y, ref, rtol=1e-10, atol=1e-9)


def test_paper_preset_is_exactly_eq8():
    """With the offset on, preset 'paper' sets it to 0; with offset=False the model has the paper's 20 parameters."""
    with_offset = get_model("mrpim")
    without = get_model("mrpim", offset=False)
    assert with_offset.preset("paper")["offset"] == 0.0
    assert without.n_params == 20 and set(without.param_names) == set(PAPER_TABLE2)
    V = paper_voltage(protocol_time(0.4, 1), 0.4)
    np.testing.assert_array_equal(with_offset.simulate(V, 1e-3, with_offset.preset("paper")),
                                  without.simulate(V, 1e-3, without.preset("paper")))


def test_batch_equals_single():
    model = get_model("mrpim")
    rng = np.random.default_rng(1)
    lo, hi = model.bounds()
    P = lo + (hi - lo) * rng.random((5, model.n_params))
    V = paper_voltage(protocol_time(0.8, 1), 0.8)
    Y = model.simulate_batch(V, 1e-3, P)
    for b in range(5):
        np.testing.assert_allclose(Y[b], model.simulate(V, 1e-3, P[b]), rtol=1e-12, atol=1e-12)


def test_a_model_simulated_over_another_input_range_uses_that_ranges_thresholds():
    """One model object simulated for fits of different input ranges gives each range's output (as a fresh
    object does), whatever it simulated before."""
    V = paper_voltage(protocol_time(0.8, 1), 0.8)
    params = get_model("mrpim").preset("paper")
    model = get_model("mrpim")
    for rng in [(0.5, 2.5), (0.0, 5.0), (0.5, 2.5)]:
        np.testing.assert_array_equal(model.simulate(V, 1e-3, params, input_range=rng),
                                      get_model("mrpim").simulate(V, 1e-3, params, input_range=rng))
    assert not np.array_equal(model.simulate(V, 1e-3, params, input_range=(0.0, 5.0)),
                              model.simulate(V, 1e-3, params, input_range=(0.5, 2.5)))


@pytest.mark.parametrize("derivative", ["backward", "smoothed"])
def test_batch_and_window_kernels_match_reference(derivative):
    """The parallel batch kernel, the windowed kernels (one set and many) and the windowed play
    regressors against eq. 5-8 written out, for each derivative (smoothed: the same dV, ddV given)."""
    from hysbench.models.derivatives import derivatives

    model = get_model("mrpim", derivative=derivative, derivative_window=0.02)
    dicts, P = random_sets(model, 3, seed=4)
    V = wandering_voltage(300, seed=5)
    rates = None if derivative == "backward" else derivatives(V, 1e-3, "smoothed", 0.02)
    refs = [mrpim_reference(list(V), 1e-3, p, rates=rates) for p in dicts]
    Y = model.simulate_batch(V, 1e-3, P)
    rows = np.array([3, 50, 51, 120, 299])
    for b in range(3):
        np.testing.assert_allclose(Y[b], refs[b], rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(model.simulate_window_batch(V, 1e-3, P[b:b + 1], slice(40, 260))[0],
                                   refs[b][40:260], rtol=1e-10, atol=1e-9)
    W = model.simulate_window_batch(V, 1e-3, P, slice(40, 260))
    np.testing.assert_allclose(W, np.array(refs)[:, 40:260], rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(model.simulate_window_batch(V, 1e-3, P, rows), np.array(refs)[:, rows],
                               rtol=1e-10, atol=1e-9)
    # regressor rows times the linear parameters (plays from the windowed play kernels)
    lin = [[p[n] for n in model.linear_names] for p in dicts]
    sets = P[:, [model.param_names.index(n) for n in model.nonlinear_names]]
    for window in (slice(40, 260), rows):
        R = model.windowed_regressors_batch(V, 1e-3, sets, window)
        for b in range(3):
            np.testing.assert_allclose(R[b] @ lin[b], refs[b][window], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("hyper", [{}, {"poly_order": 2, "q_term": False}, {"envelopes": False, "offset": False},
                                   {"derivative": "smoothed"}, {"n_operators": 5, "poly_order": 0}])
def test_regressors_reproduce_simulation(hyper):
    model = get_model("mrpim", **hyper)
    rng = np.random.default_rng(2)
    lo, hi = model.bounds()
    theta = model.unpack(lo + (hi - lo) * rng.random(model.n_params))
    V = paper_voltage(protocol_time(0.4, 1), 0.4) + rng.normal(0, 1e-3, 2500)
    Phi = model.regressors(V, 1e-3, {n: theta[n] for n in model.nonlinear_names}, input_range=(0.4, 2.6))
    y_lin = Phi @ np.array([theta[n] for n in model.linear_names])
    np.testing.assert_allclose(y_lin, model.simulate(V, 1e-3, theta, input_range=(0.4, 2.6)), rtol=1e-9, atol=1e-9)


def test_thresholds_follow_input_range():
    model = get_model("mrpim", n_operators=4)
    np.testing.assert_allclose(model.thresholds(np.array([-90.0, 90.0])), [0, 22.5, 45, 67.5])
    np.testing.assert_allclose(model.thresholds(np.array([0.5, 2.5])), [0, 0.625, 1.25, 1.875])
    np.testing.assert_allclose(model.thresholds(np.zeros(3), input_range=(0.5, 2.5)), [0, 0.625, 1.25, 1.875])
    # ||u||_inf: the largest magnitude, here the most negative input
    np.testing.assert_allclose(model.thresholds(np.array([-8.0, 2.0])), [0, 2, 4, 6])


def test_piezo_range_works():
    """A piezo at +-90 V gives a finite hysteretic loop with the paper's structure."""
    model = get_model("mrpim", q_term=False)
    t = np.arange(2000) * 1e-3
    u = 90 * np.sin(2 * np.pi * t)
    params = {n: 0.0 for n in model.param_names} | {"p1": 0.1, "a2": 0.05, "a5": 0.05}
    y = model.simulate(u, 1e-3, params)
    assert np.all(np.isfinite(y))
    up = (np.diff(u, prepend=u[0]) > 0)
    k = np.argmin(np.abs(u[1000:]) + 100 * ~up[1000:]) + 1000
    j = np.argmin(np.abs(u[1000:]) + 100 * up[1000:]) + 1000
    assert abs(y[k] - y[j]) > 1.0  # a loop: different output at u = 0 going up and going down


@pytest.mark.parametrize("bad", [{"n_operators": 0}, {"poly_order": -1}, {"derivative": "magic"},
                                 {"derivative_window": 0.0}, {"nonsense": 1}])
def test_bad_hyperparameters(bad):
    name = next(iter(bad))
    with pytest.raises(ModelError, match=f"{name} must be|hyperparameter '{name}'"):  # the refusal names it
        get_model("mrpim", **bad)


def test_bad_parameters_and_inputs():
    model = get_model("mrpim")
    with pytest.raises(ModelError, match="missing"):
        model.simulate(np.ones(10), 1e-3, {"gamma": 0.0})
    with pytest.raises(ModelError, match="NaN"):
        model.simulate(np.array([1.0, np.nan]), 1e-3, model.preset("paper"))
    with pytest.raises(ModelError, match="time step"):
        model.simulate(np.ones(3), 0.0, model.preset("paper"))
    with pytest.raises(ModelError, match="unknown model"):
        get_model("mrpm")
    with pytest.raises(ModelError, match="no preset"):
        model.preset("nope")


def test_smoothed_derivative_survives_noise():
    """On a quantised, noisy input, the smoothed derivative stays close to the true one; backward does not."""
    from hysbench.models.derivatives import derivatives

    t = protocol_time(1.0, 1)
    V = paper_voltage(t, 1.0)
    rng = np.random.default_rng(3)
    Vn = np.round((V + rng.normal(0, 2e-3, V.size)) / 1e-3) * 1e-3
    true_dd = (2 * np.pi) ** 2 * np.cos(2 * np.pi * t)
    _, dd_back = derivatives(Vn, 1e-3, "backward")
    _, dd_smooth = derivatives(Vn, 1e-3, "smoothed", window_s=0.1)
    inner = slice(100, -100)
    err_back = np.sqrt(np.mean((dd_back[inner] - true_dd[inner]) ** 2))
    err_smooth = np.sqrt(np.mean((dd_smooth[inner] - true_dd[inner]) ** 2))
    assert err_smooth < 0.05 * np.max(np.abs(true_dd))
    assert err_back > 50 * err_smooth
