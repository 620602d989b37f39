"""Held-out scores: leave one identification record out on the screen's rows, a candidate's linear parameters
solved on the other records (finalists' own nonlinear parameters refitted per fold too: their spread is the
jackknife uncertainty), the base alone refitted the same way. From the out-of-fold residuals e (``score``): the
gain G = 1 - sum e_c^2 / sum e_null^2, z (one-sided Wilcoxon signed-rank test of ln(SSE_null / SSE_c) over
``n_blocks`` contiguous blocks per left-out record, so correlated residuals are not counted as independent) and
the records improved. A record whose input leaves the others' range is scored up to there (``held_out_windows``).
"""

from __future__ import annotations

import math
from dataclasses import InitVar, dataclass
from typing import Callable, Sequence

import numpy as np
from scipy import stats

from .candidates import Candidate, is_log, own_nonlinear
from .cause import cause_of_parameter
from .policy import Policy

FOLD_NFEV = 8  # iterations of a fold's refit of a candidate's own nonlinear parameters (numerics)


@dataclass
class Folds:
    """Leave-one-record-out on the screen's stacked rows (fold m leaves record m out). Only a record's first
    ``scored[m]`` rows are held-out targets (``Screen.scored_rows``; None: every row): its out-of-fold residual
    after them (``tail``) is set to zero, so every sum, block and count covers the scored rows alone.
    ``policy``: the screen's."""
    starts: np.ndarray  # row offsets of the records, len M + 1
    scored: tuple | None = None  # per record: its scored rows, from its start (None: every row)
    policy: Policy = Policy()

    @classmethod
    def of(cls, screen) -> "Folds":
        return cls(np.cumsum([0] + [p.rows.size for p in screen.parts]), tuple(screen.scored_rows), screen.policy)

    @property
    def n(self) -> int:
        return self.starts.size - 1

    def is_scored(self, m: int) -> bool:
        return self.scored is None or self.scored[m] > 0

    def head(self, m: int) -> slice:
        """Record m's scored rows."""
        end = self.starts[m + 1] if self.scored is None else self.starts[m] + self.scored[m]
        return slice(int(self.starts[m]), int(end))

    def tail(self, m: int) -> slice:
        """Record m's rows after its scored ones (empty if all are scored)."""
        return slice(self.head(m).stop, int(self.starts[m + 1]))

    @property
    def n_scored(self) -> int:
        return sum(self.is_scored(m) for m in range(self.n))

    def test(self, m: int) -> np.ndarray:
        mask = np.zeros(self.starts[-1], dtype=bool)
        mask[self.starts[m]:self.starts[m + 1]] = True
        return mask

    def blocks(self) -> list[np.ndarray]:
        out = []
        for m in range(self.n):
            if self.is_scored(m):
                h = self.head(m)
                out += [b for b in np.array_split(np.arange(h.start, h.stop), self.policy.n_blocks) if b.size]
        return out

    def without(self, m: int) -> "Folds":
        """The folds with record m's rows taken out (to score arrays indexed by ``~self.test(m)``)."""
        sizes = [int(self.starts[k + 1] - self.starts[k]) for k in range(self.n) if k != m]
        scored = None if self.scored is None else tuple(s for k, s in enumerate(self.scored) if k != m)
        return Folds(np.cumsum([0] + sizes), scored, self.policy)


@dataclass
class HeldOut:
    """The out-of-fold residuals (``out_of_fold``) of the base alone (``null``) and of every candidate scored
    (``add``; ``of``)."""
    folds: Folds
    null: np.ndarray
    scored: InitVar[Sequence[tuple]] = ()  # (candidate, its out-of-fold residuals)

    def __post_init__(self, scored):
        self._by = {}  # id -> (candidate, residuals): the candidate is held, so its id stays its own
        for c, e in scored:
            self.add(c, e)

    def add(self, c: Candidate, e: np.ndarray) -> None:
        self._by[id(c)] = (c, e)

    def __contains__(self, c: Candidate) -> bool:
        return self._by.get(id(c), (None,))[0] is c

    def of(self, c: Candidate) -> np.ndarray:
        if c not in self:
            raise KeyError(f"{c.label} has no held-out score")
        return self._by[id(c)][1]


def out_of_fold(screen, folds: Folds, design: Callable[[int], np.ndarray],
                train_residuals: list | None = None) -> np.ndarray:
    """Every row's residual from a linear solve on the other records (``design(m)``: fold m's stacked design);
    ``train_residuals`` receives, per fold, that solve's residual on its training rows."""
    e = np.zeros(screen.n)
    for m in range(folds.n):
        test = folds.test(m)
        A = design(m)
        theta, res = screen.solve(A[~test], screen.y[~test])
        e[test] = screen.y[test] - A[test] @ theta
        e[folds.tail(m)] = 0.0
        if train_residuals is not None:
            train_residuals.append(res)
    return e


def heldout_null(screen, folds: Folds, train_residuals: list | None = None) -> np.ndarray:
    A = screen.design(screen.base, screen.base_nl)
    return out_of_fold(screen, folds, lambda m: A, train_residuals)


def heldout_errors(screen, folds: Folds, c: Candidate, refit: bool = False,
                   train_residuals: list | None = None, only: Sequence[str] | None = None,
                   designs: list | None = None) -> tuple[np.ndarray, list[dict]]:
    """Out-of-fold residuals of a candidate; with ``refit`` its own nonlinear parameters (``only`` these, if
    given) are refitted on each fold's training rows (returns the fold estimates too). ``train_residuals``: a
    list that receives, per fold, the fit's residual on its training rows; ``designs``: one that receives, per
    fold, the stacked design it was solved with (not for a clip or an interference: not linear)."""
    special = c.kind.heldout_errors(screen, folds, c, refit, train_residuals)
    if special is not None:  # not linear (a clip) or a line on top (a disturbance)
        return special
    nl = {n: c.params[n] for n in c.model.nonlinear_names}
    names = [n for n in own_nonlinear(screen, c) if only is None or n in only] if refit else []
    fold_est, fold_nl = [], []
    for m in range(folds.n):
        z = dict(nl)
        if names:
            train, others = ~folds.test(m), [k for k in range(folds.n) if k != m]

            def residual(q, train=train, others=others):  # C order, as rows picked from the whole design: same rounding
                A = np.ascontiguousarray(screen.design(c.model, q, parts=others))
                return screen.solve(A, screen.y[train])[1]

            alone = cause_of_parameter(names[0]) if len(names) == 1 else None  # e.g. a delay: scanned
            scanned = alone and alone.refit_alone(screen, c.model, z, lambda q: float(np.sum(residual(q) ** 2)))
            z = scanned or screen.refine(c.model, z, [(n, is_log(n)) for n in names], max_nfev=FOLD_NFEV,
                                         residual=residual)
            fold_est.append({n: float(z[n]) for n in names})
        fold_nl.append(z)
    mats = [screen.design(c.model, z) for z in fold_nl] if names else [screen.design(c.model, nl)] * folds.n
    if designs is not None:
        designs.extend(mats)
    return out_of_fold(screen, folds, lambda m: mats[m], train_residuals), fold_est


def signed_rank_z(d: np.ndarray) -> float:
    """One-sided Wilcoxon signed-rank test that the log ratios exceed 0, as a normal quantile."""
    d = d[np.isfinite(d) & (d != 0)]
    if d.size < 2:
        return 0.0
    p = stats.wilcoxon(d, alternative="greater").pvalue
    return float(np.clip(stats.norm.isf(max(p, 1e-300)), -40.0, 40.0))  # p = 1 (every block worse): -40, not -inf


def score(folds: Folds, e_ref: np.ndarray, e_c: np.ndarray) -> dict:
    """Held-out gain of ``e_c`` over ``e_ref``, its block z-score (log ratios) and the folds it improves."""
    blocks = folds.blocks()
    tiny = 1e-300
    d = np.array([math.log(max(float(e_ref[b] @ e_ref[b]), tiny) / max(float(e_c[b] @ e_c[b]), tiny)) for b in blocks])
    ss_ref = float(e_ref @ e_ref)
    improved = sum(float(e_ref[folds.test(m)] @ e_ref[folds.test(m)]) > float(e_c[folds.test(m)] @ e_c[folds.test(m)])
                   for m in range(folds.n) if folds.is_scored(m))
    return {"gain": 1.0 - float(e_c @ e_c) / ss_ref if ss_ref > 0 else 0.0, "z": signed_rank_z(d),
            "folds_improved": int(improved), "n_folds": folds.n_scored, "sse": float(e_c @ e_c)}


def fold_uncertainty(screen, fold_estimates: list[dict]) -> dict:
    """Jackknife standard error of each fold-refitted parameter (log-scale ones as relative errors); a clipping
    level, which has no natural zero, also as its spread over the output's range."""
    out = {}
    if len(fold_estimates) < 2:
        return out
    m = len(fold_estimates)
    for name in fold_estimates[0]:
        v = np.array([f[name] for f in fold_estimates], dtype=float)
        log = is_log(name) and np.all(v > 0)
        x = np.log(v) if log else v
        se = float(math.sqrt((m - 1) / m * np.sum((x - x.mean()) ** 2)))
        out[name] = {"relative_se": se} if log else {"se": se}
        out[name]["folds"] = [float(a) for a in v]
        owner = cause_of_parameter(name)
        if owner is not None and name in owner.relative_to_range:
            out[name]["se_over_range"] = out[name]["se"] / max(float(np.ptp(screen.y)), 1e-300)
    return out


def passes(c: Candidate, policy: Policy) -> bool:
    """Held-out evidence, within the cause's meaning and off the search bounds."""
    return evidence(c.heldout, policy) and not c.limit and not c.heldout.get("at_bound")


def evidence(h: dict, policy: Policy) -> bool:
    """A held-out score (``score``) is evidence: gain >= ``min_explained`` in a majority of folds, and z >=
    ``z_pass`` or a gain >= ``strong_gain`` in every fold; or any gain for an interference found at one frequency
    and amplitude on each fold's other records (``same_line``) that improves every held-out record with z >=
    ``z_pass`` (specific by itself, however small its gain)."""
    return bool(h) and ((bool(h.get("same_line")) and _improves_every_fold(h, policy)) or (
        h["gain"] >= policy.min_explained and h["folds_improved"] * 2 > h["n_folds"] and (
            h["z"] >= policy.z_pass or (h["gain"] >= policy.strong_gain and h["folds_improved"] == h["n_folds"]))))


def line_worth_refit(c: Candidate, policy: Policy) -> bool:
    """An interference whose quick score (frequency from every record) could become evidence as one line."""
    return (c.kind.disturbance and not c.limit and bool(c.heldout)
            and _improves_every_fold(c.heldout, policy))


def _improves_every_fold(h: dict, policy: Policy) -> bool:
    return h["gain"] > 0 and h["z"] >= policy.z_pass and h["folds_improved"] == h["n_folds"]


def promising(c: Candidate, policy: Policy) -> bool:
    """Worth refining (stage 2): some held-out gain, in a majority of folds, whatever its z."""
    h = c.heldout
    return bool(h) and h["gain"] >= policy.min_explained and h["folds_improved"] * 2 > h["n_folds"] and not c.limit


def pairwise_z(held: HeldOut, a: Candidate, b: Candidate) -> float:
    """How many standard errors b's held-out squared error exceeds a's (positive: a is better)."""
    return score(held.folds, held.of(b), held.of(a))["z"]


def share_of_misfit(screen, reference_sse: float, sse: float) -> float:
    """The share of a reference's held-out misfit beyond white noise (n sd^2, n the held-out rows) that a
    candidate removes (1 if the reference leaves nothing beyond noise)."""
    excess = reference_sse - screen.n_held_out_rows * screen.noise_sd**2
    return float((reference_sse - sse) / excess) if excess > 0 else 1.0


def carried_by_one_record(folds: Folds, e_null: np.ndarray, e_c: np.ndarray) -> bool:
    """Whether a held-out gain is evidence only through the one record it improves most (without that record's
    rows it is none); with fewer than ``min_records_check`` records it counts as it is."""
    if folds.n_scored < folds.policy.min_records_check:
        return False
    gain = [float(e_null[folds.test(m)] @ e_null[folds.test(m)] - e_c[folds.test(m)] @ e_c[folds.test(m)])
            if folds.is_scored(m) else -math.inf for m in range(folds.n)]
    best = int(np.argmax(gain))
    keep = ~folds.test(best)
    return not evidence(score(folds.without(best), e_null[keep], e_c[keep]), folds.policy)


def beyond_others(inputs: Sequence[np.ndarray]) -> list[float]:
    """How far each record's input goes beyond the range of the other records' inputs (either end), as a share
    of the span of them all (0 if within)."""
    if len(inputs) < 2:
        return [0.0] * len(inputs)
    lo, hi = [float(np.min(u)) for u in inputs], [float(np.max(u)) for u in inputs]
    span = max(hi) - min(lo)
    if not span > 0:
        return [0.0] * len(inputs)
    out = []
    for m in range(len(inputs)):
        other_lo = min(v for k, v in enumerate(lo) if k != m)
        other_hi = max(v for k, v in enumerate(hi) if k != m)
        out.append(max(hi[m] - other_hi, other_lo - lo[m], 0.0) / span)
    return out


def held_out_windows(inputs: Sequence[np.ndarray], beyond_range: float) -> list[int]:
    """How many samples of each record, from its start, the held-out test predicts (``Folds``): all of a record whose
    input stays within the other records' range (to ``beyond_range`` of the span), else those before it first leaves it
    (fitted on the others, the base would extrapolate there). All if fewer than two stay within."""
    sizes = [int(u.size) for u in inputs]
    beyond = beyond_others(inputs)
    if sum(b <= beyond_range for b in beyond) < 2:
        return sizes
    lo, hi = [float(np.min(u)) for u in inputs], [float(np.max(u)) for u in inputs]
    margin = beyond_range * (max(hi) - min(lo))
    out = []
    for m, u in enumerate(inputs):
        others = [j for j in range(len(inputs)) if j != m]
        low, high = min(lo[j] for j in others) - margin, max(hi[j] for j in others) + margin
        outside = np.flatnonzero((u > high) | (u < low)) if beyond[m] > beyond_range else []
        out.append(int(outside[0]) if len(outside) else sizes[m])
    return out
