"""Properties of the one-sided play operator (eq. 3-4, 6-7), checked with hypothesis."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.models import get_model
from hysbench.models.kernels import play_operators

finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)
inputs = st.lists(finite, min_size=2, max_size=200).map(np.array)
thresholds = st.lists(st.floats(0, 50), min_size=1, max_size=8).map(lambda x: np.sort(np.array(x)))


def play_reference(u, r, w0=0.0):
    """Eq. 3-4 literally: F(0) = f(u(0), w0), F(k) = f(u(k), F(k-1)), f(v, w) = max(v - r, min(v, w))."""
    out, w = [], w0
    for v in u:
        w = max(v - r, min(v, w))
        out.append(w)
    return np.array(out)


@given(inputs, thresholds)
def test_kernel_equals_literal_equation(u, r):
    F = play_operators(u, u, r, 0.0)
    for i, ri in enumerate(r):
        np.testing.assert_allclose(F[:, i], play_reference(u, ri), rtol=0, atol=1e-12)


@given(inputs, thresholds, st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(1e-3, 1.0))
def test_output_stays_between_envelopes(u, r, gamma, lam, dt):
    du = np.abs(np.diff(u, prepend=u[0])) / dt
    hl, hr = u - gamma * du, u + lam * du
    F = play_operators(hl, hr, r, 0.0)
    # after the first step, W >= h_l - r and W <= h_r wherever the band is not empty
    lower = hl[:, None] - r[None, :]
    assert np.all(F >= lower - 1e-9)
    band = lower <= hr[:, None]
    assert np.all((F <= hr[:, None] + 1e-9) | ~band)


@given(inputs, thresholds)
def test_classical_output_in_band(u, r):
    F = play_operators(u, u, r, 0.0)
    assert np.all(F[1:] >= u[1:, None] - r[None, :] - 1e-9)
    assert np.all(F[1:] <= u[1:, None] + 1e-9)


@given(st.lists(finite, min_size=2, max_size=100).map(lambda x: np.sort(np.array(x))), thresholds,
       st.booleans())
def test_monotone_input_gives_monotone_output(u, r, decreasing):
    if decreasing:
        u = u[::-1].copy()
    F = play_operators(u, u, r, 0.0)
    d = np.diff(F, axis=0)
    if decreasing:
        assert np.all(d <= 1e-12)
    else:
        assert np.all(d >= -1e-12)


turning_points = st.lists(st.floats(-5, 5), min_size=2, max_size=12).map(np.array)


def piecewise_linear(points, per_segment):
    """A path through the turning points with ``per_segment`` samples per segment."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        out.append(np.linspace(a, b, per_segment + 1)[1:])
    return np.concatenate(out)


@settings(max_examples=60)
@given(turning_points, st.integers(1, 6), st.integers(2, 4), st.floats(1e-4, 1.0), st.floats(1e-4, 1.0))
def test_classical_pi_is_rate_independent(points, n1, factor, dt1, dt2):
    """The same input path resampled in time gives the same output path."""
    model = get_model("classical-pi", n_operators=7)
    rng = np.random.default_rng(0)
    params = dict(zip(model.param_names, rng.normal(size=model.n_params)))
    coarse = piecewise_linear(points, n1)
    fine = piecewise_linear(points, n1 * factor)
    rng_in = (-5.0, 5.0)
    y_coarse = model.simulate(coarse, dt1, params, input_range=rng_in)
    y_fine = model.simulate(fine, dt2, params, input_range=rng_in)
    # the coarse samples are every factor-th fine sample
    np.testing.assert_allclose(y_fine[::factor], y_coarse, rtol=0, atol=1e-9)


def test_mrpim_is_rate_dependent():
    """The contrast: MRPIM's envelopes and q term make the same path at another rate give another output."""
    model = get_model("mrpim")
    params = model.preset("paper")
    u = piecewise_linear(np.array([0.5, 2.5, 0.5]), 500)
    y1 = model.simulate(u, 1e-3, params)
    y2 = model.simulate(u, 1e-2, params)
    assert np.max(np.abs(y1 - y2)) > 1e-2


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=40).map(np.array))
def test_all_finite_is_whether_every_value_is_finite(x):
    from hysbench.models.kernels import all_finite

    x = np.ascontiguousarray(x, dtype=float)
    assert all_finite(x) == bool(np.all(np.isfinite(x)))
