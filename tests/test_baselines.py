"""Baselines: elliptical, dual-polynomial, Bouc-Wen, Preisach, rate-dependent P-I.

For each model: hand-checked cases, a slow obvious reference implementation
compared with the numba kernel, batched == single, and regressors
consistency (Phi @ linear == simulate). Properties with hypothesis where one
exists (rate independence, return-point memory).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hysbench.data.metrics import loop_width
from hysbench.models import DataScale, ModelError, get_model, list_models
from hysbench.models.bouc_wen import RK_STEP, Z_CAP, BoucWen
from hysbench.models.dual_polynomial import DualPolynomial
from hysbench.models.elliptical import Elliptical
from hysbench.models.preisach import Preisach
from hysbench.models.rate_dependent_pi import RateDependentPI
from scipy.integrate import solve_ivp

BASELINES = ("elliptical", "dual-polynomial", "bouc-wen", "preisach", "rate-dependent-pi")
RATE_INDEPENDENT = ("elliptical", "dual-polynomial", "bouc-wen", "preisach")
DT = 1e-3


def paper_input(f=1.0, periods=2.0, dt=DT):
    t = np.arange(int(round(periods / (f * dt)))) * dt
    return np.sin(2 * np.pi * f * t - 0.5 * np.pi) + 1.5


def wandering_input(n=1500, seed=0, lo=-150.0, hi=150.0):
    """A piezo-like input with many reversals inside the range (minor loops)."""
    rng = np.random.default_rng(seed)
    knots = rng.uniform(lo, hi, 12)
    knots[0], knots[3] = lo, hi  # the full range is visited
    x = np.linspace(0, 1, knots.size)
    return np.interp(np.linspace(0, 1, n), x, knots)


def random_sets(model, n, seed, scale=None):
    lo, hi = model.bounds(scale)
    rng = np.random.default_rng(seed)
    P = rng.uniform(lo, hi, size=(n, model.n_params))
    if isinstance(model, BoucWen):  # keep beta + gamma > 0 (bounded z)
        b, g = model.param_names.index("beta"), model.param_names.index("gamma")
        P[:, g] = np.maximum(P[:, g], -0.8 * P[:, b])
    return P


def split(model, vector):
    p = model.unpack(vector)
    return {n: p[n] for n in model.nonlinear_names}, np.array([p[n] for n in model.linear_names])


# --- the interface, for all five ---------------------------------------------
def test_registered_under_exact_names():
    for name in BASELINES:
        assert name in list_models()
        assert get_model(name).name == name


@pytest.mark.parametrize("name", BASELINES)
def test_parameters_bounds_and_offset(name):
    model = get_model(name)
    params = model.parameters()
    assert model.param_names[-1] == "offset"  # offset on by default
    for p in params:
        assert p.min <= p.value <= p.max, p
    assert model.has_linear_part
    # bounds of output-unit parameters follow the data scale
    small, big = dict(zip(model.param_names, model.bounds(DataScale(y=1.0))[1])), dict(
        zip(model.param_names, model.bounds(DataScale(y=10.0))[1]))
    assert big["offset"] == pytest.approx(10 * small["offset"])
    # offset=False drops it and shifts the output by exactly c
    bare = get_model(name, offset=False)
    assert "offset" not in bare.param_names
    u = paper_input(1.0, 1.0)
    P = random_sets(model, 1, 3)[0]
    with_c = model.simulate(u, DT, P)
    without = bare.simulate(u, DT, P[:-1])
    np.testing.assert_allclose(with_c, without + P[-1], rtol=0, atol=1e-12 * max(1.0, np.abs(with_c).max()))


@pytest.mark.parametrize("name", BASELINES)
@pytest.mark.parametrize("which", ["dea", "piezo"])
def test_batched_equals_single_and_regressors(name, which):
    model = get_model(name)
    if which == "dea":
        u, scale, in_range = paper_input(1.0, 2.0), DataScale(), None
    else:  # +-150 V with minor loops, the range fixed from outside
        u, scale, in_range = wandering_input(), DataScale(u=150.0, y=30.0), (-150.0, 150.0)
    P = random_sets(model, 5, 11, scale)
    Y = model.simulate_batch(u, DT, P, input_range=in_range)
    assert Y.shape == (5, u.size) and np.all(np.isfinite(Y))
    for b in range(5):
        single = model.simulate(u, DT, model.unpack(P[b]), input_range=in_range)
        np.testing.assert_allclose(Y[b], single, rtol=1e-12, atol=1e-12 * np.abs(single).max())
        nonlinear, linear = split(model, P[b])
        Phi = model.regressors(u, DT, nonlinear, input_range=in_range)
        assert Phi.shape == (u.size, len(model.linear_names))
        np.testing.assert_allclose(Phi @ linear, single, rtol=1e-10, atol=1e-10 * np.abs(single).max())


@pytest.mark.parametrize("name", BASELINES)
def test_bad_input_is_a_model_error(name):
    model = get_model(name)
    with pytest.raises(ModelError):
        model.simulate_batch(paper_input(), DT, np.zeros((2, model.n_params + 1)))
    if name in RATE_INDEPENDENT:  # these normalise by the range: a constant input has none
        with pytest.raises(ModelError):
            model.simulate(np.full(10, 1.0), DT, model.default_params())
    else:  # plays of zero width: a constant input is a valid (dull) case
        assert np.all(np.isfinite(model.simulate(np.full(10, 1.0), DT, model.default_params())))
    with pytest.raises(ModelError):
        model.regressors(paper_input(), DT, {"nonsense": 1.0})
    with pytest.raises(ModelError):
        get_model(name, no_such_hyperparameter=1)


def _refine(u, factor):
    """The same piecewise-linear input path, sampled ``factor`` times finer."""
    k = np.arange(u.size)
    fine = np.interp(np.arange((u.size - 1) * factor + 1) / factor, k, u)
    return fine


@pytest.mark.parametrize("name", RATE_INDEPENDENT)
@settings(max_examples=15, deadline=None)
@given(knots=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=8), factor=st.integers(2, 5),
       seed=st.integers(0, 1000))
@example(knots=[-0.915, 0.377, 0.792, -0.816], factor=2, seed=617)  # Bouc-Wen n = 2.2: RK4 error ~3e-7 of |y|
def test_rate_independent_models_depend_on_the_path_only(name, knots, factor, seed):
    model = get_model(name)
    u = np.interp(np.linspace(0, len(knots) - 1, 60), np.arange(len(knots)), np.array(knots) * 100.0)
    in_range = (-100.0, 100.0)
    P = random_sets(model, 1, seed, DataScale(u=100.0, y=10.0))[0]
    param_sets = [P]
    if isinstance(model, BoucWen):  # n = 1 as well: the scheme is exact there
        param_sets.append(np.where(np.array(model.param_names) == "n", 1.0, P))
    for P in param_sets:
        coarse = model.simulate(u, DT, P, input_range=in_range)
        fine = model.simulate(_refine(u, factor), DT / factor, P, input_range=in_range)[::factor]
        np.testing.assert_allclose(fine, coarse, rtol=0, atol=_path_only_tolerance(model, u, P, in_range, coarse))


def _path_only_tolerance(model, u, P, in_range, coarse):
    """Round-off for the models computed exactly on a piecewise-linear path; for Bouc-Wen with
    n != 1 the RK4 scheme's error bound: sub-steps with |h| L <= RK_STEP give a global error of
    order RK_STEP^4 per unit of xi travelled, in units of z's bound (beta + gamma)^(-1/n), times
    |k_z| in the output. Both samplings lie within it of the exact path, so they differ by at
    most twice that."""
    round_off = 1e-9 * max(1.0, np.abs(coarse).max())
    if not isinstance(model, BoucWen):
        return round_off
    p = model.unpack(P)
    if p["n"] == 1.0:  # integrated exactly
        return round_off
    xi = model.normalised(u, in_range)
    z_bound = min((p["beta"] + p["gamma"]) ** (-1.0 / p["n"]), Z_CAP)
    return round_off + 2.0 * RK_STEP**4 * np.abs(np.diff(xi)).sum() * z_bound * abs(p["kz"])


# --- elliptical --------------------------------------------------------------
def test_elliptical_is_the_ellipse_of_a_lagging_sine():
    # xi = -cos(wt): y = c - m1 cos(wt) - b sin(wt), an ellipse, closed after one period
    model = Elliptical(linearise="none")
    u = paper_input(0.5, 1.0)
    wt = 2 * np.pi * 0.5 * np.arange(u.size) * DT
    y = model.simulate(u, DT, {"m1": 2.0, "b": 0.5, "offset": 1.0})
    np.testing.assert_allclose(y, 1.0 - 2.0 * np.cos(wt) - 0.5 * np.sin(wt), atol=1e-12)
    y2 = model.simulate(paper_input(0.5, 2.0), DT, {"m1": 2.0, "b": 0.5, "offset": 1.0})
    np.testing.assert_allclose(y2[u.size:], y2[: u.size], atol=1e-12)  # closed loop


def test_elliptical_square_linearisation_by_hand():
    # u = 1.5 on a rising ramp over 0.5..2.5 kV: x = 2.25 in [0.25, 6.25] -> xi = -1/3
    model = Elliptical()  # linearise="square"
    u = np.linspace(0.5, 2.5, 401)
    k = int(np.argmin(np.abs(u - 1.5)))
    assert u[k] == pytest.approx(1.5)
    y = model.simulate(u, DT, {"m1": 3.0, "b": 0.6, "offset": 0.2})
    assert y[k] == pytest.approx(0.2 + 3.0 * (-1 / 3) - 0.6 * math.sqrt(1 - 1 / 9), abs=1e-12)
    # falling through the same point: the other half of the ellipse
    y_down = model.simulate(u[::-1], DT, {"m1": 3.0, "b": 0.6, "offset": 0.2}, input_range=(0.5, 2.5))
    assert y_down[u.size - 1 - k] == pytest.approx(0.2 - 1.0 + 0.6 * math.sqrt(8 / 9), abs=1e-12)


def _branch_reference(xi, centre, half, c):
    """Slow, direct per-sample form of the two-branch rule with one-reversal memory."""
    y = np.empty(xi.size)
    s_prev, y_t, xi_t, jump = 1, 0.0, 0.0, 0.0
    for k in range(xi.size):
        s = s_prev
        if k > 0 and xi[k] != xi[k - 1]:
            s = 1 if xi[k] > xi[k - 1] else -1
        xc = min(1.0, max(-1.0, xi[k]))
        if k > 0 and s != s_prev:
            xt = min(1.0, max(-1.0, xi[k - 1]))
            y_t, xi_t = y[k - 1], xi[k - 1]
            jump = y_t - (c + centre(xi[k - 1]) - s * half(xt))
        if s > 0:
            w = (1 - xi[k]) / (1 - xi_t) if 1 - xi_t > 1e-12 else 0.0
        else:
            w = (1 + xi[k]) / (1 + xi_t) if 1 + xi_t > 1e-12 else 0.0
        w = min(1.0, max(0.0, w))
        y[k] = c + centre(xi[k]) - s * half(xc) + jump * w
        s_prev = s
    return y


def test_elliptical_against_slow_reference_with_minor_loops():
    model = Elliptical(linearise="none", poly_order=2)
    u = wandering_input(900, seed=4, lo=-1.0, hi=1.0)
    u = np.concatenate((u, [1.3, 1.2]))  # also beyond the range
    p = {"m1": 1.5, "m2": -0.4, "b": 0.3, "offset": 0.1}
    y = model.simulate(u, DT, p, input_range=(-1.0, 1.0))
    ref = _branch_reference(u, lambda x: 1.5 * x - 0.4 * x * x, lambda x: 0.3 * math.sqrt(1 - x * x), 0.1)
    np.testing.assert_allclose(y, ref, atol=1e-12)
    # continuous at every reversal: no step larger than the input's own step times the slope bound
    assert np.max(np.abs(np.diff(y[:-2]))) < 0.1


# --- dual polynomial ---------------------------------------------------------
def test_dual_polynomial_branches_by_hand():
    # order 2: M = xi + 0.5 xi^2, H = 0.25 (1 - xi^2); rising y = M - H, falling y = M + H
    model = DualPolynomial(order=2)
    p = {"m1": 1.0, "m2": 0.5, "h0": 0.25, "offset": 0.0}
    rise, fall = model.branch_polynomials(p)
    np.testing.assert_allclose(rise, [-0.25, 1.0, 0.75])  # -0.25 + xi + 0.75 xi^2
    np.testing.assert_allclose(fall, [0.25, 1.0, 0.25])
    up = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
    y = model.simulate(up, DT, p, input_range=(-1, 1))
    # hand values: -1 + 0.5 = -0.5; -0.5 + 0.125 - 0.1875 = -0.5625; -0.25; 0.5 + 0.125 - 0.1875; 1 + 0.5
    np.testing.assert_allclose(y, [-0.5, -0.5625, -0.25, 0.4375, 1.5], atol=1e-12)
    down = up[::-1]
    y = model.simulate(np.concatenate((up, down[1:])), DT, p, input_range=(-1, 1))
    # falling: y(0.5) = 0.5 + 0.125 + 0.1875 = 0.8125, y(0) = 0.25, y(-0.5) = -0.1875, y(-1) = -0.5
    np.testing.assert_allclose(y[5:], [0.8125, 0.25, -0.1875, -0.5], atol=1e-12)


def test_dual_polynomial_minor_loop_memory_by_hand():
    # rise -1 -> 0 (y_t = -0.25), fall: jump = y_t - P_fall(0) = -0.5, w = (1 + xi)/(1 + 0)
    # at xi = -0.5: y = P_fall(-0.5) + (-0.5)(0.5) = -0.1875 - 0.25 = -0.4375; at -1 the jump is gone
    model = DualPolynomial(order=2)
    p = {"m1": 1.0, "m2": 0.5, "h0": 0.25, "offset": 0.0}
    u = np.array([-1.0, -0.5, 0.0, -0.5, -1.0])
    y = model.simulate(u, DT, p, input_range=(-1, 1))
    np.testing.assert_allclose(y, [-0.5, -0.5625, -0.25, -0.4375, -0.5], atol=1e-12)


def test_dual_polynomial_against_slow_reference_and_closure():
    model = DualPolynomial(order=4)
    p = {"m1": 2.0, "m2": 0.7, "m3": -0.3, "m4": 0.2, "h0": 0.4, "h1": -0.1, "h2": 0.05, "offset": 3.0}

    def centre(x):
        return 2.0 * x + 0.7 * x**2 - 0.3 * x**3 + 0.2 * x**4

    def half(x):
        return (1 - x * x) * (0.4 - 0.1 * x + 0.05 * x * x)

    u = wandering_input(1200, seed=9)
    y = model.simulate(u, DT, p, input_range=(-150.0, 150.0))
    np.testing.assert_allclose(y, _branch_reference(u / 150.0, centre, half, 3.0), atol=1e-12)
    # on the paper's drive the major loop is closed and continuous
    u = paper_input(1.0, 2.0)
    y = model.simulate(u, DT, p)
    np.testing.assert_allclose(y[1000:], y[:1000], atol=1e-12)
    assert np.max(np.abs(np.diff(y))) < 0.05


# --- Bouc-Wen ----------------------------------------------------------------
def test_bouc_wen_ramp_closed_form_and_steady_state():
    # n = 1, rising from xi = -1 with z = 0: dz/dxi = 1 - (beta + gamma) z
    # => z = (1 - exp(-(beta + gamma)(xi + 1))) / (beta + gamma) -> 1/(beta + gamma)
    model = BoucWen()
    u = np.linspace(0.0, 10.0, 501)
    xi = u / 5.0 - 1.0
    for beta, gamma in [(2.0, 1.0), (12.0, 8.0), (0.5, -0.3)]:
        z = model.hysteretic_state(u, DT, beta, gamma, 1.0)
        s = beta + gamma
        np.testing.assert_allclose(z, (1 - np.exp(-s * (xi + 1))) / s, atol=1e-9)
    z = model.hysteretic_state(u, DT, 12.0, 8.0, 1.0)
    assert z[-1] == pytest.approx(1 / 20, rel=1e-9)
    # output: y = c + kx xi + kz z
    y = model.simulate(u, DT, {"beta": 2.0, "gamma": 1.0, "n": 1.0, "kx": 0.5, "kz": 4.0, "offset": -1.0})
    np.testing.assert_allclose(y, -1.0 + 0.5 * xi + 4.0 * (1 - np.exp(-3 * (xi + 1))) / 3, atol=1e-8)


def _bouc_wen_reference(xi, beta, gamma, n):
    """scipy's solve_ivp in time, xi linear between samples, one interval at a time."""
    z = np.zeros(xi.size)
    for k in range(1, xi.size):
        d = xi[k] - xi[k - 1]  # dxi/dt over a unit interval

        def rhs(_t, zz, d=d):
            a = abs(zz[0])
            return [d - beta * abs(d) * a ** (n - 1) * zz[0] - gamma * d * a**n]

        sol = solve_ivp(rhs, (0.0, 1.0), [z[k - 1]], method="DOP853", rtol=1e-11, atol=1e-13)
        z[k] = sol.y[0, -1]
    return z


def test_bouc_wen_against_solve_ivp_with_reversals():
    model = BoucWen()
    u = wandering_input(300, seed=2, lo=-1.0, hi=1.0)
    for beta, gamma, n in [(3.0, 1.0, 2.5), (8.0, -2.0, 1.0), (1.0, 0.5, 4.0), (5.0, 3.0, 1.3), (20.0, 5.0, 1.05)]:
        z = model.hysteretic_state(u, DT, beta, gamma, n, input_range=(-1.0, 1.0))
        np.testing.assert_allclose(z, _bouc_wen_reference(u, beta, gamma, n), atol=1e-8)


def test_bouc_wen_is_stable_at_coarse_steps_and_reaches_a_periodic_loop():
    model = BoucWen()
    # stiff set, 20 samples per period: same path as 2000 samples per period
    t_coarse = np.linspace(0, 3, 61)
    t_fine = np.linspace(0, 3, 6001)
    p = (15.0, 5.0, 1.5)
    zc = model.hysteretic_state(np.sin(2 * np.pi * t_coarse), DT, *p)
    zf = model.hysteretic_state(np.sin(2 * np.pi * t_fine), DT, *p)
    # compare where the coarse samples are the fine ones (every 100th); sin is not linear between
    # samples, so the paths differ between the knots: compare at the turning points instead
    assert np.all(np.isfinite(zc)) and np.max(np.abs(zc)) <= (p[0] + p[1]) ** (-1 / p[2]) + 1e-12
    np.testing.assert_allclose(zc[[15, 25, 35, 45, 55]], zf[[1500, 2500, 3500, 4500, 5500]], atol=1e-9)
    # periodic: the second and third periods coincide
    np.testing.assert_allclose(zf[4001:6001], zf[2001:4001], atol=1e-9)


def test_bouc_wen_unstable_set_is_clipped_not_overflowing():
    # beta + gamma < 0: dz/dxi = 1 + 20 z^3 blows up in finite xi; z is held at the cap from then on
    model = BoucWen()
    y = model.simulate(paper_input(), DT, {"beta": 0.0, "gamma": -20.0, "n": 3.0, "kx": 1.0, "kz": 1.0,
                                            "offset": 0.0})
    assert np.all(np.isfinite(y))
    z = model.hysteretic_state(paper_input(), DT, 0.0, -20.0, 3.0)
    k = int(np.argmax(np.abs(z) >= Z_CAP))
    assert k > 0 and np.all(z[k:] == Z_CAP) and np.all(np.abs(z[:k]) < Z_CAP)


# --- Preisach ----------------------------------------------------------------
def test_preisach_single_relay():
    model = Preisach(grid_size=1)
    u = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 2.0, 1.9, 0.0])
    y = model.simulate(u, DT, {"w1_1": 2.0, "offset": 0.5}, input_range=(0.0, 4.0))
    # one relay at alpha = beta = 2: +1 where u >= 2, -1 where u <= 2
    np.testing.assert_allclose(y, 0.5 + 2.0 * np.where(u >= 2.0, 1.0, -1.0))


def test_preisach_relay_sequence_by_hand():
    # range [0, 4], levels 1 and 3: relays (alpha, beta) = (1,1) w1_1, (3,1) w2_1, (3,3) w2_2
    model = Preisach(grid_size=2)
    alphas, betas = model.grid(np.zeros(1), input_range=(0.0, 4.0))
    np.testing.assert_allclose(alphas, [1, 3, 3])
    np.testing.assert_allclose(betas, [1, 1, 3])
    u = np.array([0.0, 2.0, 3.5, 2.0, 0.5, 2.0])
    y = model.simulate(u, DT, {"w1_1": 1.0, "w2_1": 2.0, "w2_2": 4.0, "offset": 0.5}, input_range=(0.0, 4.0))
    # states: all -1; (1,1) up; all up; (3,3) down, (3,1) keeps +1; all down; (1,1) up
    np.testing.assert_allclose(y, [-6.5, -4.5, 7.5, -0.5, -6.5, -4.5])


def _preisach_reference(u, alphas, betas, weights, c):
    state = [-1] * len(alphas)
    y = []
    for uk in u:
        for i in range(len(alphas)):
            if uk >= alphas[i]:
                state[i] = 1
            elif uk <= betas[i]:
                state[i] = -1
        y.append(c + sum(w * s for w, s in zip(weights, state)))
    return np.array(y)


def test_preisach_against_slow_reference():
    model = Preisach(grid_size=6)
    u = wandering_input(800, seed=5)
    rng = np.random.default_rng(1)
    w = rng.uniform(0, 1, model.n_relays)
    y = model.simulate(u, DT, np.append(w, -0.3))
    alphas, betas = model.grid(u)
    np.testing.assert_allclose(y, _preisach_reference(u, alphas, betas, w, -0.3), atol=1e-12)
    assert np.all(model.bounds()[0][:-1] == 0.0)  # weights are non-negative


@settings(max_examples=30, deadline=None)
@given(pts=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4, unique=True), seed=st.integers(0, 100))
def test_preisach_return_point_memory(pts, seed):
    # up to A, down to m, up to a < A, down to b > m, back to a: the output at a returns exactly
    m, b, a, A = sorted(pts)
    u = np.concatenate((np.linspace(0, A, 30), np.linspace(A, m, 30), np.linspace(m, a, 30),
                        np.linspace(a, b, 30), np.linspace(b, a, 30)))
    model = Preisach(grid_size=7)
    w = np.random.default_rng(seed).uniform(0, 1, model.n_params)
    y = model.simulate(u, DT, w, input_range=(0.0, 1.0))
    assert y[-1] == pytest.approx(y[89], abs=1e-12)


# --- rate-dependent P-I -------------------------------------------------------
def test_rate_dependent_pi_ramp_by_hand():
    # range [0, 4], N = 2: r0 = (0, 1); ramp u = 2 t (2 V/s) sampled at 0.1 s: |u'| = 2 after k = 0
    model = RateDependentPI(n_operators=2, poly_order=1)
    dt = 0.1
    u = 2.0 * np.arange(21) * dt
    F = model.play_outputs(u, dt, beta=0.1, input_range=(0.0, 4.0))
    # play 1: r = 0 + 0.2 -> W = max(u - 0.2, min(u + 0.2, W_prev)), from W(-1) = 0
    np.testing.assert_allclose(F[:, 0], np.maximum(u - 0.2 * (np.arange(21) > 0), 0.0), atol=1e-12)
    # play 2: r = 1.2 (1 at k = 0): stays at 0 until u > 1.2, then u - 1.2
    np.testing.assert_allclose(F[:, 1], np.maximum(u - 1.2, 0.0), atol=1e-12)
    y = model.simulate(u, dt, {"beta": 0.1, "p1": 0.5, "a1": 1.0, "a2": -2.0, "offset": 0.3},
                       input_range=(0.0, 4.0))
    np.testing.assert_allclose(y, 0.3 + 0.5 * u + F[:, 0] - 2.0 * F[:, 1], atol=1e-12)


def _rd_pi_reference(u, dt, r0, beta, poly, weights, c):
    y = np.empty(u.size)
    w = np.zeros(len(r0))
    for k in range(u.size):
        rate = abs(u[k] - u[k - 1]) / dt if k > 0 else 0.0
        for i in range(len(r0)):
            r = r0[i] + beta * rate
            w[i] = max(u[k] - r, min(u[k] + r, w[i]))
        y[k] = c + sum(p * u[k] ** (j + 1) for j, p in enumerate(poly)) + float(np.dot(weights, w))
    return y


def test_rate_dependent_pi_against_slow_reference():
    model = RateDependentPI(n_operators=5, poly_order=2)
    u = np.concatenate((paper_input(1.0, 1.0), paper_input(0.4, 1.0)))
    rng = np.random.default_rng(3)
    poly, weights = rng.normal(size=2), rng.normal(size=5)
    params = {"beta": 0.05, "p1": poly[0], "p2": poly[1], "offset": 0.7}
    params.update({f"a{i + 1}": weights[i] for i in range(5)})
    y = model.simulate(u, DT, params)
    r0 = np.arange(5) / 5 * 0.5 * (u.max() - u.min())
    np.testing.assert_allclose(y, _rd_pi_reference(u, DT, r0, 0.05, poly, weights, 0.7), atol=1e-10)


def test_rate_dependent_pi_loops_widen_with_frequency():
    model = RateDependentPI()
    params = {n: 0.0 for n in model.param_names}
    params.update({"p1": 1.0, "a1": 0.5, "a3": 0.5, "a6": 0.5})
    widths = {}
    for beta in (0.0, 0.02):
        params["beta"] = beta
        widths[beta] = []
        for f in (0.02, 0.2, 1.0):
            u = paper_input(f, 2.0)
            y = model.simulate(u, DT, params)
            half = u.size // 2
            widths[beta].append(loop_width(u[half:], y[half:]))
    # rate-independent at beta = 0 (same loop at every frequency), wider with rate at beta > 0
    np.testing.assert_allclose(widths[0.0], widths[0.0][0], rtol=2e-3)
    assert widths[0.02][0] < widths[0.02][1] < widths[0.02][2]
    assert widths[0.02][2] > 1.1 * widths[0.0][2]


@pytest.mark.parametrize("name", ["bouc-wen", "rate-dependent-pi"])
def test_windowed_regressors_batch_are_rows_of_regressors(name):
    model = get_model(name)
    u = paper_input(0.4, 2.0)
    P = random_sets(model, 3, 5)
    sets = P[:, [model.param_names.index(n) for n in model.nonlinear_names]]
    window = slice(1200, 2500)
    W = model.windowed_regressors_batch(u, DT, sets, window, input_range=(0.4, 2.6))
    assert W.shape == (3, 1300, len(model.linear_names))
    for b in range(3):
        full = model.regressors(u, DT, dict(zip(model.nonlinear_names, sets[b])), input_range=(0.4, 2.6))
        np.testing.assert_allclose(W[b], full[window], rtol=1e-12, atol=1e-12)


def _bouc_wen_reference_in_xi(xi, beta, gamma, n):
    """dz/dxi integrated by solve_ivp over each monotone stretch of xi (the model is
    rate-independent), read at the samples by dense output: fast for finely sampled inputs."""
    z = np.zeros(xi.size)
    k0 = 0
    while k0 < xi.size - 1:
        sigma = 1.0 if xi[k0 + 1] > xi[k0] else -1.0
        k1 = k0 + 1
        while k1 + 1 < xi.size and (xi[k1 + 1] - xi[k1]) * sigma > 0:
            k1 += 1

        def rhs(_x, zz, sigma=sigma):
            a = abs(zz[0])
            return [1.0 - sigma * beta * a ** (n - 1) * zz[0] - gamma * a**n]

        sol = solve_ivp(rhs, (xi[k0], xi[k1]), [z[k0]], method="DOP853", rtol=1e-12, atol=1e-14,
                        t_eval=xi[k0:k1 + 1])
        z[k0:k1 + 1] = sol.y[0]
        k0 = k1
    return z


def test_bouc_wen_finely_sampled_slow_input_against_solve_ivp():
    # 20,000 samples per period (the 0.02 Hz record at 1 ms): tiny steps take the Taylor path
    model = BoucWen()
    xi = -np.cos(2 * np.pi * np.arange(40001) / 20000)
    for beta, gamma, n in [(3.0, 1.0, 1.5), (0.3, -0.05, 3.9), (12.0, 4.0, 2.0)]:
        z = model.hysteretic_state(xi, DT, beta, gamma, n, input_range=(-1.0, 1.0))
        np.testing.assert_allclose(z, _bouc_wen_reference_in_xi(xi, beta, gamma, n), atol=1e-8)


@settings(max_examples=25, deadline=None)
@given(pts=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=4, unique=True), seed=st.integers(0, 100),
       first_low=st.booleans())
def test_preisach_minor_loops_between_the_same_extrema_are_congruent(pts, seed, first_low):
    """Mayergoyz's congruency: after different histories, the loop traced while the input cycles
    between the same two extrema u1 < u2 differs only by a constant shift (from the second cycle,
    when the relays outside u1 <= beta <= alpha <= u2 no longer switch)."""
    h1, h2, u1, u2 = pts
    u1, u2 = min(u1, u2), max(u1, u2)
    cycle = np.concatenate((np.linspace(u1, u2, 25)[1:], np.linspace(u2, u1, 25)[1:]))
    model = Preisach(grid_size=7)
    w = np.random.default_rng(seed).uniform(0, 1, model.n_params)
    loops = []
    for history in ((0.0, 1.0, h1), (1.0, 0.0, h2)) if first_low else ((1.0, h1), (0.0, 1.0, 0.0, h2)):
        path = np.concatenate([np.linspace(a, b, 20) for a, b in zip((0.0, *history), (*history, u1))])
        u = np.concatenate((path, cycle, cycle))
        y = model.simulate(u, DT, w, input_range=(0.0, 1.0))
        second = y[path.size + cycle.size - 1:]  # from u1, the end of the first cycle
        loops.append(second - second[0])
    np.testing.assert_allclose(loops[0], loops[1], rtol=0, atol=1e-12)


def test_batch_and_windowed_kernels_of_the_baselines_match_slow_references():
    """Many parameter sets at once (the parallel batch kernels) and the windowed regressors of
    many sets, against the per-sample references above, for rate-dependent P-I, Bouc-Wen, Preisach."""
    u = wandering_input(160, seed=7, lo=-1.0, hi=1.0)
    window = np.array([2, 40, 41, 100, 159])
    for name in ("rate-dependent-pi", "bouc-wen", "preisach"):
        model = get_model(name)
        P = random_sets(model, 3, seed=12)
        refs = []
        for row in P:
            p = dict(zip(model.param_names, row))
            if name == "rate-dependent-pi":
                poly = [p[f"p{j}"] for j in range(1, model.poly_order + 1)]
                weights = [p[f"a{i}"] for i in range(1, model.n_operators + 1)]
                r0 = np.arange(model.n_operators) / model.n_operators * 0.5 * 2.0
                refs.append(_rd_pi_reference(u, DT, r0, p["beta"], poly, weights, p["offset"]))
            elif name == "bouc-wen":
                z = _bouc_wen_reference(u, p["beta"], p["gamma"], p["n"])
                refs.append(p["offset"] + p["kx"] * u + p["kz"] * z)
            else:
                alphas, betas = model.grid(u, (-1.0, 1.0))
                refs.append(_preisach_reference(u, alphas, betas, row[:-1], p["offset"]))
        refs = np.array(refs)
        # Bouc-Wen: the scheme's stated error, 1e-8 in z, times the largest |k_z|
        kz = np.abs(P[:, model.param_names.index("kz")]).max() if name == "bouc-wen" else 0.0
        atol = 1e-8 * max(1.0, kz) if name == "bouc-wen" else 1e-10
        np.testing.assert_allclose(model.simulate_batch(u, DT, P, input_range=(-1.0, 1.0)), refs, rtol=0, atol=atol)
        lin = P[:, [model.param_names.index(n) for n in model.linear_names]]
        sets = P[:, [model.param_names.index(n) for n in model.nonlinear_names]]
        for some in (sets, sets[:1]):
            R = model.windowed_regressors_batch(u, DT, some, window, input_range=(-1.0, 1.0))
            np.testing.assert_allclose(np.einsum("brl,bl->br", R, lin[:len(some)]), refs[:len(some), window],
                                       rtol=0, atol=atol)



@settings(max_examples=40, deadline=None)
@given(z0=st.floats(-0.5, 0.5).filter(lambda z: abs(z) > 1e-3), past=st.floats(0.01, 0.5), n=st.floats(2.0, 4.0),
       beta=st.floats(0.5, 15.0), ratio=st.floats(-0.8, 1.0))
def test_bouc_wen_step_through_zero_against_solve_ivp(z0, past, n, beta, ratio):
    """One sample interval in which z crosses 0 (xi moving towards z's other side by |z0| + past):
    n >= 2 takes no finer sub-steps near 0, so the landing on 0 inside a sub-step carries the
    interval's error; it stays at the scheme's RK4 error (< 5e-9 here), not one of ~|z|^(n+1)."""
    from hysbench.models.bouc_wen import bouc_wen_step

    gamma = ratio * beta
    d = -np.sign(z0) * (abs(z0) + past)
    z = bouc_wen_step(z0, d, beta, gamma, n)

    def rhs(_x, zz):
        a = abs(zz[0])
        return [1.0 - np.sign(d) * beta * a ** (n - 1) * zz[0] - gamma * a**n]

    ref = solve_ivp(rhs, (0.0, d), [z0], method="DOP853", rtol=1e-13, atol=1e-15).y[0, -1]
    assert abs(z - ref) < 5e-9
