"""The root search of every causal inverse (models/inverse.py describes it): at one sample,
walk outward from the previous input to the first sign change of g(u) = y(u) - y_d, refine
the bracket by safeguarded Newton (secant steps where the model gives no dy/du) or bisection,
or, with no sign change, take the nearest output the walk visited and say the sample clipped.
"""

from __future__ import annotations

import numpy as np
from numba import njit

NEWTON_ITERATIONS = 80

# A reverse-communication search: the model's inversion kernel evaluates g = y(x) - y_d at
# the x the search asks for and hands (g, dy/du) back, until the search is done. So one
# jitted search serves every model's own (cached) kernel without passing functions.
(S_PHASE, S_X, S_RESULT, S_CLIPPED, S_START, S_LO, S_HI, S_H, S_TOL, S_CLIP_TOL, S_BEST_U, S_BEST_G, S_UP_X,
 S_UP_G, S_DN_X, S_DN_G, S_UP_DONE, S_DN_DONE, S_J, S_SIDE, S_XA, S_GA, S_XB, S_GB, S_G_PREV, S_ITER, S_NO_DY, S_XL,
 S_GL) = range(29)
SEARCH_SIZE = 29
PH_START, PH_WALK, PH_REFINE, PH_DONE = 0.0, 1.0, 2.0, 3.0
NO_INPUT = np.zeros(0)  # u_given of a kernel that searches


@njit(cache=True, nogil=True)
def search_start(st, u_given, k, start, limit_lo, limit_hi, max_step, n_grid, tol, clip_tol):
    """Begin the search at sample k around the previous input ``start`` within the limits and
    +- max_step of it (walk step (limit_hi - limit_lo) / n_grid): returns the first x to
    evaluate. ``tol``: |g| that counts as a root; ``clip_tol``: where no sign change is found,
    the sample counts as clipped when the nearest output misses by more. With a non-empty
    ``u_given`` (a kernel run forward) the search is done at once with x = u_given[k]."""
    st[:] = 0.0
    if u_given.shape[0] > 0:
        return _finish(st, u_given[k], False)
    st[S_PHASE] = PH_START
    st[S_START], st[S_H], st[S_TOL], st[S_CLIP_TOL] = start, (limit_hi - limit_lo) / n_grid, tol, clip_tol
    st[S_LO], st[S_HI] = max(limit_lo, start - max_step), min(limit_hi, start + max_step)
    st[S_X] = start
    return start


@njit(cache=True, nogil=True)
def search_done(st):
    return st[S_PHASE] == PH_DONE


@njit(cache=True, nogil=True)
def search_clipped(st):
    return st[S_CLIPPED] != 0.0


@njit(cache=True, nogil=True)
def _finish(st, x, clipped):
    st[S_RESULT] = x
    st[S_CLIPPED] = 1.0 if clipped else 0.0
    st[S_PHASE] = PH_DONE
    st[S_X] = x
    return x


@njit(cache=True, nogil=True)
def _walk_next(st):
    """The next point of the outward walk (up, down, alternately), or the end of the search."""
    while True:
        up_done, dn_done = st[S_UP_DONE] != 0.0, st[S_DN_DONE] != 0.0
        if up_done and dn_done:
            return _finish(st, st[S_BEST_U], st[S_BEST_G] > st[S_CLIP_TOL])
        if st[S_SIDE] >= 2.0:
            st[S_SIDE] = 0.0
            st[S_J] += 1.0
        side = st[S_SIDE]
        if (side == 0.0 and up_done) or (side == 1.0 and dn_done):
            st[S_SIDE] = side + 1.0
            continue
        step = st[S_J] * st[S_H]
        x = min(st[S_START] + step, st[S_HI]) if side == 0.0 else max(st[S_START] - step, st[S_LO])
        st[S_X] = x
        return x


@njit(cache=True, nogil=True)
def search_next(st, g, dy):
    """Hand back g(x) (and dy/du at x; NaN where the model gives none: secant steps) for the x the
    search asked for; returns the next x (the result once ``search_done``)."""
    x = st[S_X]
    tol = st[S_TOL]
    phase = st[S_PHASE]
    if phase == PH_START:
        st[S_NO_DY] = 1.0 if dy != dy else 0.0  # the model gives no dy/du: secant steps
        st[S_BEST_U], st[S_BEST_G] = x, abs(g)
        if abs(g) <= tol:
            return _finish(st, x, False)
        st[S_UP_X], st[S_UP_G], st[S_DN_X], st[S_DN_G] = x, g, x, g
        st[S_UP_DONE] = 1.0 if x >= st[S_HI] else 0.0
        st[S_DN_DONE] = 1.0 if x <= st[S_LO] else 0.0
        st[S_J], st[S_SIDE], st[S_PHASE] = 1.0, 0.0, PH_WALK
        return _walk_next(st)
    if phase == PH_WALK:
        if abs(g) < st[S_BEST_G]:
            st[S_BEST_U], st[S_BEST_G] = x, abs(g)
        up = st[S_SIDE] == 0.0
        px, pg = (st[S_UP_X], st[S_UP_G]) if up else (st[S_DN_X], st[S_DN_G])
        if abs(g) <= tol:
            return _finish(st, x, False)
        if (g > 0) != (pg > 0):  # a bracket: refine from its better end (evaluated again, for dy/du)
            st[S_XA], st[S_GA], st[S_XB], st[S_GB] = px, pg, x, g
            st[S_G_PREV], st[S_ITER], st[S_PHASE] = np.inf, 0.0, PH_REFINE
            if st[S_NO_DY] != 0.0:  # no dy/du to fetch: the first secant step through the bracket at once
                st[S_XL], st[S_GL] = px, pg
                st[S_X] = x - g * (x - px) / (g - pg)
            else:
                st[S_X] = px if abs(pg) < abs(g) else x
            return st[S_X]
        if up:
            st[S_UP_X], st[S_UP_G], st[S_UP_DONE] = x, g, 1.0 if x >= st[S_HI] else 0.0
        else:
            st[S_DN_X], st[S_DN_G], st[S_DN_DONE] = x, g, 1.0 if x <= st[S_LO] else 0.0
        st[S_SIDE] += 1.0
        return _walk_next(st)
    # PH_REFINE: safeguarded Newton (secant without dy/du) on the bracket [xa, xb]: a step is
    # taken when it stays inside the bracket and the previous one at least halved |g|, else bisection
    xa, ga, xb, gb = st[S_XA], st[S_GA], st[S_XB], st[S_GB]
    if abs(g) <= tol:
        return _finish(st, x, False)
    if (g > 0) == (ga > 0):
        xa, ga = x, g
    else:
        xb, gb = x, g
    st[S_XA], st[S_GA], st[S_XB], st[S_GB] = xa, ga, xb, gb
    lo, hi = min(xa, xb), max(xa, xb)
    if hi - lo <= 1e-15 * (abs(lo) + abs(hi) + 1e-300):
        return _finish(st, xa if abs(ga) < abs(gb) else xb, False)
    if dy != dy:  # NaN: secant through the last two evaluations
        xn = x - g * (x - st[S_XL]) / (g - st[S_GL]) if g != st[S_GL] else 0.5 * (lo + hi)
        st[S_XL], st[S_GL] = x, g
    else:
        xn = x - g / dy if dy != 0.0 else 0.5 * (lo + hi)
    x_next = xn if (lo < xn < hi and abs(g) <= 0.5 * st[S_G_PREV]) else 0.5 * (lo + hi)
    st[S_G_PREV] = abs(g)
    st[S_ITER] += 1.0
    if st[S_ITER] >= NEWTON_ITERATIONS:
        return _finish(st, xa if abs(ga) < abs(gb) else xb, False)
    st[S_X] = x_next
    return x_next
