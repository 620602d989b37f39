"""Numba kernels for play operators: the time loops of every P-I type model.

One-sided play operator (paper eq. 3-4 and 6-7), with envelopes h_l, h_r:

    W_i(0) = max(h_l(0) - r_i, min(h_r(0), w0))
    W_i(k) = max(h_l(k) - r_i, min(h_r(k), W_i(k-1)))

The classical operator is the case h_l = h_r = u. The rate-dependent operator
of MRPIM uses h_l = u - gamma |du/dt|, h_r = u + lambda |du/dt| (eq. 7).

All kernels are compiled with ``cache=True`` so that a second process loads
the machine code instead of recompiling it.
"""

from __future__ import annotations

import os

# numba's OpenMP layer spins in its barriers by default; on a shared, busy
# machine that costs milliseconds per parallel region. Passive waiting costs
# microseconds. Only effective before the first parallel kernel runs.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402
from numba import njit, prange  # noqa: E402

# Fast-math without reassociation or contraction (FMA): those let LLVM round differently depending on
# where a kernel is inlined, so a kernel compiled in this process and the same kernel loaded from
# numba's cache gave different last bits (tests/test_bitwise_reproducible.py).
KERNEL_FASTMATH = {"nnan", "ninf", "nsz", "arcp", "afn"}
PLAY_PAD = 16  # the batch kernel pads its plays to a multiple of this (padding plays are not summed)


_EXPONENT = np.uint64(0x7FF0000000000000)  # all exponent bits set: inf or NaN


@njit(cache=True, nogil=True)
def all_finite(x):
    """Whether a contiguous 1-D float64 array holds no NaN or inf: an integer test of the exponent
    bits, which vectorises (about 4x faster than ``np.isfinite(x).all()`` on long records)."""
    bits = x.view(np.uint64)
    top = np.uint64(0)
    for k in range(bits.shape[0]):
        top = max(top, bits[k] & _EXPONENT)
    return top != _EXPONENT


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def play_update(w, lower, upper):
    """One sample of a play operator: its previous output w clamped into the band
    [lower, upper], the lower edge winning when the band is empty (eq. 6:
    max(h_l - r, min(h_r, w))). The one home of the play update: every forward,
    step and inverse kernel of the P-I family calls it."""
    v = min(upper, w)
    return v if v > lower else lower


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def play_operators(h_left, h_right, thresholds, w0):
    """Outputs of N play operators, shape (T, N)."""
    n_t = h_left.shape[0]
    n_op = thresholds.shape[0]
    out = np.empty((n_t, n_op))
    w = np.empty(n_op)
    for i in range(n_op):
        w[i] = w0
    for k in range(n_t):
        hl = h_left[k]
        hr = h_right[k]
        for i in range(n_op):
            v = play_update(w[i], hl - thresholds[i], hr)
            w[i] = v
            out[k, i] = v
    return out


@njit(cache=True, fastmath=KERNEL_FASTMATH, nogil=True)
def _pi_output(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, out):
    """out[k] = sum_j poly[j-1] u^j + q u''(k) + offset + sum_i weights[i] W_i(k).

    With ``backward`` the derivatives are the backward differences computed
    here (input held at u(0) before the record); otherwise they are read from
    ``abs_du`` (|u'|) and ``ddu`` (u''). The whole record: the window kernel from 0.
    """
    _pi_output_window(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, 0, out)


@njit(cache=True)
def pi_output(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0):
    """Output of a P-I type model for one parameter set, shape (T,)."""
    out = np.empty(u.shape[0])
    _pi_output(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, out)
    return out


@njit(cache=True, parallel=True)
def pi_output_batch(u, dt, backward, abs_du, ddu, gammas, lams, thresholds, weights, polys, qs, offsets, w0):
    """Many parameter sets at once, in parallel over sets; returns (B, T).

    gammas, lams, qs, offsets: (B,); weights: (B, N); polys: (B, K).
    """
    n_set = gammas.shape[0]
    out = np.empty((n_set, u.shape[0]))
    for b in prange(n_set):
        _pi_output(
            u, dt, backward, abs_du, ddu, gammas[b], lams[b], thresholds, weights[b], polys[b], qs[b], offsets[b], w0,
            out[b],
        )
    return out


@njit(cache=True, fastmath=KERNEL_FASTMATH, nogil=True)
def _play_window(u, dt, backward, abs_du, gamma, lam, thresholds, w0, start, rows, out):
    """Play operators run from sample 0; stored transposed in out (N, n): rows [start, start + n)
    when ``rows`` is empty, else the samples ``rows`` (sorted, distinct; ``start`` unused)."""
    n_op = thresholds.shape[0]
    n_out = out.shape[1]
    picked = rows.shape[0] > 0
    stop = rows[n_out - 1] + 1 if picked else start + n_out
    w = np.empty(n_op)
    for i in range(n_op):
        w[i] = w0
    u1 = u[0]
    inv_dt = 1.0 / dt
    j = 0
    for k in range(stop):
        uk = u[k]
        if backward:
            a_du = abs(uk - u1) * inv_dt
            u1 = uk
        else:
            a_du = abs_du[k]
        hl = uk - gamma * a_du
        hr = uk + lam * a_du
        for i in range(n_op):
            w[i] = play_update(w[i], hl - thresholds[i], hr)
        if picked:
            if k == rows[j]:
                for i in range(n_op):
                    out[i, j] = w[i]
                j += 1
        elif k >= start:
            for i in range(n_op):
                out[i, k - start] = w[i]


@njit(cache=True, nogil=True)
def play_operators_window(u, dt, backward, abs_du, gamma, lam, thresholds, w0, start, rows, out):
    """Play-operator outputs at rows [start, start + n) (``rows`` empty) or at the samples ``rows``,
    written transposed into out (N, n).

    The operators run from the first sample (their state needs the whole
    history) but only the requested rows are stored, which keeps the memory
    traffic of long records with a short scored window (or a sparse row
    subset) small; the transposed layout gives each regressor column
    contiguous memory. Envelopes as in ``_pi_output``: h_l = u - gamma |u'|,
    h_r = u + lam |u'| with |u'| the backward difference when ``backward``,
    else read from ``abs_du``.
    """
    _play_window(u, dt, backward, abs_du, gamma, lam, thresholds, w0, start, rows, out)


@njit(cache=True, parallel=True)
def play_operators_window_batch(u, dt, backward, abs_du, gammas, lams, thresholds, w0, start, rows, out):
    """``play_operators_window`` for many (gamma, lam) pairs in parallel; out (B, N, n)."""
    for b in prange(gammas.shape[0]):
        _play_window(u, dt, backward, abs_du, gammas[b], lams[b], thresholds, w0, start, rows, out[b])


@njit(cache=True, parallel=True)
def pi_output_window_batch(u, dt, backward, abs_du, ddu, gammas, lams, thresholds, weights, polys, qs, offsets, w0,
                           start, stop):
    """Samples [start, stop) of ``pi_output_batch`` (the model still runs from sample 0); (B, stop - start)."""
    n_set = gammas.shape[0]
    out = np.empty((n_set, stop - start))
    for b in prange(n_set):
        _pi_output_window(u, dt, backward, abs_du, ddu, gammas[b], lams[b], thresholds, weights[b], polys[b], qs[b],
                          offsets[b], w0, start, out[b])
    return out


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def backward_rates(u, u1, u2, first, inv_dt, inv_dt2):
    """(|u'|, sign(u'), u'') at a sample by backward differences from the two previous inputs;
    all zero at the first sample (the input held at u(0) before the record)."""
    if first:
        return 0.0, 0.0, 0.0
    du = u - u1
    return abs(du) * inv_dt, (1.0 if du > 0 else (-1.0 if du < 0 else 0.0)), (u - 2.0 * u1 + u2) * inv_dt2


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def horner_step(p, dp, c, u):
    """One Horner step of p(u) = sum_j c_j u^(j+1) (c from the top) and of its derivative dp."""
    t = p + c
    return t * u, dp * u + t


HORNER_STEPS = 4  # the batch kernel's polynomial takes this many steps without a loop (every order up to it)


@njit(nogil=True)
def horner_coefficients(poly):
    """poly from its top coefficient, led by zeros to at least HORNER_STEPS entries (``pi_sample``'s
    ``horner``). The leading zeros leave Horner's result as it was: after them p is +0.0 or -0.0 and
    dp +0.0, and the first real step's p + c equals the loop's 0.0 + c once a top coefficient -0.0
    is made +0.0 (here, without fast-math, which could drop that addition). Order 0: p is +0.0 or
    -0.0 where the loop gives +0.0, which the sum y = acc + p + q u'' + offset turns into the same
    output unless every term of it is a zero."""
    m = poly.shape[0]
    n = max(m, HORNER_STEPS)
    out = np.zeros(n)
    for j in range(m):
        out[n - 1 - j] = poly[j]
    if m > 0:
        out[n - m] = out[n - m] + 0.0
    return out


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def pi_sample(u, a, s, d2, first, u1, inv_dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
              fa, fb0, fb1, fpow, fw, commit, want_slope, upper_offsets=True, padded_weights=None, products=None,
              horner=None):
    """One sample of the P-I family's step structure (models/inverse.py): (y(k), dy/du).

    u: the input at this sample; a = |u'|, s = sign(u'), d2 = u'' (``backward_rates``, or a
    smoothed derivative's); u1 = u(k-1); the state w (plays), xf (filters) is that after
    sample k-1 and moves to sample k only when ``commit``. ``want_slope``: also dy/du (the
    inverse's Newton steps). With ``commit``, r_lo, r_hi and w may be longer than weights:
    padding plays that move but are not summed (the batch kernel's whole vectors).
    ``upper_offsets=False``: r_hi is all zero and not read (the one-sided plays of classical-pi
    and mrpim; the batch kernel's fast path, same result). ``products`` (with ``commit``, not
    ``want_slope``; the batch kernel): a scratch as long as r_lo, ``padded_weights`` the weights
    zero-padded to that length: the play loop also forms each weighted play there, vectorised with
    the plays, and the sum adds them in play order (the same products in the same order: the
    same result, in fewer instructions per sample). ``horner`` (the batch kernel):
    ``horner_coefficients(poly)``, whose first HORNER_STEPS steps run without a loop (same
    result). The one home of
    the P-I family's per-sample maths: the batch kernels, the inverse, the steppers call it, and
    the exported C (models/export_c.py) is generated from the same expressions in the same order."""
    acc = 0.0
    dy = 0.0
    n = weights.shape[0]
    if commit:
        # The plays move first, in a loop of their own (vectorised over the plays; r_lo may carry
        # padding plays, moved but never summed, that make it whole vectors); the sum below then
        # reads them: the same operations in the same order, fewer instructions per sample.
        for i in range(r_lo.shape[0]):
            upper = u + g_hi * a
            if upper_offsets:
                upper += r_hi[i]
            v = play_update(w[i], u - g_lo * a - r_lo[i], upper)
            w[i] = v
            if products is not None:
                products[i] = padded_weights[i] * v
    if products is not None:
        # Whole eights first, then the rest: the first loop has no remainder and the second, of
        # fewer than eight trips, unrolls (docs/deploying.md, Speed).
        n8 = n & ~7
        for i in range(n8):
            acc += products[i]
        for i in range(n8, n):
            acc += products[i]
        n = 0  # summed: the loop below makes no trip
    for i in range(n):
        lower = u - g_lo * a - r_lo[i]
        upper = u + g_hi * a
        if upper_offsets:
            upper += r_hi[i]
        v = w[i] if commit else play_update(w[i], lower, upper)
        acc += weights[i] * v
        if want_slope:
            if v == lower:
                dy += weights[i] * (1.0 - g_lo * s * inv_dt)
            elif v == upper:
                dy += weights[i] * (1.0 + g_hi * s * inv_dt)
    p = 0.0
    dp = 0.0
    if horner is not None:
        # a fixed count of steps (LLVM writes them out), then the rest of an order above HORNER_STEPS
        for j in range(HORNER_STEPS):
            p, dp = horner_step(p, dp, horner[j], u)
        for j in range(HORNER_STEPS, horner.shape[0]):
            p, dp = horner_step(p, dp, horner[j], u)
    else:
        for j in range(poly.shape[0] - 1, -1, -1):  # Horner: p = sum_j poly[j] u^(j+1), dp its derivative
            p, dp = horner_step(p, dp, poly[j], u)
    y = acc + p + q * d2 + base
    if want_slope:
        dy += dp
        if not first:
            dy += q * inv_dt * inv_dt
    for j in range(fa.shape[0]):
        x = 0.0
        if not first:
            pw = fpow[j]
            x = fa[j] * xf[j] + fb0[j] * u1**pw + fb1[j] * u**pw
            y += fw[j] * x
            if want_slope:
                dy += fw[j] * fb1[j] * pw * u ** (pw - 1)
        if commit:
            xf[j] = x
    return y, dy


@njit(cache=True, fastmath=KERNEL_FASTMATH, nogil=True)
def _pi_output_window(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, start, out):
    """``_pi_output`` storing only samples [start, start + out.size): ``pi_sample`` over the record."""
    n_op = thresholds.shape[0]
    stop = start + out.shape[0]
    n_pad = -(-n_op // PLAY_PAD) * PLAY_PAD  # whole vectors: no remainder loops in the play update
    r_lo = np.zeros(n_pad)
    r_lo[:n_op] = thresholds
    w = np.empty(n_pad)
    for i in range(n_pad):
        w[i] = w0
    r_hi = np.zeros(n_pad)
    padded_weights = np.zeros(n_pad)
    padded_weights[:n_op] = weights
    products = np.empty(n_pad)
    horner = horner_coefficients(poly)
    no_filter = np.zeros(0)
    no_power = np.zeros(0, dtype=np.int64)
    u1 = u[0]
    u2 = u[0]
    inv_dt = 1.0 / dt
    inv_dt2 = inv_dt * inv_dt
    for k in range(stop):
        uk = u[k]
        if backward:
            a_du, sgn, d2 = backward_rates(uk, u1, u2, k == 0, inv_dt, inv_dt2)
        else:
            a_du = abs_du[k]
            sgn = 0.0
            d2 = ddu[k]
        y, _ = pi_sample(uk, a_du, sgn, d2, k == 0, u1, inv_dt, offset, w, no_filter, r_lo, r_hi, gamma, lam,
                         weights, poly, q, no_filter, no_filter, no_filter, no_power, no_filter, True, False, False,
                         padded_weights, products, horner)
        u2 = u1
        u1 = uk
        if k >= start:
            out[k - start] = y


@njit(cache=True, nogil=True)
def pi_output_window(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, start, stop):
    """Samples [start, stop) of ``pi_output`` for one parameter set (no threads: safe to call concurrently)."""
    out = np.empty(stop - start)
    _pi_output_window(u, dt, backward, abs_du, ddu, gamma, lam, thresholds, weights, poly, q, offset, w0, start, out)
    return out
