"""The root search every causal inverse shares (models/root_search.py) against a slow reference: the
documented walk written out plainly, scipy's brentq on the bracket it finds, and the nearest visited
output where it finds none."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from hysbench.models.root_search import (NEWTON_ITERATIONS, NO_INPUT, SEARCH_SIZE, search_clipped, search_done,
                                         search_next, search_start)

LO, HI = -1.0, 1.5  # the input limits of every case here
N_GRID = 32


def run_search(g, dg, start, max_step=np.inf, tol=1e-12, clip_tol=None, lo=LO, hi=HI, n_grid=N_GRID):
    """(x, clipped, evaluations) of the kernel's search on g (dg: dy/du, or None: secant steps)."""
    st_ = np.zeros(SEARCH_SIZE)
    x = search_start(st_, NO_INPUT, 0, start, lo, hi, max_step, n_grid, tol, tol if clip_tol is None else clip_tol)
    evaluations = 0
    while not search_done(st_):
        evaluations += 1
        assert evaluations <= 2 * n_grid + NEWTON_ITERATIONS + 4
        x = search_next(st_, g(x), np.nan if dg is None else dg(x))
    return x, bool(search_clipped(st_)), evaluations


def reference_walk(g, start, max_step=np.inf, tol=1e-12, lo=LO, hi=HI, n_grid=N_GRID):
    """The documented walk: from ``start`` outward in steps of (hi - lo) / n_grid, up then down
    alternately, within the limits narrowed to start +- max_step. Returns (visited points, outcome):
    ("root", x) where |g| <= tol, ("bracket", a, b) at the first sign change (a: that side's previous
    point), or None."""
    h = (hi - lo) / n_grid
    a, b = max(lo, start - max_step), min(hi, start + max_step)
    visited = [start]
    if abs(g(start)) <= tol:
        return visited, ("root", start)
    last = [start, start]
    done = [start >= b, start <= a]
    j = 1
    while not all(done):
        for side in (0, 1):
            if done[side]:
                continue
            x = min(start + j * h, b) if side == 0 else max(start - j * h, a)
            visited.append(x)
            if abs(g(x)) <= tol:
                return visited, ("root", x)
            if (g(x) > 0) != (g(last[side]) > 0):
                return visited, ("bracket", last[side], x)
            last[side] = x
            done[side] = x >= b if side == 0 else x <= a
        j += 1
    return visited, None


def check_against_reference(g, dg, start, max_step=np.inf, tol=1e-12):
    """The kernel's result is the reference's: the root it brackets (brentq), the root the walk hits,
    or the visited point of smallest |g| (clipped)."""
    x, clipped, _ = run_search(g, dg, start, max_step, tol)
    visited, outcome = reference_walk(g, start, max_step, tol)
    if outcome is None:
        assert clipped
        assert x == min(visited, key=lambda v: abs(g(v)))
    elif outcome[0] == "root":
        assert not clipped and x == outcome[1]
    else:
        a, b = sorted(outcome[1:])
        assert not clipped and a <= x <= b
        eps = 1e-14 * (abs(a) + abs(b))
        if abs(g(x)) > tol:  # no root to tolerance: a sign change within a few ulps of x
            assert (g(max(a, x - eps)) > 0) != (g(min(b, x + eps)) > 0)
        signs = np.sign([g(v) for v in np.linspace(a, b, 65)])
        if np.all(signs != 0) and np.count_nonzero(np.diff(signs)) == 1:  # one crossing: brentq's root is x's
            r = brentq(g, a, b, xtol=1e-15, rtol=1e-15, maxiter=1000)
            # where g is flat at its root (a multiple root) |g| <= tol holds some way from the crossing
            assert abs(x - r) <= 1e-12 * (1 + abs(r)) or abs(g(x)) <= tol, (x, r, g(x))
    return x, clipped


def cubic(c):
    return (lambda x: ((c[3] * x + c[2]) * x + c[1]) * x + c[0],
            lambda x: (3 * c[3] * x + 2 * c[2]) * x + c[1])


@settings(max_examples=60)
@given(c=st.lists(st.floats(-3, 3), min_size=4, max_size=4), start=st.floats(LO, HI),
       max_step=st.sampled_from([np.inf, 0.5, 1.3]), newton=st.booleans())
def test_cubics_match_the_reference_walk_and_brentq(c, start, max_step, newton):
    """Non-monotone g: the first bracket of the walk, its root, or the nearest visited output."""
    g, dg = cubic(c)
    check_against_reference(g, dg if newton else None, start, max_step)


@settings(max_examples=60)
@given(knots=st.lists(st.floats(LO, HI), min_size=1, max_size=5), seed=st.integers(0, 10_000),
       start=st.floats(LO, HI), flat=st.sampled_from(["none", "zero", "level"]), jump=st.booleans(),
       newton=st.booleans(), tol=st.sampled_from([0.0, 1e-12]))
def test_kinks_flat_segments_and_jumps_match_the_reference(knots, seed, start, flat, jump, newton, tol):
    """Piecewise-linear g (the P-I family's shape) with a flat piece at zero or at a level, and a jump
    (a Preisach stair): the kernel follows the reference walk; across a jump it returns the jump's
    location (a sign change within a few ulps), not clipped."""
    rng = np.random.default_rng(seed)
    kx = np.concatenate(([LO - 1.0], np.sort(knots), [HI + 1.0]))
    ky = rng.normal(size=kx.size)
    if flat != "none":
        i = rng.integers(0, kx.size - 1)
        ky[i + 1] = ky[i] = 0.0 if flat == "zero" else ky[i]

    def g(x):
        return float(np.interp(x, kx, ky)) + (0.3 if jump and x > kx[1] else 0.0)

    def dg(x):
        i = min(max(int(np.searchsorted(kx, x, side="right")) - 1, 0), kx.size - 2)
        return float((ky[i + 1] - ky[i]) / (kx[i + 1] - kx[i]))

    check_against_reference(g, dg if newton else None, start, tol=tol)


@settings(max_examples=40)
@given(slope=st.floats(0.2, 5.0), root=st.floats(LO, HI), start=st.floats(LO, HI), newton=st.booleans())
def test_a_monotone_function_is_inverted_from_any_start(slope, root, start, newton):
    """Property: for an increasing g with a root within the limits the search returns that root,
    unclipped, whatever the previous input."""
    def g(x):
        return slope * (x - root) + 0.3 * np.tanh(3 * (x - root))

    def dg(x):
        return slope + 0.9 / np.cosh(3 * (x - root)) ** 2

    x, clipped, _ = run_search(g, dg if newton else None, start)
    assert not clipped
    assert abs(x - root) <= 1e-12 / slope


@settings(max_examples=40)
@given(level=st.floats(0.01, 10.0), side=st.sampled_from([-1.0, 1.0]), start=st.floats(LO, HI),
       max_step=st.sampled_from([np.inf, 0.3]))
def test_an_unreachable_target_takes_the_nearest_reachable_limit_and_clips(level, side, start, max_step):
    """Property: g increasing with no root within the limits (narrowed by max_step): the result is the
    end of the narrowed interval nearer the target, and the sample is clipped."""
    def g(x):
        return x - (HI + level if side > 0 else LO - level)

    x, clipped, _ = run_search(g, lambda x: 1.0, start, max_step)
    assert clipped
    assert x == (min(HI, start + max_step) if side > 0 else max(LO, start - max_step))


def test_edge_cases_by_hand():
    """A root at the start (no further evaluation), at each limit, on a walk point, a touching root
    (clipped), a flat zero piece, the clip tolerance, zero max_step, and a given input (run forward)."""
    x, clipped, n = run_search(lambda x: x - 0.2, lambda x: 1.0, 0.2)
    assert (x, clipped, n) == (0.2, False, 1)
    for root in (LO, HI):
        x, clipped, _ = run_search(lambda x, r=root: x - r, lambda x: 1.0, 0.1)
        assert x == pytest.approx(root, abs=1e-12) and not clipped
    h = (HI - LO) / N_GRID
    x, clipped, _ = run_search(lambda x: x - (0.0 + 3 * h), None, 0.0)  # hit by the walk's third up step
    assert x == pytest.approx(3 * h, abs=1e-15) and not clipped
    x, clipped, _ = run_search(lambda x: (x - 0.4321) ** 2, lambda x: 2 * (x - 0.4321), 0.0)
    assert clipped and x == pytest.approx(0.4321, abs=h)  # touching root: no sign change
    x, clipped, _ = run_search(lambda x: x - 0.1 if x < 0.1 else x - 0.5 if x > 0.5 else 0.0, None, 1.0)
    assert not clipped and 0.1 <= x <= 0.5 + 1e-12
    g = lambda x: abs(x - 0.3) + 0.05  # noqa: E731
    assert run_search(g, None, 0.0, clip_tol=0.1)[1] is False  # misses by 0.05 < clip_tol
    assert run_search(g, None, 0.0, clip_tol=0.01)[1] is True
    x, clipped, _ = run_search(lambda x: x - 1.0, lambda x: 1.0, 0.25, max_step=0.0)
    assert (x, clipped) == (0.25, True)
    st_ = np.zeros(SEARCH_SIZE)
    assert search_start(st_, np.array([0.7, 0.9]), 1, 0.0, LO, HI, np.inf, N_GRID, 1e-12, 1e-12) == 0.9
    assert search_done(st_) and not search_clipped(st_)
