"""``diagnose(dataset, model)``: show where a model departs from the data, name the cause, extend, measure.

0. Records that hold the same samples (one recording listed with an
   identification and a validation window) are cut to their windows, so no
   whole-record fit sees another record's samples; with ``segments`` each
   identification record is cut into that many records (whole periods,
   from input minima: ``hysbench.data.segments``).
1. The base model is identified with varpro on the identification records
   (their scored windows, as the benchmark does): the "before" model.
2. It is simulated over every record, whole; residuals, noise level and
   whiteness per record (``residuals``).
3. Candidate causes are fitted on the identification records' whole length
   (``screen``, one module per cause) and scored by leave-one-record-out
   prediction against the base model refitted the same way (``search``,
   ``selection``).
4. The verdict (``selection.decide``): a cause, ``none`` or ``unexplained``;
   two causes that predict equally well are reported as ambiguous, with the
   drive that separates them (``experiment``). An ``unexplained`` verdict
   whose best partial cause passes by itself is completed by the forward
   selection of step 5 on top of it; if the two explain half of the misfit,
   it is named (``secondary.complete_partial``). A ``none`` verdict whose
   best candidate is promising but short of evidence alone is completed the
   same way; it is named if together they show evidence that more than one
   record carries (``secondary.complete_promising``).
5. Other causes are tried on top of the named one (composite extension)
   and kept as "also" if they pass the held-out test against what is kept,
   their own parameters refitted per fold (``secondary.secondary_causes``);
   if those alone then predict as well without the named cause, it is
   dropped and the first of them named (``backward.drop_redundant_primary``).
6. A named relaxation slower than every drive period: its slowest part
   replaced by creep (``slow_part``); if that predicts as well, creep is
   reported as ambiguous with it.
7. The named extension (a registered model, e.g. ``mrpim+relaxation``) is
   identified on the identification records' whole length, every parameter
   free; the base model is refitted the same way; the validation records --
   untouched so far -- measure the gain of the one over the other
   (confirmed if it lowers their residual by more than their noise explains,
   ``residuals.gain_z``: correlated noise counted). An interference is confirmed by
   the same frequency and amplitude on the validation records, its phase
   fitted per record.
8. An ``unexplained`` verdict that rests on a candidate's held-out evidence
   alone (no period-to-period structure) is checked the same way: that
   candidate's extension, fitted on the identification records' whole
   length, must predict the validation records beyond their noise, else what
   looked structured is not borne out and the verdict is ``none``
   (``validation.check_unexplained``; coloured noise fits a slow part of one record's
   noise on the others).
9. Each cause kept under "also" is checked on the validation records on top
   of what was kept before it, by the same test (``validation.check_also``):
   reported, the verdict unchanged.
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

from .backward import drop_redundant_primary
from .candidates import MAX_RELAXATION, MAX_ROWS
from .experiment import suggest
from .extensions import residuals_of_fit
from .policy import Policy
from .residuals import periodic_structure, summarise
from .result import Diagnosis
from .screen import Screen
from .search import run_screen
from .secondary import complete_partial, complete_promising, secondary_causes
from .selection import UNEXPLAINED, decide, step
from .slow_part import predicts_as_well, slow_part_composite
from .validation import check_also, check_unexplained, fit_extension, refit_base_whole

class DiagnosisError(HysbenchError):
    """A dataset or model the diagnosis cannot work with."""


def slow_part_twin(diag: Diagnosis, result: dict, experiments: bool, say: Callable[[str], None]) -> None:
    """Creep as ambiguous with the named relaxation's slowest part (``slow_part``), unless creep is
    already named, ambiguous, or kept on top of the relaxation ("also": then the records show both)."""
    v = diag.verdict
    if v.chosen is None or v.chosen.kind.slow_twin is None:
        return
    twin = v.chosen.kind.slow_twin
    say("the slowest time constant or creep")
    comp = slow_part_composite(diag.screen, result["heldout"], v.chosen, result["candidates"],
                               result["relaxation_variants"])
    diag.slow_part = comp
    taken = {c.cause for c in (*v.ambiguous_with, *diag.also)}
    if comp is None:
        return
    as_well = predicts_as_well(result["heldout"], v.chosen, comp)
    ambiguous = as_well and twin not in taken
    diag.trace.append(step("slow-part-twin", f"{twin} ambiguous" if ambiguous else f"{v.chosen.cause} alone",
                           composite=comp.label, gain=comp.heldout.get("gain"), z=comp.heldout.get("z"),
                           predicts_as_well=as_well, creep_already=sorted(taken & {twin})))
    if not ambiguous:
        return
    v.ambiguous_with.append(comp)
    slowest = v.chosen.kind.slowest_time_s(v.chosen.estimates)
    v.reason += (f"; its slowest time constant ({slowest:.3g} s) is longer than the longest "
                 f"drive period, and the faster ones plus a drift since the start predict the held-out records as well "
                 f"(z < {diag.policy.z_same:g}): that part may be creep")
    if experiments:
        diag.experiments.append({"causes": [v.chosen.cause, twin], **suggest(diag.screen, v.chosen, comp)})


def also_experiments(diag: Diagnosis, say: Callable[[str], None]) -> None:
    """A suggested experiment for each secondary cause kept with others as good on top of the same part (the
    simpler one kept, ``secondary._choose``): the drive on which the two composites' predictions differ most."""
    for c in diag.also:
        for other in diag.as_good_as(c):
            say(f"suggesting an experiment to separate {c.cause} from {other.cause} on top of what was kept")
            diag.experiments.append({"causes": [c.cause, other.cause], "on_top_of": diag.on_top_of(c),
                                     **suggest(diag.screen, c, other)})


def _held_out_in_part(screen) -> list[dict]:
    """The records the held-out test predicts only up to their first excursion beyond the others' input range:
    that time on the record's own clock (None: not predicted at all) and the share of its samples before it."""
    out = []
    for p, w, b in zip(screen.parts, screen.held_out_windows, screen.beyond_range):
        r = p.record
        if w < r.u.size:
            out.append({"record": r.file, "beyond_others_range": b, "predicted_share": w / r.u.size,
                        "held_out_until_s": float(r.t[w]) if w > 0 else None})
    return out


def diagnose(dataset: Dataset | str, model: str | HysteresisModel = "mrpim", seed: int = 0,
             max_rows: int = MAX_ROWS, max_relaxation: int = MAX_RELAXATION,
             extend: bool = True, experiments: bool = True, segments: int | None = None,
             progress: Callable[[str], None] | None = None, thorough: bool = False,
             policy: Policy = Policy()) -> Diagnosis:
    """Diagnose ``model`` on ``dataset``; see the module docstring. ``segments``: cut each identification
    record into that many consecutive records (whole periods) for leave-one-record-out, e.g. one long
    recording. ``thorough``: every cause tried afresh on top of the named one also on long records
    (``secondary.secondary_causes``; slower). ``policy``: the thresholds of the decision rule
    (``policy.Policy``; the default is the documented rule)."""
    with threadpool_limits(1, user_api="blas"):  # small dense algebra: threads only contend
        return _diagnose(dataset, model, seed, max_rows, max_relaxation, extend, experiments,
                         segments, progress, thorough, policy)


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
    """The base model identified on the windows (varpro), its residuals and their summaries, the noise sd
    (median over the identification records) and the candidate screen on the whole records' rows, carrying
    ``policy``: ``(base_fit, before, summaries, noise_sd, screen)``."""
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


def _diagnose(dataset, model, seed, max_rows, max_relaxation, extend, experiments,
              segments, progress, thorough, policy) -> Diagnosis:
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
                     trace=list(verdict.trace),
                     settings={"max_rows": max_rows, "max_relaxation": max_relaxation,
                               "drive_time_s": screen.drive_time, "creep_min_s": screen.creep_min, "segments": segments,
                               "not_held_out": _held_out_in_part(screen),
                               "thorough": thorough})
    t1 = time.perf_counter()
    if experiments and verdict.chosen is not None:
        for other in verdict.ambiguous_with:
            say(f"suggesting an experiment to separate {verdict.chosen.cause} from {other.cause}")
            diag.experiments.append({"causes": [verdict.chosen.cause, other.cause],
                                     **suggest(screen, verdict.chosen, other)})
    if diag.experiments:
        timings["experiments"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    completed = verdict.chosen is None and extend and (complete_partial(diag, result, say)
                                                       or complete_promising(diag, result, say))
    secondary_s = time.perf_counter() - t1  # a completion runs the secondary causes on the partial or promising cause
    if extend and diag.cause == UNEXPLAINED and diag.verdict.partial is not None and not structured:
        t1 = time.perf_counter()
        refit_base_whole(diag, say)
        check_unexplained(diag, say)
        timings["unexplained_check"] = time.perf_counter() - t1
    if diag.chosen is None or not extend:
        t1 = time.perf_counter()
        slow_part_twin(diag, result, experiments, say)
        timings["secondary"] = secondary_s + time.perf_counter() - t1
        timings["total"] = time.perf_counter() - t0
        return diag
    t1 = time.perf_counter()
    refit_base_whole(diag, say)
    timings["base_refit"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    if not completed:  # a completed partial cause has its secondary causes already
        secondary_causes(diag, result, say)
    drop_redundant_primary(diag, result, say)
    slow_part_twin(diag, result, experiments, say)
    timings["secondary"] = secondary_s + time.perf_counter() - t1
    if experiments and any(diag.as_good_as(c) for c in diag.also):
        t1 = time.perf_counter()
        also_experiments(diag, say)
        timings["experiments"] = timings.get("experiments", 0.0) + time.perf_counter() - t1
    t1 = time.perf_counter()
    diag.extended_fit, diag.after, diag.interference_check = fit_extension(diag, diag.chosen, say)
    timings["extended_fit"] = time.perf_counter() - t1
    v = diag.gain().get("validation") or {}
    diag.trace.append(step("validation", "confirmed" if diag.confirmed else "not confirmed", cause=diag.cause,
                           **{k: v.get(k) for k in ("explained_whole", "explained_window", "z_whole")},
                           **({"same_amplitude": diag.interference_check.get("same_amplitude")}
                              if diag.chosen.kind.disturbance else {})))
    if diag.also:
        t1 = time.perf_counter()
        check_also(diag, say)
        timings["also_check"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    return diag
