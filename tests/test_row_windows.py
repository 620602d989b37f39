"""A window may be a row subset (increasing sample indices) as well as a slice.

Every registered model: its windowed regressors and windowed simulation on a
row subset are exactly those rows of the whole-record regressors / output
(the slow, obvious reference), for random inputs, parameters and subsets.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hysbench.models import DataScale, ExtendedModel, ModelError, Window, get_model, list_models
from hysbench.models.extended import KEPT

DT = 1e-3
N = 1500
SCALE = DataScale(u=3.0, y=10.0, time=0.5)
EXTENDED = ExtendedModel("mrpim", ("relaxation", "delay", "resonance", "creep", "interference"), n_relaxation=2)


def _input(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(N) * DT
    u = 1.5 + sum(rng.uniform(0.2, 0.6) * np.sin(2 * np.pi * rng.uniform(0.5, 4.0) * t + rng.uniform(0, 6))
                  for _ in range(3))
    return u + 0.005 * rng.normal(size=N)


def _models():
    names = [n for n in list_models() if "+" not in n]
    exact = {"viscoelastic": {"warmup_stride": 1}}  # its default crosses the warm-up in 5-sample steps
    return [get_model(n, **exact.get(n, {})) for n in names] + [EXTENDED]


MODELS = _models()
IDS = [m.name for m in MODELS]


def _params(model, rng) -> np.ndarray:
    lo, hi = model.bounds(SCALE)
    P = lo + rng.random((2, lo.size)) * (hi - lo)
    for i, p in enumerate(model.parameters(SCALE)):  # keep the slow (ODE) models' inputs tame
        if p.name in ("delay",):
            P[:, i] = rng.uniform(0.0, 0.01, 2)
        if p.name.startswith("tau") or p.name == "creep_time":
            P[:, i] = rng.uniform(0.05, 2.0, 2)
        if p.name == "natural_frequency":
            P[:, i] = rng.uniform(5.0, 50.0, 2)
    return P


rows_strategy = st.lists(st.integers(0, N - 1), min_size=1, max_size=60, unique=True).map(sorted)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 10_000), rows=rows_strategy)
def test_row_subsets_are_rows_of_the_whole(model, seed, rows):
    rng = np.random.default_rng(seed)
    u = _input(seed)
    P = _params(model, rng)
    rows = np.array(rows, dtype=np.int64)
    in_range = (float(u.min()), float(u.max()))
    whole = model.simulate_batch(u, DT, P, input_range=in_range)
    got = model.simulate_window_batch(u, DT, P, rows, input_range=in_range)
    np.testing.assert_allclose(got, whole[:, rows], rtol=1e-10, atol=1e-10)
    # the same windows as Window values: a row subset and the contiguous span it covers
    as_window = model.simulate_window_batch(u, DT, P, Window.of(rows, N), input_range=in_range)
    np.testing.assert_array_equal(as_window, got)
    span = Window.of(slice(int(rows[0]), int(rows[-1]) + 1), N)
    np.testing.assert_allclose(model.simulate_window_batch(u, DT, P, span, input_range=in_range),
                               whole[:, span.index], rtol=1e-10, atol=1e-10)
    if not model.has_linear_part:
        return
    nl_idx = [model.param_names.index(n) for n in model.nonlinear_names]
    sets = P[:, nl_idx]
    batch = model.windowed_regressors_batch(u, DT, sets, rows, input_range=in_range)
    assert batch.shape == (2, rows.size, len(model.linear_names))
    for row, B in zip(sets, batch):
        nl = dict(zip(model.nonlinear_names, map(float, row)))
        full = model.regressors(u, DT, nl, input_range=in_range)
        np.testing.assert_allclose(B, full[rows], rtol=1e-10, atol=1e-10)
        one = model.windowed_regressors(u, DT, nl, rows, input_range=in_range)
        np.testing.assert_allclose(one, full[rows], rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("bad", [np.array([], dtype=int), np.array([5, 3]), np.array([2, 2]),
                                 np.array([-1, 4]), np.array([0, N]), np.array([0.0, 3.0]),
                                 np.array([[1, 2]])])
def test_a_bad_row_subset_is_refused(bad):
    model = get_model("mrpim")
    u = _input(0)
    with pytest.raises(ModelError, match="window"):
        model.windowed_regressors(u, DT, {"gamma": 0.0, "lambda": 0.0}, bad)
    with pytest.raises(ModelError, match="window"):
        model.simulate_window_batch(u, DT, np.zeros((1, model.n_params)), bad)


def test_window_values():
    w = Window.of(slice(10, 20), N)
    assert (w.start, w.stop, w.rows, len(w), w.index, w.in_span) == (10, 20, None, 10, slice(10, 20), slice(None))
    r = Window.of(np.array([3, 7, 9]), N)
    assert (r.start, r.stop, len(r)) == (3, 10, 3)
    np.testing.assert_array_equal(r.in_span, [0, 4, 6])
    assert Window.of(r, N) is r
    with pytest.raises(ModelError, match="step 1"):
        Window.of(slice(0, 10, 2), N)
    with pytest.raises(ModelError, match="reaching"):
        Window.of(Window(0, N + 1), N)


@pytest.mark.parametrize("components", [("relaxation", "creep"), ("relaxation", "creep", "resonance")])
@settings(max_examples=5, deadline=None)
@given(seed=st.integers(0, 10_000), rows=rows_strategy)
def test_assembled_columns_at_rows_are_rows_of_the_whole_columns(components, seed, rows):
    model = ExtendedModel("mrpim", components, n_relaxation=2)
    rng = np.random.default_rng(seed)
    u, rows = _input(seed), np.array(rows, dtype=np.int64)
    nl = {"tau1": rng.uniform(0.05, 2.0), "tau2": rng.uniform(0.05, 2.0), "creep_time": rng.uniform(0.1, 5.0),
          "natural_frequency": rng.uniform(5.0, 50.0), "damping_ratio": rng.uniform(0.1, 0.9)}
    base = model.base_columns(u, DT, {"gamma": 0.01, "lambda": 0.02}, (float(u.min()), float(u.max())))
    t0 = float(rng.uniform(0.0, 3.0))
    whole = model.assemble_columns(u, DT, base, nl, t0)
    at_rows = model.assemble_columns(u, DT, base, nl, t0, rows=rows)
    assert set(at_rows) == set(whole)
    for name, column in whole.items():
        np.testing.assert_array_equal(at_rows[name], column[rows])


@pytest.mark.parametrize("components", [("relaxation", "delay", "creep"), ("delay", "resonance", "interference")])
@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 10_000), rows=rows_strategy)
def test_regressors_from_a_cache_are_those_computed_afresh(components, seed, rows):
    """A caller's cache (``windowed_regressors(..., cache=)``: what a delay and base parameters seen before give)
    changes no bit of the regressors, over points that move one parameter at a time (as a numerical Jacobian
    does), and keeps at most ``KEPT`` entries."""
    model = ExtendedModel("mrpim", components)
    rng = np.random.default_rng(seed)
    u, rows = _input(seed), np.array(rows, dtype=np.int64)
    in_range = (float(u.min()), float(u.max()))
    P = _params(model, rng)[0]
    start = {n: float(P[model.param_names.index(n)]) for n in model.nonlinear_names}
    points = [start] + [{**start, n: v * (1 + 1e-4) + 1e-6} for n, v in start.items()]
    for window in (rows, slice(int(rows[0]), N)):
        cache = {}
        for nl in points + points[::-1]:
            kept = model.windowed_regressors(u, DT, nl, window, input_range=in_range, cache=cache)
            np.testing.assert_array_equal(kept, model.windowed_regressors(u, DT, nl, window, input_range=in_range))
        assert 0 < len(cache) <= KEPT
