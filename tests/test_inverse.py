"""Inverses (models/inverse.py and the models' own step kernels): step kernels against a slow
reference, the model driven by its own inverse, the analytic classical P-I inverse, clipping."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hysbench.models import MRPIM, get_model
from hysbench.models.errors import ModelError
from hysbench.models.inverse import _pi_operator, classical_pi_inverse, guide_gain, guided_simulate
from test_baselines import _bouc_wen_reference, _branch_reference, _preisach_reference

DT = 1e-3
LIMITS = (0.5, 2.5)


def slow_step_model(u, dt, r_lo, r_hi, g_lo, g_hi, weights, poly, q, offset, filters=()):
    """The step structure of models/inverse.py written out plainly, one sample at a time.
    filters: (a, b0, b1, power, weight) first-order-hold low-passes from rest."""
    w = [0.0] * len(r_lo)
    x = [0.0] * len(filters)
    out = []
    for k, uk in enumerate(u):
        u1 = u[k - 1] if k >= 1 else uk
        u2 = u[k - 2] if k >= 2 else u1
        rate = abs(uk - u1) / dt
        for i in range(len(r_lo)):
            lower = uk - g_lo * rate - r_lo[i]
            upper = uk + g_hi * rate + r_hi[i]
            w[i] = max(lower, min(upper, w[i]))
        for j, (a, b0, b1, p, _) in enumerate(filters):
            x[j] = 0.0 if k == 0 else a * x[j] + b0 * u1 ** p + b1 * uk ** p
        y = offset + sum(c * uk ** (j + 1) for j, c in enumerate(poly)) + q * (uk - 2 * u1 + u2) / dt ** 2
        y += sum(a * wi for a, wi in zip(weights, w)) + sum(f[4] * xj for f, xj in zip(filters, x))
        out.append(y)
    return np.array(out)


def smooth_input(seed, n, max_rate=5.0):
    """A random, rate-limited input inside LIMITS starting at the lower limit."""
    rng = np.random.default_rng(seed)
    steps = np.cumsum(rng.normal(0.0, 1.0, n))
    steps = np.convolve(steps, np.ones(50) / 50, mode="same")
    target = np.interp(steps, (steps.min(), steps.max()), (0.6, 2.4))
    u = np.empty(n)
    previous = LIMITS[0]
    for k in range(n):
        previous += min(max(target[k] - previous, -max_rate * DT), max_rate * DT)
        u[k] = previous
    return u


def mrpim_params(rng, model, gamma=0.004, lam=0.003, q=2e-6):
    p = model.default_params()
    for name in p:
        if name.startswith("a") or name.startswith("p"):
            p[name] = float(rng.uniform(0.05, 1.0))
    p.update(gamma=gamma, **{"lambda": lam}, q=q, offset=0.3)
    return p


def test_step_kernels_match_a_slow_reference_and_the_forward_kernels():
    rng = np.random.default_rng(3)
    u = smooth_input(1, 1500)
    m = get_model("mrpim")
    p = mrpim_params(rng, m, gamma=0.02, lam=-0.01, q=1e-4)
    s = m.step_structure(DT, p, LIMITS, u.size)
    ref = slow_step_model(u, DT, s.r_lo, s.r_hi, s.g_lo, s.g_hi, s.weights, s.poly, s.q, p["offset"])
    np.testing.assert_allclose(m.simulate_steps(u, DT, p, input_range=LIMITS), ref, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(m.simulate(u, DT, p, input_range=LIMITS), ref, rtol=1e-11, atol=1e-11)

    rd = get_model("rate-dependent-pi")
    prd = {n: float(rng.uniform(0.1, 1.0)) for n in rd.param_names}
    prd["beta"] = 0.01
    s = rd.step_structure(DT, prd, LIMITS, u.size)
    ref = slow_step_model(u, DT, s.r_lo, s.r_hi, s.g_lo, s.g_hi, s.weights, s.poly, 0.0, prd["offset"])
    np.testing.assert_allclose(rd.simulate(u, DT, prd, input_range=LIMITS), ref, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(rd.simulate_steps(u, DT, prd, input_range=LIMITS), ref, rtol=1e-11, atol=1e-11)

    ext = get_model("mrpim+relaxation", relaxation_powers=(1, 2))
    pe = mrpim_params(rng, ext)
    pe.update(tau1=0.7, c1=0.4, c1_u2=-0.2)
    s = ext.step_structure(DT, pe, LIMITS, u.size)
    filters = list(zip(s.filter_a, s.filter_b0, s.filter_b1, s.filter_power, s.filter_weight))
    ref = slow_step_model(u, DT, s.r_lo, s.r_hi, s.g_lo, s.g_hi, s.weights, s.poly, s.q, pe["offset"], filters)
    np.testing.assert_allclose(ext.simulate(u, DT, pe, input_range=LIMITS), ref, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ext.simulate_steps(u, DT, pe, input_range=LIMITS), ref, rtol=1e-10, atol=1e-10)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), name=st.sampled_from(["mrpim", "rate-dependent-pi", "mrpim+relaxation",
                                                          "classical-pi"]),
       gamma=st.floats(0.0, 0.01), lam=st.floats(-0.01, 0.01), q=st.floats(0.0, 1e-5))
def test_model_driven_by_its_inverse_reproduces_the_desired_output(seed, name, gamma, lam, q):
    """Reachable trajectories (outputs of the model for random inputs): wherever the exact inverse
    did not clip, the model driven by it gives the desired output to 1e-6 of its range."""
    rng = np.random.default_rng(seed)
    m = get_model(name)
    p = {n: float(rng.uniform(0.05, 1.0)) for n in m.param_names}
    p.update({k: v for k, v in {"gamma": gamma, "lambda": lam, "q": q, "beta": abs(gamma), "tau1": 0.5}.items()
              if k in p})
    u = smooth_input(seed, 2000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    inv = m.invert(y, DT, p, input_range=LIMITS, inverse="exact")
    assert inv.inverse == "exact"
    achieved = m.simulate(inv.u, DT, p, input_range=LIMITS)
    ok = ~inv.clipped
    span = np.ptp(y)
    assert np.all((inv.u >= LIMITS[0]) & (inv.u <= LIMITS[1]))
    assert np.max(np.abs(achieved - y)[ok]) <= 1e-6 * span
    if name == "classical-pi":  # positive weights: monotone, every sample is reachable
        assert inv.n_clipped == 0


def positive_classical_pi(seed):
    """classical-pi with random positive weights: a monotone model."""
    rng = np.random.default_rng(seed)
    m = get_model("classical-pi")
    return m, {n: float(rng.uniform(0.05, 1.0)) for n in m.param_names}


def test_analytic_classical_pi_inverse_agrees_with_the_numerical_one():
    m, p = positive_classical_pi(7)
    u = smooth_input(2, 5000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    analytic = m.invert_analytic(y, DT, p, LIMITS)
    numerical = m.invert(y, DT, p, input_range=LIMITS)
    assert numerical.n_clipped == 0
    np.testing.assert_allclose(analytic.u, numerical.u, atol=1e-9)
    np.testing.assert_allclose(analytic.u, u, atol=1e-9)  # monotone: the input is unique


def symmetric_pi(x, c0, weights, half_widths, states):
    """c0 x + sum_i c_i P_{h_i}[x], each symmetric play P_h[x](k) = max(x(k) - h, min(x(k) + h, P(k-1)))
    starting from its state, one sample at a time."""
    q = [float(v) for v in states]
    out = []
    for xk in x:
        acc = c0 * xk
        for i, h in enumerate(half_widths):
            q[i] = max(xk - h, min(xk + h, q[i]))
            acc += weights[i] * q[i]
        out.append(acc)
    return np.array(out)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_plays=st.integers(0, 6), b0=st.floats(-3.0, 3.0))
def test_pi_operator_is_its_formula(seed, n_plays, b0):
    """_pi_operator: u = b0 z + sum_i b_i P_{s_i}[z] from the states q0, written out plainly (any signs
    of the weights, widths from zero up, states inside and outside the first band)."""
    rng = np.random.default_rng(seed)
    z = np.cumsum(rng.normal(0.0, 0.3, 400))
    s = np.sort(rng.uniform(0.0, 2.0, n_plays))
    b, q0 = rng.normal(size=n_plays), rng.normal(0.0, 2.0, n_plays)
    got = _pi_operator(z, b0, b, s, q0)
    np.testing.assert_allclose(got, symmetric_pi(z, b0, b, s, q0), rtol=1e-14, atol=1e-14 * np.max(np.abs(z)))
    assert np.array_equal(q0, q0.copy())  # the caller's states are not advanced


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_plays=st.integers(1, 6))
def test_analytic_classical_pi_inverse_inverts_the_operator(seed, n_plays):
    """Property: the P-I operator classical_pi_inverse builds (thresholds s_i, weights b_i, states q_i of
    the module docstring) returns the input of a0 u + sum_i a_i P_{h_i}[u], written out plainly, for
    weights of either sign with increasing partial sums, from the play states a random history left."""
    rng = np.random.default_rng(seed)
    a0 = rng.uniform(0.2, 2.0)
    a = rng.normal(0.0, 1.0, n_plays)
    while np.any(a0 + np.cumsum(a) <= 0.05):  # the loading curve increases
        a = np.where(a0 + np.cumsum(a) <= 0.05, np.abs(a), a)
    h = np.cumsum(rng.uniform(0.05, 0.5, n_plays))
    history = np.cumsum(rng.normal(0.0, 0.3, 100))
    p = np.array([symmetric_pi(history, 0.0, np.eye(n_plays)[i], h, np.zeros(n_plays))[-1] for i in range(n_plays)])
    u = history[-1] + np.cumsum(rng.normal(0.0, 0.2, 500))
    z = symmetric_pi(u, a0, a, h, p)
    np.testing.assert_allclose(classical_pi_inverse(z, a0, a, h, p), u, rtol=0, atol=1e-11 * np.max(np.abs(u)))


def test_analytic_inverse_refuses_play_states_no_history_leaves():
    """Plays 0.1 apart in threshold cannot differ by 0.5: from such states the formula's inverse misses
    the input (here by 0.035 at the first samples), so it is refused; states at the edge are accepted."""
    a0, a, h = 1.0, np.array([0.8, 0.5]), np.array([0.1, 0.2])
    u = 0.05 * np.arange(10)
    with pytest.raises(ModelError, match="input history can leave"):
        classical_pi_inverse(symmetric_pi(u, a0, a, h, [0.0, 0.5]), a0, a, h, np.array([0.0, 0.5]))
    for edge in ([0.0, 0.1], [0.0, -0.1]):
        np.testing.assert_allclose(classical_pi_inverse(symmetric_pi(u, a0, a, h, edge), a0, a, h, np.array(edge)),
                                   u, rtol=0, atol=1e-14)


def test_analytic_inverse_refuses_a_decreasing_loading_curve():
    m = get_model("classical-pi")
    p = {n: 0.5 for n in m.param_names}
    p["a5"] = -20.0
    with pytest.raises(ModelError, match="loading curve"):
        m.invert_analytic(np.ones(10), DT, p, LIMITS)


def test_clipping_count_on_an_unreachable_reference():
    m, p = positive_classical_pi(11)
    u = smooth_input(4, 1000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    y_max = m.simulate(np.array([LIMITS[1]]), DT, p, input_range=LIMITS)[0]
    desired = np.concatenate([y, np.full(30, y_max + 5.0), np.full(20, -1e3), y[:5] * 0 + y.min() - 50.0])
    inv = m.invert(desired, DT, p, input_range=LIMITS)
    assert inv.n_clipped == 55
    np.testing.assert_array_equal(np.flatnonzero(inv.clipped), np.arange(1000, 1055))
    assert np.all(inv.u[1000:1030] == LIMITS[1]) and np.all(inv.u[1030:1055] == LIMITS[0])


def test_rate_limit_is_kept_and_counted():
    m = get_model("classical-pi")
    p = {n: 0.3 for n in m.param_names}
    y = m.simulate(np.array([0.5, 0.5, 2.5, 2.5]), DT, p, input_range=LIMITS)
    inv = m.invert(y, DT, p, input_range=LIMITS, max_rate=100.0)  # 0.1 kV per sample at most
    assert np.max(np.abs(np.diff(inv.u))) <= 0.1 + 1e-12
    assert inv.clipped[2] and inv.clipped[3]


@pytest.mark.parametrize("name", ["classical-pi", "mrpim", "viscoelastic", "bouc-wen", "preisach"])
def test_a_start_input_outside_the_input_limits_is_refused_not_clipped(name):
    m = get_model(name)
    lo, hi = LIMITS
    with pytest.raises(ModelError, match="u_start .* outside the input limits"):
        m.invert(np.ones(5), DT, m.default_params(), input_range=LIMITS, u_start=hi + 0.1 * (hi - lo))
    with pytest.raises(ModelError, match="outside the input limits"):
        m.inverse_stepper(DT, m.default_params(), input_range=LIMITS, u_start=lo - 1.0)


@pytest.mark.parametrize("name", ["classical-pi", "mrpim", "viscoelastic", "bouc-wen"])
@pytest.mark.parametrize("bad", [True, 0.0, -1.0, float("nan"), float("inf"), "5"])
def test_a_rate_limit_that_is_no_positive_number_is_refused(name, bad):
    m = get_model(name)  # max_rate=True must not be read as 1.0 input unit per second
    with pytest.raises(ModelError, match="max_rate"):
        m.invert(np.ones(5), DT, m.default_params(), input_range=LIMITS, max_rate=bad)


def test_models_without_an_inverse_say_why():
    for name in ("bouc-wen-oscillator", "mrpim+saturation", "mrpim+delay"):
        m = get_model(name)
        assert m.inverse_unavailable
        with pytest.raises(ModelError, match="cannot be inverted"):
            m.invert(np.ones(5), DT, m.default_params(), input_range=LIMITS)
    with pytest.raises(ModelError, match="derivative"):
        get_model("mrpim", derivative="smoothed").invert(np.ones(5), DT, get_model("mrpim").default_params(),
                                                          input_range=LIMITS)


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), scale=st.floats(0.7, 1.4))
def test_viscoelastic_driven_by_its_inverse_reproduces_the_desired_output(seed, scale):
    """The physics model's inverse (dea_physics.invert_stretch) on reachable trajectories: from
    sample 1 on (sample 0 is the rest state whatever the input) the output is reproduced."""
    m = get_model("viscoelastic")
    p = m.preset("virtual-dea")
    p.update(mu1=p["mu1"] * scale, tau2=p["tau2"] / scale, offset=0.2)
    u = smooth_input(seed, 1500)
    y = m.simulate(u, DT, p)
    inv = m.invert(y, DT, p, input_limits=LIMITS, u_start=u[0])
    assert inv.n_clipped == 0
    achieved = m.simulate(inv.u, DT, p)
    assert np.max(np.abs(achieved - y)[1:]) <= 1e-6 * np.ptp(y)
    np.testing.assert_allclose(inv.u, u, atol=1e-6)  # the stretch increases with the voltage: unique


@pytest.mark.parametrize("name", ["mrpim+creep", "mrpim+interference"])
def test_known_in_time_components_step_and_invert(name):
    """Creep and interference only shift the target: the step kernel equals the forward model
    and the exact inverse reproduces a reachable output."""
    rng = np.random.default_rng(5)
    m = get_model(name)
    p = mrpim_params(rng, m)
    p.update({k: v for k, v in {"creep_time": 20.0, "creep_size": 0.7, "interference_frequency": 3.0,
                                "interference_sin": 0.05, "interference_cos": -0.02}.items() if k in p})
    u = smooth_input(6, 3000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    np.testing.assert_allclose(m.simulate_steps(u, DT, p, input_range=LIMITS), y, rtol=1e-11, atol=1e-11)
    inv = m.invert(y, DT, p, input_range=LIMITS, inverse="exact")
    ok = ~inv.clipped
    assert ok.mean() > 0.99
    assert np.max(np.abs(m.simulate(inv.u, DT, p, input_range=LIMITS) - y)[ok]) <= 1e-6 * np.ptp(y)


# --- the non-P-I models: elliptical, dual-polynomial, preisach, bouc-wen --------------
NON_PI = ("elliptical", "dual-polynomial", "preisach", "bouc-wen")


def non_pi_params(name, rng):
    """A random parameter set of a plausible shape (a rising loop of output range ~1-5; the
    branch models' higher terms kept small, so their branches turn back rarely: where one does,
    the greedy inverse, taking the root nearest the previous input, may take the other side of
    the turn and later miss the reference's path: clipped, and counted)."""
    m = get_model(name)
    if name == "preisach":
        p = {n: float(rng.uniform(0.0, 0.3)) for n in m.param_names}
    elif name == "bouc-wen":
        beta = float(rng.uniform(0.5, 10.0))
        p = dict(beta=beta, gamma=float(rng.uniform(-0.5, 1.0)) * beta, n=float(rng.uniform(1.0, 3.0)),
                 kx=float(rng.uniform(0.5, 2.0)), kz=float(rng.uniform(0.1, 2.0)))
    else:
        p = {n: float(rng.uniform(-0.15, 0.15)) for n in m.param_names}
        p["m1"] = float(rng.uniform(1.0, 2.0))
    p["offset"] = float(rng.uniform(-1.0, 1.0))
    return m, p


def test_non_pi_step_kernels_match_slow_references_and_the_forward_kernels():
    """simulate_steps runs each inverse's step kernel forward: it equals the model's forward
    kernel (bit for bit where both sum alike, 1e-12 for the branch models' matrix product) and
    a plain per-sample reference (test_baselines: 1e-12; Bouc-Wen's solve_ivp: 1e-8)."""
    rng = np.random.default_rng(8)
    u = smooth_input(9, 1200)
    for name, hyper in [("elliptical", {}), ("elliptical", {"linearise": "none", "poly_order": 2}),
                        ("dual-polynomial", {})]:
        m = get_model(name, **hyper)
        p = non_pi_params(name, rng)[1] if not hyper else {"m1": 1.5, "m2": -0.4, "b": 0.3, "offset": 0.1}
        steps = m.simulate_steps(u, DT, p, input_range=LIMITS)
        np.testing.assert_allclose(steps, m.simulate(u, DT, p, input_range=LIMITS), rtol=0, atol=1e-12)
        centre = [p[f"m{j}"] for j in range(1, m.n_centre + 1)]
        half = [p[n] for n in m.param_names[m.n_centre:-1]]
        if name == "elliptical":
            def half_fn(x):
                return half[0] * np.sqrt(1 - x * x)
        else:
            def half_fn(x):
                return (1 - x * x) * sum(h * x**j for j, h in enumerate(half))
        ref = _branch_reference(m.normalised(u, LIMITS), lambda x: sum(c * x ** (j + 1) for j, c in enumerate(centre)),
                                half_fn, p["offset"])
        np.testing.assert_allclose(steps, ref, rtol=0, atol=1e-12)

    m, p = non_pi_params("preisach", rng)
    steps = m.simulate_steps(u, DT, p, input_range=LIMITS)
    np.testing.assert_array_equal(steps, m.simulate(u, DT, p, input_range=LIMITS))
    alphas, betas = m.grid(u, LIMITS)
    weights = [p[n] for n in m.param_names[:-1]]
    np.testing.assert_allclose(steps, _preisach_reference(u, alphas, betas, weights, p["offset"]), atol=1e-12)

    m = get_model("bouc-wen")
    for beta, gamma, n in [(8.0, -2.0, 1.0), (3.0, 1.0, 2.5)]:
        p = dict(beta=beta, gamma=gamma, n=n, kx=0.7, kz=1.9, offset=-0.2)
        steps = m.simulate_steps(u, DT, p, input_range=LIMITS)
        np.testing.assert_array_equal(steps, m.simulate(u, DT, p, input_range=LIMITS))
        xi = m.normalised(u[:300], LIMITS)
        ref = -0.2 + 0.7 * xi + 1.9 * _bouc_wen_reference(xi, beta, gamma, n)
        np.testing.assert_allclose(steps[:300], ref, rtol=0, atol=1e-8)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), name=st.sampled_from(NON_PI))
def test_non_pi_models_driven_by_their_inverse_reproduce_reachable_outputs(seed, name):
    """Reachable trajectories (the model's output for a random smooth input): wherever the
    inverse did not clip, the model driven by it gives the desired output to 1e-6 of its range;
    Preisach to within half its largest stair (its staircase resolution: an output between two
    stairs, e.g. one reached only at a switching level exactly, cannot be met closer)."""
    rng = np.random.default_rng(seed)
    m, p = non_pi_params(name, rng)
    u = smooth_input(seed, 2000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    inv = m.invert(y, DT, p, input_range=LIMITS)
    achieved = m.simulate(inv.u, DT, p, input_range=LIMITS)
    ok = ~inv.clipped
    assert np.all((inv.u >= LIMITS[0]) & (inv.u <= LIMITS[1]))
    assert ok.mean() > 0.99
    error = np.abs(achieved - y)[ok]
    if name == "preisach":
        assert np.max(error) <= 0.5 * m.largest_stair(p, LIMITS) + 1e-12
        # most samples are met exactly; an inverse that lands beside a switching level the reference
        # input hit exactly leaves relays in another state until the input wipes them out
        assert np.mean(error <= 1e-12) > 0.9
    else:
        assert np.max(error) <= 1e-6 * np.ptp(y)


@pytest.mark.parametrize("name", NON_PI)
def test_non_pi_clipping_count_on_an_unreachable_reference(name):
    """30 samples far above and 20 far below every reachable output: exactly those 50 clip, at
    the input limits for the continuous models; with a rate limit it holds throughout."""
    m, p = non_pi_params(name, np.random.default_rng(21))
    u = smooth_input(4, 1000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    span = np.ptp(y)
    desired = np.concatenate([y, np.full(30, y.max() + 5 * span), np.full(20, y.min() - 5 * span), y[-10:]])
    inv = m.invert(desired, DT, p, input_range=LIMITS)
    reachable = m.invert(y, DT, p, input_range=LIMITS)  # the ellipse's first samples fall in its dip at
    # the range's end, narrower than the walk's step: stepped over, so clipped (elliptical.py)
    assert inv.n_clipped == reachable.n_clipped + 50
    np.testing.assert_array_equal(inv.clipped[:1000], reachable.clipped)
    assert np.all(inv.clipped[1000:1050]) and not np.any(inv.clipped[1050:])
    if name != "preisach":  # the staircase is flat at its ends: the first point reaching it is taken
        assert inv.u[1029] == LIMITS[1] and inv.u[1049] == LIMITS[0]
    limited = m.invert(desired, DT, p, input_range=LIMITS, max_rate=50.0)  # 0.05 kV per sample at most
    assert np.max(np.abs(np.diff(limited.u))) <= 50.0 * DT + 1e-12
    assert np.all(limited.clipped[1000:1050])


def test_inverse_recursion_roots_match_finite_differences_of_simulate():
    """The exact inverse's error recursion c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0: its coefficients from
    perturbing the inputs of ``simulate`` (slow reference), away from reversals, give the same roots."""
    model = get_model("mrpim")
    rng = np.random.default_rng(3)
    dt = 1e-3
    params = mrpim_params(rng, model, gamma=0.004, lam=0.003, q=2e-6)
    t = np.arange(400) * dt
    u = 1.5 - np.cos(2 * np.pi * 2.0 * t)  # reversals at 0, 250 ms
    rng_in = (0.5, 2.5)
    rho = model.inverse_recursion_radius(u, dt, params, rng_in)
    assert rho[0] == rho[1] == 0.0 and np.all(np.isfinite(rho))
    for k in (60, 130, 190, 330):
        base = model.simulate(u[:k + 1], dt, params, input_range=rng_in)[k]
        c = []
        for j in range(3):
            h = 1e-6
            up = u[:k + 1].copy()
            up[k - j] += h
            dn = u[:k + 1].copy()
            dn[k - j] -= h
            c.append((model.simulate(up, dt, params, input_range=rng_in)[k]
                      - model.simulate(dn, dt, params, input_range=rng_in)[k]) / (2 * h))
        assert np.isfinite(base)
        assert rho[k] == pytest.approx(np.max(np.abs(np.roots(c))), rel=1e-4)


def test_a_rate_independent_model_has_no_inverse_recursion():
    model = get_model("classical-pi")
    params = dict(model.default_params(), p1=1.0, **{f"a{i}": 0.1 for i in range(1, 14)})
    u = 1.5 - np.cos(np.linspace(0, 6 * np.pi, 300))
    assert np.all(model.inverse_recursion_radius(u, 1e-3, params, (0.5, 2.5)) == 0.0)


# --- the reference-driven inverse -------------------------------------------------------
def slow_guided_model(u, guide, dt, s):
    """The reference-driven model (models/inverse.py) written out plainly: the rates |u'| and u''
    are the guide's backward differences, the filters follow the guide and add their lag x - g^p
    to u^p; the rest is the step structure ``s`` (plays, polynomial, offset per sample)."""
    w = [0.0] * len(s.r_lo)
    filters = list(zip(s.filter_a, s.filter_b0, s.filter_b1, s.filter_power, s.filter_weight))
    x = [0.0] * len(filters)
    out = []
    for k, uk in enumerate(u):
        g = guide[k]
        g1 = guide[k - 1] if k >= 1 else g
        g2 = guide[k - 2] if k >= 2 else g1
        rate = abs(g - g1) / dt
        for i in range(len(s.r_lo)):
            w[i] = max(uk - s.g_lo * rate - s.r_lo[i], min(uk + s.g_hi * rate + s.r_hi[i], w[i]))
        y = s.base[k] + sum(c * uk ** (j + 1) for j, c in enumerate(s.poly)) + s.q * (g - 2 * g1 + g2) / dt ** 2
        y += sum(a * wi for a, wi in zip(s.weights, w))
        for j, (a, b0, b1, p, c) in enumerate(filters):
            x[j] = 0.0 if k == 0 else a * x[j] + b0 * g1 ** p + b1 * g ** p
            if k > 0:
                y += c * (x[j] - g ** p + uk ** p)
        out.append(y)
    return np.array(out)


def slow_guide(y, u_start, gain, dt, guide_time, max_rate=None):
    """The guide, plainly: the reference mapped to the input, u_start + (y - y(0)) / gain, through
    the critically damped follower g(k) = g(k-1) + v, v = (g(k-1) - g(k-2)) (1 - 2c) + c^2 (m - g(k-1)),
    c = dt / guide_time (c = 1: v = m - g(k-1)), v limited to max_rate dt."""
    mapped = u_start + (np.asarray(y) - y[0]) / gain
    c = 1.0 if guide_time == 0 else min(1.0, dt / guide_time)
    step = np.inf if max_rate is None else max_rate * dt
    g = [mapped[0], mapped[0]]  # g(-2), g(-1): at rest
    for m in mapped:
        v = m - g[-1] if c >= 1.0 else (g[-1] - g[-2]) * (1 - 2 * c) + c * c * (m - g[-1])
        g.append(g[-1] + min(max(v, -step), step))
    return np.array(g[2:])


def guided_arguments(m, p, n):
    s = m.step_structure(DT, p, LIMITS, n)
    return s, (DT, np.ascontiguousarray(s.base), *s.arguments())


def test_reference_driven_model_matches_a_slow_reference_and_is_the_model_when_guided_by_its_input():
    rng = np.random.default_rng(8)
    u = smooth_input(3, 1500)
    guide = smooth_input(4, 1500)
    cases = [(get_model("mrpim"), mrpim_params(rng, get_model("mrpim"), gamma=0.02, lam=-0.01, q=1e-4))]
    rd = get_model("rate-dependent-pi")
    cases.append((rd, dict({n: float(rng.uniform(0.1, 1.0)) for n in rd.param_names}, beta=0.01)))
    ext = get_model("mrpim+relaxation", relaxation_powers=(1, 2))
    cases.append((ext, dict(mrpim_params(rng, ext), tau1=0.7, c1=0.4, c1_u2=-0.2)))
    for m, p in cases:
        s, args = guided_arguments(m, p, u.size)
        np.testing.assert_allclose(guided_simulate(u, guide, *args), slow_guided_model(u, guide, DT, s),
                                   rtol=1e-10, atol=1e-10)
        # guided by its own input, the reference-driven model is the model
        np.testing.assert_allclose(guided_simulate(u, u, *args), m.simulate(u, DT, p, input_range=LIMITS),
                                   rtol=1e-10, atol=1e-10)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), name=st.sampled_from(["mrpim", "rate-dependent-pi", "mrpim+relaxation"]),
       gamma=st.floats(0.0, 0.05), lam=st.floats(-0.05, 0.05), q=st.floats(0.0, 1e-4),
       guide_time=st.sampled_from([0.0, 0.005, 0.02]), max_rate=st.sampled_from([None, 20.0]))
def test_reference_driven_inverse_inverts_the_reference_driven_model(seed, name, gamma, lam, q, guide_time, max_rate):
    """The reference-driven inverse is the exact inverse of the model with its rate and relaxation
    terms driven by the guide (slow guide and model above): wherever it did not clip, that model
    driven by its input gives the desired output to 1e-6 of its range; the input stays within the
    limits and the rate limit."""
    rng = np.random.default_rng(seed)
    m = get_model(name)
    p = {n: float(rng.uniform(0.05, 1.0)) for n in m.param_names}
    p.update({k: v for k, v in {"gamma": gamma, "lambda": lam, "q": q, "beta": abs(gamma), "tau1": 0.5}.items()
              if k in p})
    u = smooth_input(seed, 1500)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    inv = m.invert(y, DT, p, input_range=LIMITS, u_start=u[0], inverse="reference-driven", guide_time=guide_time,
                   max_rate=max_rate)
    assert inv.inverse == "reference-driven"
    s = m.step_structure(DT, p, LIMITS, u.size)
    guide = slow_guide(y, u[0], guide_gain(s, LIMITS), DT, guide_time, max_rate)
    achieved = slow_guided_model(inv.u, guide, DT, s)
    ok = ~inv.clipped
    assert np.all((inv.u >= LIMITS[0]) & (inv.u <= LIMITS[1]))
    assert np.max(np.abs(achieved - y)[ok]) <= 1e-6 * np.ptp(y)
    if max_rate is not None:
        assert np.max(np.abs(np.diff(inv.u))) <= max_rate * DT * (1 + 1e-12)


def test_reference_driven_inverse_of_a_rate_independent_model_is_the_exact_one():
    m, p = positive_classical_pi(5)
    u = smooth_input(9, 2000)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    auto = m.invert(y, DT, p, input_range=LIMITS)
    forced = m.invert(y, DT, p, input_range=LIMITS, inverse="reference-driven")
    assert auto.inverse == "exact" and forced.inverse == "reference-driven"
    np.testing.assert_array_equal(forced.u, auto.u)
    np.testing.assert_allclose(forced.u, u, atol=1e-9)
    assert auto.exact_recursion_radius == 0.0


# MRPIM fitted by varpro on the virtual DEA (data/virtual_dea; a fixed model, so no fit runs
# here): its exact inverse's error recursion has roots up to about 1.008 per sample
DEA_MRPIM = {"gamma": 0.1, "lambda": 0.07502, "p1": -1.34117, "p2": 2.19027, "p3": -0.138619, "p4": -0.0204397,
             "q": 0.0237183, "a1": -1.31949, "a2": 1.55213, "a3": -0.405417, "a4": 0.19744, "a5": 0.0531297,
             "a6": 0.161204, "a7": 0.176602, "a8": 0.243429, "a9": 0.321282, "a10": 0.447268, "a11": 2.28218,
             "a12": 0.0, "a13": 0.0, "offset": 3.1498}


def test_reference_driven_inverse_does_not_amplify_an_error_where_the_exact_one_does():
    """One reference sample disturbed by d: the exact inverse of the DEA's MRPIM (recursion roots
    above 1) carries the disturbance on with growth; the reference-driven inverse's input moves by a
    bounded multiple of d and comes back; its input varies about as much as the drive (no ringing)."""
    m = MRPIM()
    t = np.arange(12000) * DT
    u = 1.6 - 0.8 * np.cos(2 * np.pi * 0.2 * t)  # from rest: a reachable trajectory
    y = m.simulate(u, DT, DEA_MRPIM, input_range=LIMITS)
    d = 1e-6 * np.ptp(y)
    disturbed = y.copy()
    disturbed[1000] += d
    response = {}
    for inverse in ("exact", "reference-driven"):
        a, b = (m.invert(r, DT, DEA_MRPIM, input_range=LIMITS, u_start=u[0], inverse=inverse) for r in (y, disturbed))
        response[inverse] = np.abs(a.u - b.u) / d
        if inverse == "reference-driven":
            assert a.exact_recursion_radius > 1.0  # the exact recursion along this input is unstable
            assert np.sum(np.abs(np.diff(a.u))) <= 1.3 * np.sum(np.abs(np.diff(u)))
    assert np.max(response["exact"][-1000:]) > 10.0  # grown from the disturbance, 11 s later
    assert np.max(response["reference-driven"]) < 20.0
    assert np.max(response["reference-driven"][-1000:]) < 1e-3


def test_inversion_names_its_inverse_and_the_exact_recursion_radius():
    m = MRPIM()
    t = np.arange(3000) * DT
    u = 1.6 - 0.8 * np.cos(2 * np.pi * 1.0 * t)
    y = m.simulate(u, DT, DEA_MRPIM, input_range=LIMITS)
    inv = m.invert(y, DT, DEA_MRPIM, input_range=LIMITS, u_start=u[0])
    assert inv.inverse == "reference-driven"  # auto: the model has rate terms
    assert inv.exact_recursion_radius == np.max(m.inverse_recursion_radius(inv.u, DT, DEA_MRPIM, LIMITS))


def test_bad_inverse_options_are_refused():
    m = MRPIM()
    for bad in ({"inverse": "damped"}, {"guide_time": -0.1}, {"guide_time": float("nan")}, {"guide_time": True}):
        with pytest.raises(ModelError, match="inverse|guide_time"):
            m.invert(np.ones(5), DT, DEA_MRPIM, input_range=LIMITS, **bad)
    # a loading curve that falls over the input range: no gain to map the reference by
    p = dict(DEA_MRPIM, p1=-5.0, p2=0.0, p3=0.0, p4=0.0)
    with pytest.raises(ModelError, match="increasing loading curve"):
        m.invert(np.ones(5), DT, p, input_range=LIMITS, inverse="reference-driven")
    assert m.invert(np.ones(5), DT, p, input_range=LIMITS).inverse == "exact"  # auto falls back


def test_the_step_kernels_slope_is_the_derivative_of_its_output_in_the_input():
    """dy/du of ``step_output`` (the inverse's Newton steps, c0 of its error recursion) against a central
    difference of its own y, with relaxation filters of powers 1 and 2 and a non-zero play and filter state."""
    from hysbench.models.inverse import step_output

    rng = np.random.default_rng(5)
    ext = get_model("mrpim+relaxation", relaxation_powers=(1, 2))
    p = dict(mrpim_params(rng, ext), tau1=0.7, c1=0.4, c1_u2=-0.3)
    s = ext.step_structure(DT, p, LIMITS, 10)
    args = s.arguments()
    w = rng.uniform(-0.5, 0.5, args[0].size)
    xf = rng.uniform(0.5, 1.5, args[7].size)
    base = float(np.asarray(s.base)[0])
    for u, u1, u2 in [(1.7, 1.69, 1.685), (0.9, 0.92, 0.93), (2.2, 2.21, 2.2)]:
        def y(x):
            return step_output(x, False, u1, u2, DT, base, w.copy(), xf.copy(), *args)[0]

        slope = step_output(u, False, u1, u2, DT, base, w.copy(), xf.copy(), *args)[1]
        h = 1e-7
        assert slope == pytest.approx((y(u + h) - y(u - h)) / (2 * h), rel=1e-5)


def test_the_guide_gain_is_the_secant_of_the_loading_curve_from_rest():
    """Slow reference: the model without rate terms driven from rest up a ramp over the input range; its
    output's rise over the range's width is the reference-driven inverse's gain."""
    rng = np.random.default_rng(6)
    m = get_model("mrpim")
    p = mrpim_params(rng, m, gamma=0.0, lam=0.0, q=0.0)
    u = np.linspace(LIMITS[0], LIMITS[1], 2001)
    y = m.simulate(u, DT, p, input_range=LIMITS)
    s = m.step_structure(DT, p, LIMITS, u.size)
    assert guide_gain(s, LIMITS) == pytest.approx((y[-1] - y[0]) / (LIMITS[1] - LIMITS[0]), rel=1e-12)
