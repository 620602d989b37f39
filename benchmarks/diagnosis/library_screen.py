"""Library screen: sparse regression (pysindy FROLS) of the null's residual on candidate terms.

Evidence and start values only (the cause is chosen on held-out records):
first-order low-pass histories of the input on a grid of time constants,
the derivatives of the model's own output, slow exponential drifts, a
sinusoid at the pooled spectrum's peak, hinge functions of the model's output
at high and low levels -- each made orthogonal to the base model's
regressors and scaled to unit norm. The path is cut where BIC (with the
null residual's effective sample size) is lowest.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import pysindy as ps

from hysbench.identification.criteria import bic
from hysbench.identification.linear import scaled_lstsq
from hysbench.models.extended import CREEP_TIME_BOUNDS, TAU_BOUNDS
from hysbench.models.filter_kernels import first_order_foh, lowpass1_bank

from .candidates import prominence
from .residuals import RecordResidual, coherent_spectrum, spectral_peaks


def library_screen(screen, residuals: Sequence[RecordResidual], max_terms: int = 8,
                   n_taus: int = 10) -> dict:
    """Sparse regression (pysindy FROLS) of the null's residual on a library of candidate terms.

    Forward orthogonal least squares adds one term at a time, the one that
    explains most of what is left; the path is cut where BIC is lowest.
    Returns {"terms": [{name, group, explained, order}], "groups": {cause: share of the null's
    residual sum of squares explained}, "relaxation_taus": [time constants of kept low-pass terms]}.
    """
    T = screen.drive_time
    taus = np.exp(np.linspace(math.log(TAU_BOUNDS[0] * T * 5), math.log(TAU_BOUNDS[1] * T / 5), n_taus))
    creeps = np.exp(np.linspace(math.log(screen.creep_min), math.log(CREEP_TIME_BOUNDS[1] * T / 10), 5))
    null_theta = np.array([screen.null.params[n] for n in screen.base_lin])
    bc = screen.base_columns(screen.base_nl, full=True)
    # an interference candidate frequency: the pooled coherent spectrum's peak
    dt = max(p.record.dt for p in screen.parts)  # below every record's Nyquist frequency
    f, amp = coherent_spectrum(screen.null_residuals(), 1.0 / T, 0.45 / dt)
    peak = spectral_peaks(f, prominence(amp), n=1)
    names, groups, blocks = [], [], []
    y_hat_rows = np.concatenate([rows @ null_theta for rows in bc.rows])
    q_hi = np.quantile(y_hat_rows, [0.90, 0.97])
    q_lo = np.quantile(y_hat_rows, [0.03, 0.10])
    for m, p in enumerate(screen.parts):
        r = p.record
        n = r.t.size
        y_hat = np.column_stack([bc.full[m][c] for c in screen.base_lin]) @ null_theta
        dy = np.gradient(y_hat, r.dt)
        ddy = np.gradient(dy, r.dt)
        a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(float(t), r.dt) for t in taus)))
        lp = lowpass1_bank(np.ascontiguousarray(r.u), a, b0, b1)
        tt = np.arange(n) * r.dt
        cols = [lp[j] for j in range(len(taus))] + [dy, ddy] + [-np.expm1(-tt / c) for c in creeps]
        if peak:
            cols += [np.sin(2 * np.pi * peak[0][0] * tt), np.cos(2 * np.pi * peak[0][0] * tt)]
        cols += [np.maximum(y_hat - L, 0.0) for L in q_hi] + [np.maximum(L - y_hat, 0.0) for L in q_lo]
        blocks.append(np.stack([c[p.rows] for c in cols], axis=1))
    names = ([f"L_{t:.3g}s[u]" for t in taus] + ["d/dt y_model", "d2/dt2 y_model"]
             + [f"1-exp(-t/{c:.3g}s)" for c in creeps]
             + ([f"sin {peak[0][0]:.4g}Hz", f"cos {peak[0][0]:.4g}Hz"] if peak else [])
             + [f"max(y_model-{L:.3g},0)" for L in q_hi] + [f"max({L:.3g}-y_model,0)" for L in q_lo])
    tau_of = [float(t) for t in taus] + [None] * (len(names) - len(taus))
    groups = (["relaxation"] * len(taus) + ["delay", "resonance"] + ["creep"] * len(creeps)
              + (["interference"] * 2 if peak else []) + ["saturation"] * 4)
    Theta = np.concatenate(blocks)
    # orthogonal to the base model's regressors, unit norm
    A = np.concatenate(bc.rows)
    Theta = Theta - A @ scaled_lstsq(A, Theta, rcond=1e-10)
    norms = np.sqrt(np.einsum("ij,ij->j", Theta, Theta))
    keep = norms > 1e-9 * max(float(norms.max()), 1e-300)
    Theta = Theta[:, keep] / norms[keep]
    names = [n for n, k in zip(names, keep) if k]
    groups = [g for g, k in zip(groups, keep) if k]
    tau_of = [t for t, k in zip(tau_of, keep) if k]
    target = screen.null_residual
    opt = ps.FROLS(max_iter=min(max_terms, Theta.shape[1]), alpha=1e-10, normalize_columns=False, unbias=True)
    opt.fit(Theta, target)
    # choose the number of terms by BIC along FROLS's forward path
    n = target.size
    path = [np.asarray(h, dtype=float).reshape(-1) for h in opt.history_]
    rss_path = [float(np.sum((target - Theta @ h) ** 2)) for h in path]
    bics = [bic(max(r, 1e-300), n, int(np.count_nonzero(h)), screen.n_effective) for r, h in zip(rss_path, path)]
    best = int(np.argmin(bics))
    total = rss_path[0] if rss_path else float(target @ target)
    terms, explained_by = [], {g: 0.0 for g in dict.fromkeys(groups)}
    for k in range(1, best + 1):
        new = [j for j in np.flatnonzero(path[k]) if path[k - 1][j] == 0.0]
        share = (rss_path[k - 1] - rss_path[k]) / total if total > 0 else 0.0
        for j in new:
            terms.append({"name": names[j], "group": groups[j], "explained": share / len(new), "order": k})
            explained_by[groups[j]] += share / len(new)
    kept = np.flatnonzero(path[best]) if path else []
    kept_taus = [tau_of[j] for j in kept if tau_of[j] is not None]
    return {"method": "pysindy FROLS (forward orthogonal least squares), number of terms by BIC (effective sample size)",
            "terms": terms, "groups": explained_by,
            "explained_total": float(1.0 - rss_path[best] / total) if total > 0 else 0.0,
            "relaxation_taus": kept_taus, "n_library": len(names), "n_terms": int(best)}

