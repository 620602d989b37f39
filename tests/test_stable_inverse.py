"""Identification constrained to a stable exact inverse (varpro's ``stable_inverse``): the recursion
rows against finite differences of ``simulate``, the constrained linear solve against an enumeration of active sets,
a constrained fit whose recursion roots stay within the radius, and the default path untouched."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from hysbench.data.dataset import load_dataset
from hysbench.identification import identify
from hysbench.identification.errors import IdentificationError
from hysbench.identification.linear import (column_norms, least_distance, solve_spectrum,
                                            spectral_inequality_solve, spectrum_from_qr)
from hysbench.identification.varpro import Varpro, recursion_roots
from hysbench.models import get_model
from hysbench.models.inverse import reachable_operating_points, recursion_activity

from tiny_dataset import write_tiny_dataset


def active_set_reference(A, b, G, h):
    """min ||A x - b||^2 subject to G x >= h by trying every set of rows held as equalities (slow,
    obvious): each equality-constrained least squares is a KKT system; the best feasible one wins."""
    n = A.shape[1]
    best, best_f = None, np.inf
    for subset in itertools.chain.from_iterable(itertools.combinations(range(G.shape[0]), k) for k in range(n + 1)):
        E = G[list(subset)]
        K = np.block([[2 * A.T @ A, E.T], [E, np.zeros((len(subset), len(subset)))]])
        try:
            sol = np.linalg.solve(K, np.concatenate([2 * A.T @ b, h[list(subset)]]))
        except np.linalg.LinAlgError:
            continue
        x = sol[:n]
        f = float(np.sum((A @ x - b) ** 2))
        if np.all(G @ x >= h - 1e-10) and f < best_f:
            best, best_f = x, f
    return best


@pytest.mark.parametrize("seed", range(6))
def test_constrained_linear_solve_matches_an_active_set_enumeration(seed):
    rng = np.random.default_rng(seed)
    n = 4
    A = rng.standard_normal((30, n)) * np.array([1.0, 10.0, 0.1, 3.0])  # columns of different scales
    b = rng.standard_normal(30)
    G = rng.standard_normal((6, n))
    h = G @ rng.uniform(-0.3, 0.3, n) - rng.uniform(0.0, 0.1, 6)  # feasible by construction
    D = column_norms(A)
    ev, V, rhs = spectrum_from_qr(A, b, column_scale=D)
    spec = solve_spectrum(ev, V, rhs)
    x = spectral_inequality_solve(V[:, spec.kept], spec.denominators[spec.kept], rhs[spec.kept], D, G, h)
    ref = active_set_reference(A, b, G, h)
    unconstrained = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.any(G @ unconstrained < h)  # the constraint matters
    assert np.all(G @ x >= h - 1e-10)
    f = float(np.sum((A @ x - b) ** 2))
    assert f == pytest.approx(float(np.sum((A @ ref - b) ** 2)), rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(x, ref, rtol=1e-6, atol=1e-7)


def test_least_distance_feasible_inactive_and_inconsistent():
    E = np.array([[1.0, 0.0], [0.0, 1.0]])
    np.testing.assert_allclose(least_distance(E, np.array([1.0, 2.0])), [1.0, 2.0], atol=1e-12)
    np.testing.assert_array_equal(least_distance(E, np.array([-1.0, -2.0])), [0.0, 0.0])  # z = 0 holds
    assert least_distance(np.array([[1.0], [-1.0]]), np.array([1.0, 0.0])) is None  # z >= 1 and z <= 0
    # a consistent row far from the origin: the least-norm z is on it, however far
    np.testing.assert_allclose(least_distance(np.array([[1.0, 0.0]]), np.array([1e3])), [1e3, 0.0], rtol=1e-9)


def test_recursion_rows_match_finite_differences_of_simulate():
    """c_j = dy(k)/du(k-j) with the plays held: the rows (linear in the linear parameters) against
    central differences of ``simulate`` at samples away from reversals and play edges."""
    model = get_model("mrpim")
    rng = np.random.default_rng(5)
    dt = 1e-3
    params = model.default_params()
    for name in params:
        if name[0] in "ap" and name != "offset":
            params[name] = float(rng.uniform(-1.0, 1.0))
    params.update(gamma=0.004, **{"lambda": 0.003}, q=2e-6, offset=0.3)
    u = 1.5 - np.cos(2 * np.pi * 2.0 * np.arange(400) * dt)
    rng_in = (0.5, 2.5)
    rows = model.inverse_recursion_rows(u, dt, {"gamma": 0.004, "lambda": 0.003}, None, rng_in, n_levels=10**6)
    theta = np.array([params[n] for n in model.linear_names])
    checked = 0
    for k in (60, 130, 190, 330):
        at = np.flatnonzero(rows.sample == k)
        if at.size == 0:
            continue
        c = []
        for j in range(3):
            h = 1e-7
            up, dn = u[:k + 1].copy(), u[:k + 1].copy()
            up[k - j] += h
            dn[k - j] -= h
            c.append((model.simulate(up, dt, params, input_range=rng_in)[k]
                      - model.simulate(dn, dt, params, input_range=rng_in)[k]) / (2 * h))
        got = [float(C[at[0]] @ theta) for C in (rows.c0, rows.c1, rows.c2)]
        np.testing.assert_allclose(got, c, rtol=1e-5, atol=1e-6)
        checked += 1
    assert checked >= 3


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return write_tiny_dataset(tmp_path_factory.mktemp("tiny"))


def test_a_constrained_fit_keeps_the_recursion_roots_within_the_radius(tiny):
    options = {"n_candidates": 4, "n_starts": 1, "max_nfev": 10}
    fit = identify("mrpim", tiny, "varpro", seed=0, stable_inverse=True, inverse_radius=0.99, **options)
    report = fit.diagnostics["varpro"]["stable_inverse"]
    assert report["inverse_radius"] == [0.99] and report["operating_points"] > 0
    assert report["largest_violation"] <= 1e-9
    # a double root on the radius moves by the square root of the conditions' rounding
    assert report["largest_root_at_operating_points"] <= 0.99 * (1 + 1e-5)
    assert any("stable_inverse" in n and "active at the optimum" in n for n in fit.notes)
    model = get_model("mrpim")
    from hysbench.data.dataset import load_dataset
    for record in load_dataset(tiny).identification:
        rho = model.inverse_recursion_radius(record.u, record.dt, fit.params, fit.input_range)
        assert np.max(rho) <= 0.99 * (1 + 1e-5)
    # the same fit without the constraint leaves the radius, so the constraint did something here
    free = identify("mrpim", tiny, "varpro", seed=0, **options)
    assert free.fitness <= fit.fitness
    worst = max(np.max(model.inverse_recursion_radius(r.u, r.dt, free.params, free.input_range))
                for r in load_dataset(tiny).identification)
    assert worst > 0.99


def random_inputs(rng, lo, hi, n_inputs, n=3000, dt=1e-3):
    """Inputs within [lo, hi] from rest at lo: band-limited random, sines, triangles and steps at
    random rates, amplitudes and offsets (each call with its own generator: fresh inputs)."""
    t = np.arange(n) * dt
    for i in range(n_inputs):
        amp = rng.uniform(0.05, 0.5) * (hi - lo)
        mid = rng.uniform(lo + amp, hi - amp)
        f = 10 ** rng.uniform(-1.0, 1.0)
        kind = i % 4
        if kind == 0:
            spectrum = np.fft.rfft(rng.standard_normal(n))
            spectrum[np.fft.rfftfreq(n, dt) > 3 * f] = 0.0
            x = np.fft.irfft(spectrum, n)
            x = mid + amp * x / np.max(np.abs(x))
        elif kind == 1:
            x = mid + amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        elif kind == 2:
            x = mid + amp * (2 * np.abs(2 * ((f * t + rng.uniform()) % 1.0) - 1) - 1)
        else:
            levels = rng.uniform(lo, hi, 12)
            x = levels[np.minimum((t * 12 / t[-1]).astype(int), 11)]
        x = np.clip(x, lo, hi)
        x[0] = lo
        yield x


@pytest.mark.parametrize("seed, rates", [(11, (0.0, 0.1)), (12, (0.0, 0.1)), (13, (-0.1, 0.1))])
def test_every_visited_operating_point_is_in_the_input_ranges_cover(seed, rates):
    """The cover (``reachable_operating_points``) against the operating points random inputs visit,
    for random rate coefficients (non-negative, or of either sign): each visited (edges, sign) is one
    of the cover's patterns (play 1's edges meet at u' = 0, where either label gives the same row),
    with u within the pattern's interval."""
    rng = np.random.default_rng(seed)
    model = get_model("mrpim")
    lo, hi = 0.5, 2.5
    r = model.thresholds(np.array([lo, hi]), (lo, hi))
    visited = 0
    for x in random_inputs(rng, lo, hi, 8):
        g_lo, g_hi = rng.uniform(*rates, 2)
        edge, sign, u = reachable_operating_points(r, (lo, hi), 32, g_lo, g_hi)
        span = {}
        for e, s, v in zip(edge, sign, u):
            key = (e.tobytes(), s)
            a, b = span.get(key, (np.inf, -np.inf))
            span[key] = (min(a, v), max(b, v))
        e_run, s_run = recursion_activity(x, 1e-3, r, np.zeros_like(r), g_lo, g_hi, 2, x.size)
        for e, s, v in zip(e_run, s_run, x[2:]):
            e = e.copy()
            if s == 0.0 and e[0] == 1 and np.any(e == -1):
                e[0] = -1  # u' = 0: play 1's edges coincide
            a, b = span[(e.tobytes(), s)]
            assert a - 1e-12 <= v <= b + 1e-12
            visited += 1
    assert visited > 0


def test_a_constrained_fit_keeps_the_roots_within_the_radius_on_inputs_it_never_saw(tiny):
    """The constraint covers every operating point an input within the input range reaches: along
    fresh random inputs (not the fit records, not used to build any row) the roots stay within rho."""
    options = {"n_candidates": 4, "n_starts": 1, "max_nfev": 10}
    fit = identify("mrpim", tiny, "varpro", seed=0, stable_inverse=True, inverse_radius=0.99, **options)
    report = fit.diagnostics["varpro"]["stable_inverse"]
    assert report["operating_points_input_range"] > 0
    assert report["operating_points"] == report["operating_points_fit_records"] + report["operating_points_input_range"]
    assert "within the input range" in report["constrained_points"]
    model = get_model("mrpim")
    lo, hi = fit.input_range
    free = identify("mrpim", tiny, "varpro", seed=0, **options)
    worst = {"constrained": 0.0, "free": 0.0}
    rng = np.random.default_rng(2024)
    for dt in sorted({r.dt for r in load_dataset(tiny).identification}):  # the rate the inverse runs at
        for x in random_inputs(rng, lo, hi, 12, n=600, dt=dt):
            for name, f in (("constrained", fit), ("free", free)):
                rho = model.inverse_recursion_radius(x, dt, f.params, f.input_range)
                worst[name] = max(worst[name], float(np.max(rho)))
    # u between the cover's points (band ends) moves only the polynomial's slope
    assert worst["constrained"] <= 0.99 * (1 + 1e-4)
    assert worst["free"] > 1.0  # these inputs do reach unstable operating points of an unconstrained fit


def test_the_default_radius_is_a_decay_within_the_shortest_drive_period(tiny):
    fit = identify("mrpim", tiny, "varpro", seed=0, stable_inverse=True, n_candidates=2, n_starts=1, max_nfev=4)
    period = fit.scale["time"]
    expected = sorted({math.exp(-r.dt / period) for r in __import__("hysbench").load_dataset(tiny).identification})
    np.testing.assert_allclose(fit.diagnostics["varpro"]["stable_inverse"]["inverse_radius"], expected, rtol=1e-15)


def test_the_default_path_is_the_unconstrained_one(tiny):
    assert Varpro().stable_inverse is False
    options = {"n_candidates": 3, "n_starts": 1, "max_nfev": 6}
    default = identify("mrpim", tiny, "varpro", seed=0, **options)
    off = identify("mrpim", tiny, "varpro", seed=0, stable_inverse=False, inverse_radius=0.5, **options)
    assert default.params == off.params and default.fitness == off.fitness
    assert "stable_inverse" not in default.diagnostics["varpro"]
    assert not any("stable_inverse" in n for n in default.notes)


def test_bad_stable_inverse_options_are_refused_in_one_line(tiny):
    with pytest.raises(IdentificationError, match="inverse_radius must be in"):
        identify("mrpim", tiny, "varpro", stable_inverse=True, inverse_radius=1.5)
    with pytest.raises(IdentificationError, match="does not state its exact inverse's error recursion"):
        identify("rate-dependent-pi", tiny, "varpro", stable_inverse=True)
    with pytest.raises(IdentificationError, match="would move the parameters without the constraint"):
        identify("mrpim", tiny, "varpro+lsq", stable_inverse=True)


def test_recursion_roots_agree_with_numpy():
    rng = np.random.default_rng(2)
    c = rng.standard_normal((50, 3))
    expected = [np.max(np.abs(np.roots(row))) for row in c]
    np.testing.assert_allclose(recursion_roots(c[:, 0], c[:, 1], c[:, 2]), expected, rtol=1e-12)


def test_recursion_rows_give_the_roots_inverse_recursion_radius_reports():
    """The rows at every operating point (no thinning) against the model's own per-sample radius,
    across reversals and play edges (there both take the one-sided slope the inverse's search uses)."""
    model = get_model("mrpim")
    rng = np.random.default_rng(8)
    params = model.default_params()
    for name in params:
        if name[0] in "ap":
            params[name] = float(rng.uniform(-1.0, 1.0))
    params.update(gamma=0.05, **{"lambda": 0.03}, q=1e-4, offset=0.1)
    dt = 1e-3
    t = np.arange(3000) * dt
    u = 1.5 - np.cos(2 * np.pi * 1.0 * t) * (0.6 + 0.4 * np.sin(2 * np.pi * 0.7 * t))
    rows = model.inverse_recursion_rows(u, dt, {"gamma": 0.05, "lambda": 0.03}, None, (0.5, 2.5), n_levels=10**9)
    theta = np.array([params[n] for n in model.linear_names])
    rho = model.inverse_recursion_radius(u, dt, params, (0.5, 2.5))
    assert rows.sample.size == u.size - 2  # every sample is its own point at this resolution
    np.testing.assert_allclose(recursion_roots(rows.c0 @ theta, rows.c1 @ theta, rows.c2 @ theta),
                               rho[rows.sample], rtol=1e-9)
