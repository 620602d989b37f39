"""What the numbers say: AIC/BIC (with the effective sample size), paired comparisons, verdicts."""

from __future__ import annotations

import math

import numpy as np

from hysbench.data.dataset import Dataset
from hysbench.identification.criteria import aic, ar1_information_ratio, bic

from .plan import TIE_RELATIVE, Variant

def _summarise(rows: list[dict], dataset: Dataset, reference: Variant) -> None:
    """Aggregate scores, AIC/BIC and their autocorrelation-aware forms, in place."""
    ref = next(r for r in rows if r["reference"])
    neff = sum(n_m * ar1_information_ratio(rho) for (n_m, _), rho in zip(ref["id_weights"], ref["residual_lag1"].values()))
    for row in rows:
        recs = row["records"]
        for role in ("identification", "validation"):
            sel = [s for s in recs if s["role"] == role]
            row[f"{role}_e_rms"] = float(np.mean([s["e_rms"] for s in sel])) if sel else None
            row[f"{role}_e_m"] = float(max(s["e_m"] for s in sel)) if sel else None
        folds = row.get("cv_folds")
        if folds:
            row["cv_e_rms"] = float(np.mean([f["e_rms"] for f in folds]))
            row["cv_e_rms_worst"] = float(max(f["e_rms"] for f in folds))
            row["cv_e_m"] = float(max(f["e_m"] for f in folds))
        else:
            row["cv_e_rms"] = row["cv_e_rms_worst"] = row["cv_e_m"] = None
        n = row["n_scored"]
        f = row["fitness"]
        k = row["n_params"] + 1
        const = -sum(n_m * math.log(k_m / n_m) for n_m, k_m in row["id_weights"] if k_m > 0)  # eq. 9's weights
        row["aic"] = aic(f, n, k, constant=const)
        row["bic"] = bic(f, n, k, constant=const)
        row["n_effective"] = neff
        row["aic_effective"] = aic(f, n, k, n_effective=neff, constant=const)
        row["bic_effective"] = bic(f, n, k, n_effective=neff, constant=const)
    for key in ("aic", "bic", "aic_effective", "bic_effective"):
        best = min(r[key] for r in rows)
        for r in rows:
            r[f"delta_{key}"] = r[key] - best


def compare(a: dict, b: dict) -> dict:
    """Paired comparison of two variants' cross-validation: d = b - a per frequency."""
    fa = {f["left_out"]: f["e_rms"] for f in a["cv_folds"]}
    fb = {f["left_out"]: f["e_rms"] for f in b["cv_folds"]}
    common = [k for k in fa if k in fb]
    d = np.array([fb[k] - fa[k] for k in common])
    mean = float(d.mean())
    se = float(d.std(ddof=1) / math.sqrt(d.size)) if d.size > 1 else 0.0
    margin = max(se, TIE_RELATIVE * min(a["cv_e_rms"], b["cv_e_rms"]))
    verdict = "worse" if mean > margin else "better" if mean < -margin else "tie"
    return {"mean": mean, "se": se, "margin": margin, "verdict": verdict,
            "n_worse": int(np.sum(d > 0)), "n": int(d.size)}


def _family(rows: list[dict], family: str) -> list[dict]:
    return [r for r in rows if family in r["families"] and r.get("cv_folds")]


def _smallest_adequate(rows: list[dict], key: str) -> tuple[dict, dict]:
    """(best by cv_e_rms, smallest ``key`` not worse than the best)."""
    best = min(rows, key=lambda r: r["cv_e_rms"])
    for r in sorted(rows, key=lambda r: r[key]):
        if r is best or compare(best, r)["verdict"] != "worse":
            return best, r
    return best, best


def verdicts(result: dict) -> dict:
    """The verdicts behind the conclusions, as data: for q_term and envelopes, what removing the part
    does to the cross-validated error ("worse", "better" or "tie"); for order and n_operators, the
    smallest value not worse than the best."""
    rows = result["variants"]
    ref = next(r for r in rows if r["reference"])
    out = {}
    if not ref.get("cv_folds"):
        return out
    for factor in ("q_term", "envelopes"):
        other = next((r for r in _family(rows, factor) if r[factor] != ref[factor]), None)
        if other is not None:
            with_it, without = (ref, other) if ref[factor] else (other, ref)
            out[factor] = {"without": compare(with_it, without)["verdict"]}
    for factor in ("order", "n_operators"):
        fam = _family(rows, factor)
        if len(fam) >= 2:
            best, enough = _smallest_adequate(fam, factor)
            out[factor] = {"enough": enough[factor], "best": best[factor]}
    return out
