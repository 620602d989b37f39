"""``diagnose(dataset, model)``: show where a model departs from the data, name the cause, extend, measure.

1. The base model is identified with varpro on the identification records' scored windows (records that
   share samples are first cut to their windows; ``segments`` cuts each into that many records).
2. It is simulated over every record, whole (``residuals``).
3. Candidate causes are fitted on the identification records' whole length (``screen``, ``causes``) and
   scored by leave-one-record-out prediction against the base refitted the same way (``search``).
4. The verdict: ``selection.decide`` applies ``selection.SELECTION``, then the rules of
   ``rules.AFTER_SELECTION`` are applied in order, each on the evidence its gathering step computes; the
   validation records are used last (``validation``).
5. Suggested experiments for what is ambiguous (``experiment``); each cause under "also" checked on the
   validation records (``validation.check_also``; reported only).
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from hysbench.data.dataset import Dataset, DatasetError, load_dataset
from hysbench.data.segments import own_samples, split_records
from hysbench.identification import data_scale, identify
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel
from hysbench.models.errors import HysbenchError

from .candidates import MAX_RELAXATION, MAX_ROWS
from .experiment import suggest
from .extensions import residuals_of_fit
from .policy import Policy
from .residuals import periodic_structure, summarise
from .result import Diagnosis
from .screen import Screen
from .search import run_screen
from .rule import Context, apply
from .rules import AFTER_SELECTION
from .selection import decide
from .validation import check_also


class DiagnosisError(HysbenchError):
    """A dataset or model the diagnosis cannot work with."""


def suggest_experiments(diag: Diagnosis, say: Callable[[str], None]) -> None:
    """An experiment for each cause ambiguous with the named one, and each under "also" with others as good."""
    if diag.chosen is None:
        return
    for other in diag.verdict.ambiguous_with:
        say(f"suggesting an experiment to separate {diag.cause} from {other.cause}")
        diag.experiments.append({"causes": [diag.cause, other.cause], **suggest(diag.screen, diag.chosen, other)})
    for c in diag.also:
        for other in diag.as_good_as(c):
            say(f"suggesting an experiment to separate {c.cause} from {other.cause} on top of what was kept")
            diag.experiments.append({"causes": [c.cause, other.cause], "on_top_of": diag.on_top_of(c),
                                     **suggest(diag.screen, c, other)})


def _held_out_in_part(screen) -> list[dict]:
    """The records predicted only up to their first excursion beyond the others' input range, with that time on
    their own clock (None: not predicted at all) and the share of their samples before it."""
    out = []
    for p, w, b in zip(screen.parts, screen.held_out_windows, screen.beyond_range):
        r = p.record
        if w < r.u.size:
            out.append({"record": r.file, "beyond_others_range": b, "predicted_share": w / r.u.size,
                        "held_out_until_s": float(r.t[w]) if w > 0 else None})
    return out


def _check(dataset: Dataset, base: HysteresisModel) -> None:
    if base.name.count("+"):
        raise DiagnosisError(f"diagnose the base model, not an extended one ({base.name!r})")
    if not base.has_linear_part:
        raise DiagnosisError(f"model {base.name!r} has no linear part: the diagnosis needs a model varpro can identify")
    if len(dataset.identification) < 2:
        raise DiagnosisError(f"dataset {dataset.name!r} needs at least two identification records "
                             "(causes are chosen by leave-one-record-out prediction); with one long record, "
                             "cut it into segments (--segments K, K >= 2)")
    if not dataset.validation:
        raise DiagnosisError(f"dataset {dataset.name!r} has no validation records: the gain cannot be measured")


def build_screen(dataset: Dataset, base: HysteresisModel, seed: int = 0, max_rows: int = MAX_ROWS,
                 say: Callable[[str], None] = lambda s: None, timings: dict | None = None,
                 policy: Policy = Policy()):
    """The base identified on the windows and its screen: ``(base_fit, before, summaries, noise_sd, screen)``."""
    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    say(f"identifying {base.name} (varpro) on the identification records' windows")
    base_fit = identify(base, dataset, method="varpro", seed=seed)
    timings["base_fit"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    before = residuals_of_fit(base_fit, dataset)
    summaries = summarise(before)
    noise = float(np.median([s.noise_sd for s in summaries if s.role == "identification"]))
    timings["residuals"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    screen = Screen(base, base_fit.params, base_fit.input_range, dataset.identification,
                    data_scale(dataset.identification), noise_sd=noise, max_rows=max_rows, seed=seed, policy=policy)
    timings["null_fit"] = time.perf_counter() - t1
    return base_fit, before, summaries, noise, screen


def diagnose(dataset: Dataset | str, model: str | HysteresisModel = "mrpim", seed: int = 0,
             max_rows: int = MAX_ROWS, max_relaxation: int = MAX_RELAXATION,
             extend: bool = True, experiments: bool = True, segments: int | None = None,
             progress: Callable[[str], None] | None = None, thorough: bool = False,
             policy: Policy = Policy()) -> Diagnosis:
    """Diagnose ``model`` on ``dataset``. ``segments``: cut each identification record into that many records
    (whole periods), e.g. one long recording. ``thorough``: every cause tried afresh on top of the named one
    also on long records (slower). ``policy``: the thresholds of the decision rule (``policy.Policy``)."""
    with threadpool_limits(1, user_api="blas"):  # small dense algebra: threads only contend
        say = progress or (lambda s: None)
        if isinstance(dataset, str) or hasattr(dataset, "__fspath__"):
            dataset = load_dataset(dataset)
        dataset = own_samples(dataset)
        if segments is not None:
            try:
                dataset = split_records(dataset, segments)
            except DatasetError as e:
                raise DiagnosisError(str(e)) from None
        base = get_model(model) if isinstance(model, str) else model
        _check(dataset, base)
        timings = {}
        t0 = time.perf_counter()
        base_fit, before, summaries, noise, screen = build_screen(dataset, base, seed, max_rows, say, timings, policy)
        t1 = time.perf_counter()
        say("fitting candidate causes on the identification records' whole length")
        result = run_screen(screen, before, max_relaxation=max_relaxation, progress=say)
        structure = periodic_structure(screen.null_residuals())
        structured = bool(structure["F"] > policy.structure_f) if structure["records"] else False
        verdict = decide(screen, result["heldout"], result["candidates"], result["relaxation_variants"], structured)
        timings["screen"] = time.perf_counter() - t1
        diag = Diagnosis(dataset=dataset, model=base.name, seed=seed, base_fit=base_fit, before=before,
                         summaries=summaries, noise_sd=noise, screen=screen, library=result["library"],
                         candidates=result["candidates"], relaxation_variants=result["relaxation_variants"],
                         verdict=verdict, structure={**structure, "structured": structured}, timings=timings,
                         settings={"max_rows": max_rows, "max_relaxation": max_relaxation,
                                   "drive_time_s": screen.drive_time, "creep_min_s": screen.creep_min,
                                   "segments": segments, "not_held_out": _held_out_in_part(screen),
                                   "thorough": thorough})
        ctx = Context(diag, result, say, extend)
        for rule in AFTER_SELECTION:
            t1 = time.perf_counter()
            evidence = rule.gather(ctx, diag.verdict)
            spent = time.perf_counter() - t1
            if evidence is not None or spent > 0.01:
                timings[rule.timing] = timings.get(rule.timing, 0.0) + spent
            if evidence is not None:
                diag.verdict = apply(rule, evidence, diag.verdict, policy)
        t1 = time.perf_counter()
        if experiments:
            suggest_experiments(diag, say)
            if diag.experiments:
                timings["experiments"] = time.perf_counter() - t1
        if extend and diag.also and diag.after:
            t1 = time.perf_counter()
            check_also(diag, say)
            timings["also_check"] = time.perf_counter() - t1
        timings["total"] = time.perf_counter() - t0
        return diag
