"""The linear blocks' kernels (models/filter_kernels.py) against slow references: the first-order-hold
coefficients in 40-digit decimal arithmetic, and every kernel's output against scipy's continuous-time
simulation of the same block (signal.lsim, input linear between samples)."""

from decimal import Decimal, localcontext

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from hysbench.models.filter_kernels import (first_order_foh, lowpass1_bank, lowpass1_bank_advance, lowpass2_advance,
                                            lowpass2_coefficients, lowpass2_rows, lowpass2_sets, second_order_foh)

DT = 1e-3
N = 300


def continuous_first_order(x, tau):
    """tau y' = x - y from rest (y(0) = 0), x linear between samples."""
    return signal.lsim(([1.0], [tau, 1.0]), x, np.arange(x.size) * DT, interp=True)[1]


def continuous_second_order(x, fn, zeta):
    """y'' + 2 zeta w y' + w^2 y = w^2 x at rest at x(0), x linear between samples."""
    w = 2 * np.pi * fn
    return x[0] + signal.lsim(([w * w], [1.0, 2 * zeta * w, w * w]), x - x[0], np.arange(x.size) * DT,
                              interp=True)[1]


def random_walk(rng, shape):
    return np.cumsum(rng.normal(size=shape), axis=-1) + rng.uniform(-3.0, 3.0)


@settings(max_examples=80)
@given(log_r=st.one_of(st.floats(-12.0, 3.0), st.floats(-8.2, -7.8)))
def test_first_order_coefficients_are_the_closed_form(log_r):
    """a = exp(-r), b1 = 1 - (1 - a) / r, b0 = (1 - a) - b1 (r = h / tau), evaluated with 40 digits, for
    steps from 1e-12 to 1e3 time constants: each coefficient within an ulp of 1, the resolution a itself is
    stored with (the recurrence x <- a x + ... cannot resolve 1 - a more finely)."""
    r = 10.0 ** log_r
    a, b0, b1 = first_order_foh(1.0 / r, 1.0)
    with localcontext() as ctx:
        ctx.prec = 40
        R = Decimal(1.0 / (1.0 / r))  # the r the kernel sees (h / tau, rounded)
        A = (-R).exp()
        B1 = 1 - (1 - A) / R
        B0 = (1 - A) - B1
        for got, exact in ((a, A), (b0, B0), (b1, B1)):
            assert abs(Decimal(got) - exact) <= Decimal(2.3e-16)


def test_first_order_coefficients_keep_the_static_gain():
    """b0 + b1 = 1 - a: a constant input's steady state is that input."""
    for tau in (1e-6, 1e-3, 0.07, 3.0, 1e4, 1e9):
        _, b0, b1 = first_order_foh(tau, DT)
        one_minus_a = -np.expm1(-DT / tau)
        assert abs((b0 + b1) - one_minus_a) <= 2.3e-16 * one_minus_a


@settings(max_examples=20)
@given(taus=st.lists(st.floats(1e-4, 1e3), min_size=1, max_size=4), seed=st.integers(0, 10_000))
def test_first_order_bank_is_each_continuous_response(taus, seed):
    x = random_walk(np.random.default_rng(seed), N)
    a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(t, DT) for t in taus)))
    out = lowpass1_bank(x, a, b0, b1)
    for j, tau in enumerate(taus):
        np.testing.assert_allclose(out[j], continuous_first_order(x, tau), rtol=0, atol=1e-12 * np.max(np.abs(x)))


@settings(max_examples=20)
@given(sets=st.lists(st.tuples(st.floats(0.05, 150.0), st.floats(0.005, 4.0)), min_size=1, max_size=4),
       seed=st.integers(0, 10_000))
def test_second_order_sets_are_each_rows_continuous_response(sets, seed):
    """lowpass2_sets: row j of V through its own (natural frequency, damping ratio)."""
    V = random_walk(np.random.default_rng(seed), (len(sets), N))
    coefficients = [second_order_foh(fn, zeta, DT) for fn, zeta in sets]
    phis, g0s, g1s = (np.ascontiguousarray(np.array(c)) for c in zip(*coefficients))
    out = lowpass2_sets(V, phis, g0s, g1s)
    assert out.shape == V.shape
    for j, (fn, zeta) in enumerate(sets):
        np.testing.assert_allclose(out[j], continuous_second_order(V[j], fn, zeta), rtol=0,
                                   atol=1e-12 * np.max(np.abs(V[j])))
        assert np.array_equal(out[j], lowpass2_rows(V[j:j + 1], *coefficients[j])[0])


@settings(max_examples=20)
@given(blocks=st.lists(st.tuples(st.floats(1e-3, 50.0), st.integers(1, 3), st.floats(-2.0, 2.0)), min_size=1,
                       max_size=4), seed=st.integers(0, 10_000))
def test_first_order_bank_stepper_is_the_weighted_continuous_responses(blocks, seed):
    """lowpass1_bank_advance, one sample at a time: sum_j w_j (block of time constant tau_j on u^p_j)."""
    u = 1.0 + 0.3 * np.sin(np.cumsum(np.random.default_rng(seed).normal(size=N)) * 0.2)
    taus, powers, weights = (np.array(c) for c in zip(*blocks))
    a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(t, DT) for t in taus)))
    coef = np.concatenate((a, b0, b1, weights))
    state = np.zeros(len(blocks) + 2)
    state[0] = 1.0  # the first sample
    got = np.array([lowpass1_bank_advance(state, coef, powers.astype(np.int64), float(v)) for v in u])
    ref = sum(w * continuous_first_order(u ** p, t) for t, p, w in blocks)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.sum(np.abs(weights)) * np.max(u) ** 3)


@settings(max_examples=20)
@given(fn=st.floats(0.05, 150.0), zeta=st.floats(0.005, 4.0), seed=st.integers(0, 10_000))
def test_second_order_stepper_is_the_continuous_response(fn, zeta, seed):
    """lowpass2_advance, one sample at a time, from rest at the first sample's value."""
    x = random_walk(np.random.default_rng(seed), N)
    coef = lowpass2_coefficients(*second_order_foh(fn, zeta, DT))
    state = np.array([1.0, 0.0, 0.0, 0.0])
    got = np.array([lowpass2_advance(state, coef, float(v)) for v in x])
    np.testing.assert_allclose(got, continuous_second_order(x, fn, zeta), rtol=0, atol=1e-12 * np.max(np.abs(x)))
