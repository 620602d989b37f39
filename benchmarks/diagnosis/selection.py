"""Choosing the cause on records that took no part in fitting it.

Leave-one-identification-record-out on the screen's rows: for every fold
the linear parameters of a candidate (the many: the base model's weights and
the extension's gains) are solved on the other identification records and
the left-out record is predicted; the base model alone is refitted the
SAME way on the SAME rows. The finalists (every candidate that passes the
test below on this quick score) are scored again with their own nonlinear
parameters (time constants, delay, mode, creep time; an interference's
frequency searched afresh) also refitted on each fold's training records;
the spread of those fold estimates is the parameter's uncertainty
(jackknife). The validation records are not touched.

Held-out score per candidate, from the out-of-fold residuals e (every row
predicted by a fit that did not see its record):

* gain G = 1 - sum e_c^2 / sum e_null^2;
* z: each left-out record is cut into ``n_blocks`` contiguous blocks and
  ln(SSE_null / SSE_c) taken per block; z is the normal quantile of the
  one-sided Wilcoxon signed-rank test of those log ratios -- blocks, not
  samples, so correlated residuals are not counted as independent, and
  ranks, so a record with a large misfit does not swamp the others;
* the folds (records) it improves.

A record whose input goes beyond the other identification records' range
(``screen.held_out_windows``) is scored only up to where it first does:
it is fitted whole in every other fold, but the base model fitted without
it would extrapolate beyond, so its out-of-fold residuals there are not a
test of the cause.

Decision rule (``decide``; every threshold named here is a field of the policy, ``policy.Policy``, carried by
the folds and the screen):

1. A candidate *passes* if G >= ``min_explained``, it improves more than half
   of the folds, z >= ``z_pass`` (or G >= ``strong_gain`` with every fold
   improved: a transient misfit concentrates in few blocks), its parameters
   are within the cause's meaning and none is at its search bound (else:
   "not identified (at bound)"). An interference whose frequency, searched
   on each fold's training records alone, and amplitude agree across the
   folds (one line) passes with any G > 0 if it improves every fold with
   z >= ``z_pass`` (``line_evidence``).
2. Parsimony: among the passing candidates that the best (highest G) does not
   beat by z >= ``z_same`` and that would be a verdict themselves (rule 3),
   the one with fewest parameters is named. Another cause in that set is
   reported as ambiguous with it, with the drive that would separate them
   (``experiment``). When the named relaxation's slowest time constant is
   longer than the longest drive period and creep predicts as well (a slow
   low-pass of a drive with one mean level and a drift since the start are
   nearly the same function), creep is named instead -- the weaker claim: the
   records do not show that the slow part depends on the input -- with the
   relaxation as ambiguous, even with creep's own time scale at its limit.
   Relaxation variants with time constants closer than a factor ``duplicate_tau_ratio`` are not
   admitted (two nearly equal low-passes with opposite gains are a band-pass,
   not a relaxation); closer than their fold uncertainty, the variant with one
   fewer is named if it predicts as well.
3. A named cause that removes less than ``explain_share`` of the base's
   held-out misfit beyond white noise (n sd^2) is still named, with the rest
   reported as unexplained remainder, if it is *specific*: the part it removes
   passes the block test (z >= ``z_pass``), its fold estimates agree within
   ``partial_se`` (a mode's: its frequency, ``IDENTIFYING``; its damping is
   reported), and every other passing cause that predicts as well
   (z < ``z_same``) removes the *same* part (held-out improvements
   e_null - e with cosine >= ``same_slice``): those are rival explanations of
   one part, so the one with fewest parameters is named and the others are
   ambiguous with it (as in rule 2). A rival that removes another part makes
   it a guess -- if the rival's own parameters agree across the folds; one
   whose fold estimates disagree is no explanation either. So does a
   sinusoid at a drive harmonic with the same phase in every record (no
   interference: misfit locked to the drive) that has held-out evidence.
   If the best-predicting partial cause is not specific, another passing
   cause that is (by the same test, with ``min_records_check`` or more records) is named
   with the rest as unexplained remainder (``specific_part``).
   Otherwise the verdict is ``unexplained``; so it is if nothing passes
   while the residual is structured (a candidate has held-out evidence but
   fails the rest, or removes >= ``strong_gain`` of the held-out
   squared error in all though not in most records -- either still evidence
   without the record it improves most, ``carried_by_one_record`` -- or the
   residual repeats from period to period: ``residuals.periodic_structure``).
   Otherwise nothing passes: ``none``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy import stats

from .candidates import DRIVE_LOCKED, Candidate, is_log
from .delay import refit_delay
from .interference import fold_amplitude, fold_frequencies, joint_line, lines_removed, on_top
from .policy import Policy
from .saturation import columns_of, fit_level, shows_clip, unclipped

FOLD_NFEV = 8  # iterations of a fold's refit of a candidate's own nonlinear parameters (numerics)


@dataclass
class Folds:
    """Leave-one-record-out on the screen's stacked rows. Every record is left out once (fold m: record m);
    only its first ``scored[m]`` rows are held-out targets (``Screen.scored_rows``): past where a record's
    input first goes beyond the other records' range it is predicted by extrapolation, and its out-of-fold
    residual there (the ``tail``) is set to zero, so that every sum, block and fold count below covers the
    scored rows alone. A record with no scored row is no target. ``policy``: the decision policy (the screen's),
    for every test that compares held-out scores."""

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


def out_of_fold(screen, folds: Folds, design: Callable[[int], np.ndarray],
                train_residuals: list | None = None) -> np.ndarray:
    """Every row's residual from a linear solve on the other records; ``design(m)`` gives fold m's
    stacked design (all rows). ``train_residuals``: a list that receives, per fold, the residual on its
    training rows (the other records) of that same solve."""
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


def own_nonlinear(screen, c: Candidate) -> list[str]:
    return [n for n in c.model.nonlinear_names if n not in screen.base_nl_names]


def heldout_errors(screen, folds: Folds, c: Candidate, refit: bool = False,
                   train_residuals: list | None = None, only: Sequence[str] | None = None,
                   designs: list | None = None) -> tuple[np.ndarray, list[dict]]:
    """Out-of-fold residuals of a candidate; with ``refit`` its own nonlinear parameters (``only`` these, if
    given) are refitted on each fold's training rows (returns the fold estimates too). ``train_residuals``: a
    list that receives, per fold, the fit's residual on its training rows; ``designs``: one that receives, per
    fold, the stacked design it was solved with (not for a clip or an interference: not linear)."""
    nl = {n: c.params[n] for n in c.model.nonlinear_names}
    if c.cause == "interference":  # a disturbance: a line fitted jointly with the base, its phase per record
        base_rows = screen.design(screen.base, {k: c.params[k] for k in screen.base_nl_names})
        if c.limit == DRIVE_LOCKED:  # no disturbance but the base's misfit at a harmonic: on the base's residual
            base_train = []
            e_base = out_of_fold(screen, folds, lambda m: base_rows, base_train)
            f = fold_frequencies(screen, base_train) if refit else [nl["interference_frequency"]] * folds.n
            fold_est = [{"interference_frequency": f[m]} if refit else {} for m in range(folds.n)]
            for m, est in enumerate(fold_est):
                est["amplitude"] = fold_amplitude(screen, m, base_train[m], f[m])
            if train_residuals is not None:
                train_residuals.extend(lines_removed(screen, m, base_train[m], f[m]) for m in range(folds.n))
            return on_top(screen, folds, e_base, base_train, f), fold_est
        lines = joint_line(screen, folds, lambda m: base_rows,
                           None if refit else [nl["interference_frequency"]] * folds.n)
        fold_est = [{"interference_frequency": f, "amplitude": a} if refit else {"amplitude": a}
                    for f, a in zip(lines.frequencies_hz, lines.amplitudes)]
        if train_residuals is not None:
            train_residuals.extend(lines.train_residuals)
        return lines.errors, fold_est
    if c.cause == "saturation":
        return _heldout_saturation(screen, folds, c, refit, train_residuals)
    names = [n for n in own_nonlinear(screen, c) if only is None or n in only] if refit else []
    fold_est, fold_nl = [], []
    for m in range(folds.n):
        z = dict(nl)
        if names:
            train = ~folds.test(m)

            def residual(q, train=train):
                A = screen.design(c.model, q)
                return screen.solve(A[train], screen.y[train])[1]

            if names == ["delay"]:  # a rough profile: scanned, not a gradient step
                z = refit_delay(screen, c.model, z, lambda q: float(np.sum(residual(q) ** 2)))
            else:
                z = screen.refine(c.model, z, [(n, is_log(n)) for n in names], max_nfev=FOLD_NFEV, residual=residual)
            fold_est.append({n: float(z[n]) for n in names})
        fold_nl.append(z)
    if not names:
        A = screen.design(c.model, nl)
        mats = [A] * folds.n
    else:
        mats = [screen.design(c.model, z) for z in fold_nl]
    if designs is not None:
        designs.extend(mats)
    return out_of_fold(screen, folds, lambda m: mats[m], train_residuals), fold_est


def clipped_columns(screen, c: Candidate) -> np.ndarray:
    """The regressors a clipping candidate clips: the base's, or those of the kept part it sits on."""
    if c.clips is not None:
        return columns_of(screen, c.clips)
    return np.concatenate(screen.base_columns({k: c.params[k] for k in screen.base_nl_names}).rows)


def _heldout_saturation(screen, folds: Folds, c: Candidate, refit: bool = False,
                        train_residuals: list | None = None) -> tuple[np.ndarray, list[dict]]:
    """Out-of-fold residuals of a clipping: the linear parameters solved on the other records' free samples;
    with ``refit`` the level too (returns the fold levels). A fold whose records do not show a clip at their
    level (no flat top there, ``shows_clip``) predicts the left-out record unclipped: records that never reach
    a clip leave its level open above their peaks, and a level placed just under them would cut a record
    that goes higher."""
    side, level = c.hyperparameters["saturation_side"], c.params["saturation_level"]
    A = clipped_columns(screen, c)
    e = np.zeros(screen.n)
    fold_est = []
    for m in range(folds.n):
        test = folds.test(m)
        if refit:
            level = fit_level(screen, A[~test], screen.y[~test], side)
            fold_est.append({"saturation_level": level})
            if not shows_clip(screen, A[~test], screen.y[~test], side, level):
                level = math.inf if side == "upper" else -math.inf
        train = ~test & unclipped(screen, screen.y, side, level)
        theta, _ = screen.solve(A[train], screen.y[train])
        clip = np.minimum if side == "upper" else np.maximum
        e[test] = screen.y[test] - clip(A[test] @ theta, level)
        e[folds.tail(m)] = 0.0
        if train_residuals is not None:
            train_residuals.append(screen.y[~test] - clip(A[~test] @ theta, level))
    return e, fold_est


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
    z = signed_rank_z(d)
    improved = sum(float(e_ref[folds.test(m)] @ e_ref[folds.test(m)]) > float(e_c[folds.test(m)] @ e_c[folds.test(m)])
                   for m in range(folds.n) if folds.is_scored(m))
    return {"gain": 1.0 - float(e_c @ e_c) / ss_ref if ss_ref > 0 else 0.0, "z": z, "folds_improved": int(improved),
            "n_folds": folds.n_scored, "sse": float(e_c @ e_c)}


def jackknife(fold_estimates: list[dict]) -> dict:
    """Jackknife standard error of each fold-refitted parameter (log-scale ones as relative errors)."""
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
    return out


def fold_uncertainty(screen, fold_estimates: list[dict]) -> dict:
    """The jackknife uncertainty of fold-refitted parameters; a clipping level, which has no natural zero,
    also as its spread over the output's range."""
    out = jackknife(fold_estimates)
    if "saturation_level" in out:
        u = out["saturation_level"]
        u["se_over_range"] = u["se"] / max(float(np.ptp(screen.y)), 1e-300)
    return out


OPEN_ENDED = ("creep_time",)  # parameters whose upper search bound is a limit within the cause's meaning
OPEN_ENDED_NOTE = "longer than these records show, at its upper search bound: a straight drift"


def open_ended(screen, c: Candidate) -> list[str]:
    """The candidate's parameters at an upper search bound that is a limit within its cause's meaning: creep's
    time scale longer than these records show (1 - exp(-t / T) -> t / T, a straight drift since the start).
    The cause is identified (its drift over the records), that parameter is not: only a lower bound."""
    out = []
    for n in own_nonlinear(screen, c):
        if n in OPEN_ENDED and math.log(screen.bounds_of(c.model, n)[1] / float(c.params[n])) < screen.policy.at_bound:
            out.append(n)
    return out


def bound_flags(screen, c: Candidate) -> dict:
    """The held-out score's bound entries: ``at_bound`` and ``open_ended``."""
    return {"at_bound": at_bound(screen, c), "open_ended": open_ended(screen, c)}


def at_bound(screen, c: Candidate) -> list[str]:
    """The candidate's own nonlinear parameters at a search bound (not an ``open_ended`` one)."""
    out = []
    if c.cause in ("saturation", "interference"):
        return out
    near = screen.policy.at_bound
    for n in own_nonlinear(screen, c):
        lo, hi = screen.bounds_of(c.model, n)
        v = float(c.params[n])
        if n == "delay":  # a delay at zero is no delay: only the upper bound counts
            if v >= hi * (1 - near):
                out.append(n)
        elif is_log(n) and lo > 0:
            if math.log(v / lo) < near or (math.log(hi / v) < near and n not in OPEN_ENDED):
                out.append(n)
        elif v <= lo + near * (hi - lo) or v >= hi - near * (hi - lo):
            out.append(n)
    return out


def passes(c: Candidate, policy: Policy) -> bool:
    h = c.heldout
    return significant(c, policy) and not c.limit and not h.get("at_bound")


def significant(c: Candidate, policy: Policy) -> bool:
    """Held-out evidence for a candidate, whatever its meaning (``evidence``)."""
    return evidence(c.heldout, policy)


def evidence(h: dict, policy: Policy) -> bool:
    """A held-out score (``score``) is evidence: gain >= ``min_explained`` in a majority of folds, and z >=
    ``z_pass`` or a gain >= ``strong_gain`` in every fold; or, for one line (``line_evidence``), any gain."""
    return bool(h) and (line_evidence(h, policy) or (
        h["gain"] >= policy.min_explained and h["folds_improved"] * 2 > h["n_folds"] and (
            h["z"] >= policy.z_pass or (h["gain"] >= policy.strong_gain and h["folds_improved"] == h["n_folds"]))))


def line_evidence(h: dict, policy: Policy) -> bool:
    """An interference found on each fold's other records at one frequency and amplitude (``same_line``)
    that improves every held-out record with z >= ``z_pass`` is evidence however small its share: the gain
    floor guards against a flexible extension shaving a little off a large misfit, but a line whose
    frequency records chose independently is specific by itself."""
    return bool(h.get("same_line")) and _improves_every_fold(h, policy)


def line_worth_refit(c: Candidate, policy: Policy) -> bool:
    """An interference whose quick score (frequency from every record) could become ``line_evidence``."""
    return (c.cause == "interference" and not c.limit and bool(c.heldout)
            and _improves_every_fold(c.heldout, policy))


def _improves_every_fold(h: dict, policy: Policy) -> bool:
    return h["gain"] > 0 and h["z"] >= policy.z_pass and h["folds_improved"] == h["n_folds"]


def promising(c: Candidate, policy: Policy) -> bool:
    """Worth refining (stage 2): some held-out gain, in a majority of folds, whatever its z."""
    h = c.heldout
    return bool(h) and h["gain"] >= policy.min_explained and h["folds_improved"] * 2 > h["n_folds"] and not c.limit


@dataclass
class Verdict:
    cause: str  # none, unexplained or a vocabulary cause
    chosen: Candidate | None
    ambiguous_with: list[Candidate] = field(default_factory=list)
    reason: str = ""
    not_identified: list[str] = field(default_factory=list)  # "cause: parameter (at bound)"
    partial: Candidate | None = None  # the best candidate when the verdict is unexplained
    remainder: float | None = None  # share of the held-out misfit (beyond noise) the named cause leaves
    trace: list = field(default_factory=list)  # the rules that decided it, in order (``step``)


def step(rule: str, outcome: str, **inputs) -> dict:
    """One entry of a diagnosis's trace: the rule's id (docs/diagnosis.md, "The decision rule"), what it
    decided (a cause, ``none``, ``unexplained``, or what it changed) and the inputs it decided on."""
    return {"rule": rule, "outcome": outcome, "inputs": inputs}


def _score_of(c: Candidate) -> dict:
    h = c.heldout
    return {"cause": c.cause, "label": c.label, "gain": h.get("gain"), "z": h.get("z"),
            "share_of_misfit": h.get("share_of_misfit")}


def none_reason(candidates: Sequence[Candidate], policy: Policy) -> str:
    """Why nothing is named: no candidate predicts the held-out records better, or the best that does falls
    short of evidence (or only one record shows it), or outside its cause's meaning (said with its score)."""
    best = max(candidates, key=lambda c: c.heldout_gain, default=None)
    if best is None or not best.heldout_gain > 0:
        return "no candidate predicts the held-out records better than the base model"
    h = best.heldout
    why = (f"outside its meaning ({best.limit})" if best.limit else
           "carried by one held-out record" if significant(best, policy) else
           f"not evidence (z = {h['z']:.1f}, better in {h['folds_improved']} of {h['n_folds']} held-out records)")
    return (f"no candidate predicts the held-out records better than the base model with evidence and within its "
            f"meaning; the best, {best.label} (held-out gain {100 * best.heldout_gain:.2f} %), is {why}")


def merge_duplicates(chosen: Candidate, variants: Sequence[Candidate], folds: Folds, errors: dict) -> Candidate:
    """A relaxation variant with two time constants closer than their uncertainty (or a factor 1.25)
    gives way to the variant with one fewer, if that passes and does not predict worse (z < ``z_same``)."""
    pol = folds.policy
    while chosen.cause == "relaxation" and chosen.estimates["tau_s"] and len(chosen.estimates["tau_s"]) > 1:
        taus = chosen.estimates["tau_s"]
        se = {n: v.get("relative_se", 0.0) for n, v in chosen.uncertainty.items()}
        ses = sorted(((chosen.params[n], s) for n, s in se.items()), key=lambda p: p[0])
        width = [s for _, s in ses] if len(ses) == len(taus) else [0.0] * len(taus)
        floor = math.log(pol.duplicate_tau_ratio)
        close = any(math.log(taus[i + 1] / taus[i]) < max(floor, 2 * max(width[i], width[i + 1]))
                    for i in range(len(taus) - 1))
        fewer = [v for v in variants if len(v.estimates["tau_s"]) == len(taus) - 1 and passes(v, pol)
                 and pairwise_z(folds, errors, chosen, v) < pol.z_same]
        if not (close and fewer):
            break
        chosen = fewer[0]
    return chosen


def pairwise_z(folds: Folds, errors: dict, a: Candidate, b: Candidate) -> float:
    """How many standard errors b's held-out squared error exceeds a's (positive: a is better)."""
    return score(folds, errors[id(b)], errors[id(a)])["z"]


def decide(screen, folds: Folds, candidates: Sequence[Candidate], variants: Sequence[Candidate], errors: dict,
           e_null: np.ndarray, structured: bool) -> Verdict:
    """See the module docstring (every relaxation variant competes, not only the best); ``e_null``: the base
    model's out-of-fold residuals. The thresholds: ``folds.policy``."""
    pol = folds.policy
    null_sse = float(e_null @ e_null)
    candidates = list({id(c): c for c in [*candidates, *variants]}.values())
    ok = [c for c in candidates if passes(c, pol)]
    not_identified = [f"{c.cause}: {', '.join(c.heldout['at_bound'])} (at bound)" for c in candidates
                      if c.heldout.get("at_bound") and c.heldout_gain > 0]  # would predict something, unidentified
    not_identified += [f"{c.cause}: {', '.join(c.heldout['open_ended'])} ({OPEN_ENDED_NOTE})" for c in candidates
                       if c.heldout.get("open_ended") and not c.heldout.get("at_bound") and c.heldout_gain > 0]
    not_identified = list(dict.fromkeys(not_identified))  # relaxation variants may repeat a line
    evidence = [c for c in candidates if (significant(c, pol) or c.heldout_gain >= pol.strong_gain)  # partly predicted
                and not carried_by_one_record(folds, e_null, errors[id(c)])]
    if not ok:
        seen = {"structured": structured, "evidence": [c.cause for c in evidence]}
        if structured or evidence:
            partial = max(evidence, key=lambda c: c.heldout_gain) if evidence else None
            why = ("the residual is structured (it repeats from period to period)" if structured else
                   f"{partial.label} predicts part of it on held-out records, but not consistently over the records "
                   "or not within its meaning")
            return Verdict("unexplained", None, reason=why + "; no cause's extension predicts it on held-out records",
                           not_identified=not_identified, partial=partial,
                           trace=[step("nothing-passes", "unexplained", **seen)])
        return Verdict("none", None, reason=none_reason(candidates, pol), not_identified=not_identified,
                       trace=[step("nothing-passes", "none", **seen)])

    def record_share(c: Candidate) -> None:
        c.heldout["share_of_misfit"] = share_of_misfit(screen, null_sse, c.heldout["sse"])

    for c in ok:
        record_share(c)
    best = max(ok, key=lambda c: c.heldout_gain)
    # as good as the best: not worse by z >= z_same, and explaining enough of the misfit to be a verdict itself
    same = [c for c in ok if c is best or (pairwise_z(folds, errors, best, c) < pol.z_same
                                           and c.heldout["share_of_misfit"] >= pol.explain_share)]
    if best.heldout["share_of_misfit"] < pol.explain_share:  # a partial explanation: rivals for the same slice of it
        same += [c for c in ok if c is not best and pairwise_z(folds, errors, best, c) < pol.z_same
                 and same_slice(e_null, errors[id(best)], errors[id(c)], pol) and identified(c, pol)]
    chosen = min(same, key=lambda c: (c.k, -c.heldout_gain))
    trace = [step("simplest-as-good", chosen.cause, best=_score_of(best), as_good=[_score_of(c) for c in same],
                  passing=[c.cause for c in ok])]
    merged = merge_duplicates(chosen, variants, folds, errors)
    if merged is not chosen:
        trace.append(step("merge-duplicates", merged.label, named=chosen.label, tau_s=chosen.estimates["tau_s"]))
        chosen = merged
    others = {}
    for c in same:
        if c.cause != chosen.cause and (c.cause not in others or c.heldout_gain > others[c.cause].heldout_gain):
            others[c.cause] = c
    slow_twin = slow_relaxation_twin(screen, folds, errors, chosen, candidates)
    drift_note = ""
    if slow_twin is not None:  # the weaker claim: a drift since the start, not a dependence on the input
        others.pop(slow_twin.cause, None)
        others = {chosen.cause: chosen, **others}
        drift_note = (f"; named rather than relaxation: the relaxation's slowest time constant "
                      f"({max(chosen.estimates['tau_s']):.3g} s) is longer than the longest drive period, so these "
                      "records do not show that it depends on the input, and a drift since the start predicts "
                      f"them as well (z < {pol.z_same:g})")
        trace.append(step("slow-relaxation-twin", "creep", relaxation=_score_of(chosen), creep=_score_of(slow_twin),
                          slowest_tau_s=max(chosen.estimates["tau_s"])))
        chosen = slow_twin
        if "share_of_misfit" not in chosen.heldout:
            record_share(chosen)
    share = chosen.heldout.get("share_of_misfit", 1.0)
    reason = (f"predicts the held-out identification records better than the base model refitted the same way "
              f"(gain {100 * chosen.heldout_gain:.2f} %, z = {chosen.heldout['z']:.1f})")
    if chosen is not best and not drift_note:
        reason += f"; simpler than {best.label}, which does not predict better by z >= {pol.z_same:g}"
    reason += drift_note
    remainder = None
    if share < pol.explain_share:
        verdict_on = why_not_specific(folds, errors, chosen, candidates, best, e_null)
        why_not = verdict_on["text"]
        not_named = {k: verdict_on[k] for k in ("why", "rivals")}
        if why_not:
            other = specific_part(folds, errors, ok, chosen, candidates, e_null)  # their shares recorded above
            if other is not None:
                share = other.heldout["share_of_misfit"]
                trace.append(step("specific-part", other.cause, partial=_score_of(chosen), named=_score_of(other),
                                  not_specific=not_named))
                return Verdict(other.cause, other, [], (
                    f"predicts the held-out identification records better than the base model refitted the same "
                    f"way (gain {100 * other.heldout_gain:.2f} %, z = {other.heldout['z']:.1f}); it removes "
                    f"{100 * share:.0f} % of the base model's held-out misfit beyond white noise: the other "
                    f"{100 * (1 - share):.0f} % is unexplained ({chosen.label} predicts more of it, but {why_not})"
                    + loose_note(other, pol)), not_identified, remainder=1.0 - share, trace=trace)
            trace.append(step("partial-not-specific", "unexplained", partial=_score_of(chosen), not_specific=not_named))
            return Verdict("unexplained", None, reason=(
                f"the best-predicting cause ({chosen.cause}) removes only {100 * share:.0f} % of the base model's "
                f"held-out misfit beyond white noise, and {why_not}"), not_identified=not_identified, partial=chosen,
                trace=trace)
        trace.append(step("partial-specific", chosen.cause, share_of_misfit=share))
        remainder = 1.0 - share
        reason += (f"; it removes {100 * share:.0f} % of the base model's held-out misfit beyond white noise: "
                   f"the other {100 * remainder:.0f} % is unexplained")
    return Verdict(chosen.cause, chosen, list(others.values()), reason + loose_note(chosen, pol), not_identified,
                   remainder=remainder, trace=trace)


def share_of_misfit(screen, reference_sse: float, sse: float) -> float:
    """The share of a reference's held-out misfit beyond white noise (n sd^2, n the held-out rows) that a
    candidate removes (1 if the reference leaves nothing beyond noise)."""
    excess = reference_sse - screen.n_held_out_rows * screen.noise_sd**2
    return float((reference_sse - sse) / excess) if excess > 0 else 1.0


def carried_by_one_record(folds: Folds, e_null: np.ndarray, e_c: np.ndarray) -> bool:
    """Whether a held-out gain is evidence only through the one record it improves most: without that record's
    rows it is no evidence (``evidence``). Coloured noise on the other records occasionally throws the base's
    extrapolation to one record far off, and any extension with more columns then repairs it.
    With fewer than ``min_records_check`` records nothing is left to check, and the gain counts as it is."""
    if folds.n_scored < folds.policy.min_records_check:
        return False
    gain = [float(e_null[folds.test(m)] @ e_null[folds.test(m)] - e_c[folds.test(m)] @ e_c[folds.test(m)])
            if folds.is_scored(m) else -math.inf for m in range(folds.n)]
    best = int(np.argmax(gain))
    keep = ~folds.test(best)
    return not evidence(score(folds.without(best), e_null[keep], e_c[keep]), folds.policy)


IDENTIFYING = {"resonance": ("natural_frequency",)}  # a cause identified by these alone; the rest is its shape


def identified(c: Candidate, policy: Policy) -> bool:
    """Every parameter refitted per fold that identifies the cause agrees across the folds within
    ``partial_se`` (relative; a clipping level relative to the output's range); a candidate with none refitted
    per fold does not show it. A mode is identified by its frequency: its damping ratio, which drives far below
    the mode barely show, is reported with its fold spread but does not decide whether the mode is there."""
    if not c.uncertainty:  # nothing refitted per fold: agreement not shown
        return False
    only = IDENTIFYING.get(c.cause)
    return all(agrees(u, policy) for name, u in c.uncertainty.items() if only is None or name in only)


def agrees(u: dict, policy: Policy) -> bool:
    """One parameter's fold estimates (``fold_uncertainty``) agree within ``partial_se``: relative, a clipping
    level relative to the output's range, else relative to the folds' mean."""
    if "relative_se" in u or "se_over_range" in u:
        return u.get("relative_se", u.get("se_over_range")) <= policy.partial_se
    return u["se"] <= policy.partial_se * max(abs(float(np.mean(u["folds"]))), 1e-300)


def loose_note(c: Candidate, policy: Policy) -> str:
    """What the reason says of a named cause's parameters that do not identify it (``IDENTIFYING``) and whose
    fold estimates differ by more than ``partial_se``: e.g. a mode's damping ratio."""
    only = IDENTIFYING.get(c.cause)
    if only is None:
        return ""
    loose = [f"{n} (fold spread ±{100 * u['relative_se']:.0f} %)" for n, u in c.uncertainty.items()
             if n not in only and not agrees(u, policy)]
    if not loose:
        return ""
    agree = f" (the folds agree on {', '.join(only)})" if identified(c, policy) else ""
    return f"; its {', '.join(loose)} not identified{agree}"


def same_slice(e_null: np.ndarray, e_a: np.ndarray, e_b: np.ndarray, policy: Policy) -> bool:
    """Two candidates remove the same part of the base's held-out misfit: their improvements (e_null - e)
    point the same way (cosine >= ``same_slice``)."""
    d_a, d_b = e_null - e_a, e_null - e_b
    norm = float(np.linalg.norm(d_a) * np.linalg.norm(d_b))
    return norm > 0 and float(d_a @ d_b) / norm >= policy.same_slice


def not_specific(folds: Folds, errors: dict, chosen: Candidate, candidates: Sequence[Candidate],
                 best: Candidate | None = None, e_null: np.ndarray | None = None) -> str:
    """Why a cause that removes only part of the misfit is not named, as text ("" if it is): ``why_not_specific``."""
    return why_not_specific(folds, errors, chosen, candidates, best, e_null)["text"]


def why_not_specific(folds: Folds, errors: dict, chosen: Candidate, candidates: Sequence[Candidate],
                     best: Candidate | None = None, e_null: np.ndarray | None = None) -> dict:
    """Why a cause that removes only part of the misfit is not named ("" if it is): the part it removes must
    pass the block test (z >= ``z_pass``, by the best predictor of that part), its parameters must agree across
    the folds, and every other passing cause that predicts about as well (z < ``z_same``), with its own parameters
    agreeing across the folds, must remove the same part (then it is ambiguous with it) -- when several causes
    each take a different slice of a misfit that is mostly something else, naming one of them would be a guess.
    A drive-locked sinusoid with held-out evidence counts as such a rival: it shows misfit locked to the drive.
    Returns {"why": "" (specific), "z", "folds" or "rivals"; "rivals": their causes ("drive-locked" for such a
    sinusoid); "text": the reason in words}."""
    best = best or chosen
    pol = folds.policy
    if best.heldout["z"] < pol.z_pass:
        return {"why": "z", "rivals": [], "text": f"its block test gives z = {best.heldout['z']:.1f} < {pol.z_pass:g}"}
    if not identified(chosen, pol):
        return {"why": "folds", "rivals": [],
                "text": f"its parameters differ between the folds by more than {100 * pol.partial_se:.0f} %"}
    rivals = [c for c in candidates if c.cause != chosen.cause and passes(c, pol) and identified(c, pol)]  # admissible
    # a sinusoid locked to the drive is no cause, but with evidence it shows a drive-locked misfit of its own
    rivals += [c for c in candidates if c.limit == DRIVE_LOCKED and significant(c, pol)]
    close = [c for c in rivals if pairwise_z(folds, errors, chosen, c) < pol.z_same
             and (e_null is None or not same_slice(e_null, errors[id(chosen)], errors[id(c)], pol))]
    if close:
        names = sorted({"a misfit locked to the drive" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        rivals = sorted({"drive-locked" if c.limit == DRIVE_LOCKED else c.cause for c in close})
        return {"why": "rivals", "rivals": rivals,
                "text": f"{', '.join(names)} predicts the held-out records about as well, removing another part"}
    return {"why": "", "rivals": [], "text": ""}


def specific_part(folds: Folds, errors: dict, ok: Sequence[Candidate], partial: Candidate,
                  candidates: Sequence[Candidate], e_null: np.ndarray) -> Candidate | None:
    """When the best-predicting partial explanation is not specific (``not_specific``), another passing cause
    that is -- its own part passes the block test, its parameters agree across the folds, and no admissible
    rival predicting about as well removes another part -- is named with the rest as unexplained remainder:
    e.g. an interference on top of a misfit that an unstable relaxation predicts partly. The one predicting
    most among those; None if there is none, or with fewer than ``min_records_check`` records (two fold
    estimates that agree are too weak a check to name a cause that does not predict best)."""
    if folds.n_scored < folds.policy.min_records_check:
        return None
    for c in sorted(ok, key=lambda c: -c.heldout_gain):
        if c is not partial and c.cause != partial.cause and not not_specific(folds, errors, c, candidates, c, e_null):
            return c
    return None


def slow_relaxation_twin(screen, folds: Folds, errors: dict, chosen: Candidate,
                         candidates: Sequence[Candidate]) -> Candidate | None:
    """Creep, when the named relaxation's slowest time constant is longer than the longest drive period and
    creep predicts the held-out records as well (z < ``z_same``), even with its own time scale at its limit
    (``creep_periods`` drive periods): under drives of one mean level a slow low-pass of the input and a
    drift since the start are nearly the same function."""
    pol = folds.policy
    if chosen.cause != "relaxation" or max(chosen.estimates["tau_s"]) < screen.creep_min / pol.creep_periods:
        return None
    twins = [c for c in candidates if c.cause == "creep" and significant(c, pol)
             and pairwise_z(folds, errors, chosen, c) < pol.z_same]
    return max(twins, key=lambda c: c.heldout_gain) if twins else None
