"""Library screen: sparse regression (pysindy FROLS) of the null's residual on each cause's candidate terms
(``Cause.library_terms``), made orthogonal to the base's regressors; evidence and start values only.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pysindy as ps

from hysbench.identification.criteria import bic
from hysbench.identification.linear import scaled_lstsq

from .causes import CAUSES
from .residuals import RecordResidual


def library_screen(screen, residuals: Sequence[RecordResidual], max_terms: int = 8) -> dict:
    """FROLS's forward path cut where BIC is lowest: {"terms", "groups" (share explained per cause),
    "relaxation_taus" (the kept low-pass terms' time constants), ...}."""
    null_theta = np.array([screen.null.params[n] for n in screen.base_lin])
    bc = screen.base_columns(screen.base_nl, full=True)
    y_hat_rows = np.concatenate([rows @ null_theta for rows in bc.rows])
    terms = [(kind.name, t) for kind in CAUSES.values() if (t := kind.library_terms(screen, y_hat_rows)) is not None]
    blocks = []
    for m, p in enumerate(screen.parts):
        r = p.record
        y_hat = np.column_stack([bc.full[m][c] for c in screen.base_lin]) @ null_theta
        t = np.arange(r.t.size) * r.dt
        cols = [col for _, (_, columns, _) in terms for col in columns(r, y_hat, t)]
        blocks.append(np.stack([c[p.rows] for c in cols], axis=1))
    names = [n for _, (group_names, _, _) in terms for n in group_names]
    groups = [g for g, (group_names, _, _) in terms for _ in group_names]
    tau_of = [tau for _, (_, _, taus) in terms for tau in taus]
    Theta = np.concatenate(blocks)
    # orthogonal to the base model's regressors, unit norm
    A = np.concatenate(bc.rows)
    Theta = Theta - A @ scaled_lstsq(A, Theta, rcond=1e-10)
    norms = np.sqrt(np.einsum("ij,ij->j", Theta, Theta))
    keep = norms > 1e-9 * max(float(norms.max()), 1e-300)
    Theta = Theta[:, keep] / norms[keep]
    names, groups, tau_of = ([v for v, k in zip(column, keep) if k] for column in (names, groups, tau_of))
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

