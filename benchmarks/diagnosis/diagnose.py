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
   dropped and the first of them named (``secondary.drop_redundant_primary``).
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

import copy
import json
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from hysbench.data.dataset import Dataset, DatasetError, load_dataset
from hysbench.data.files import jsonable
from hysbench.data.segments import own_samples, split_records
from hysbench.identification import Fit, data_scale, identify
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel
from hysbench.models.errors import HysbenchError

from .candidates import MAX_RELAXATION, MAX_ROWS, Candidate
from .experiment import RESHAPING_CAUSES, one_drive, suggest
from .extensions import gain, residuals_of_fit, scores_by_file
from .residuals import RecordResidual, ResidualSummary, periodic_structure, summarise
from .screen import Screen
from .search import run_screen
from .secondary import complete_partial, complete_promising, drop_redundant_primary, not_identified, secondary_causes
from .slow_part import predicts_as_well, slow_part_composite
from .validation import borne_out, check_also, check_unexplained, fit_extension, refit_base_whole
from .policy import Policy
from .selection import Verdict, decide, step

FORMAT = "hysbench-diagnosis/3"  # 3: the thresholds in "policy" (not "settings"), the rule "trace"


class DiagnosisError(HysbenchError):
    """A dataset or model the diagnosis cannot work with."""


def _plain(obj):
    """JSON fallback for numpy values."""
    return obj.tolist() if hasattr(obj, "tolist") else str(obj)


@dataclass
class Diagnosis:
    dataset: Dataset
    model: str
    seed: int
    base_fit: Fit
    before: list[RecordResidual]
    summaries: list[ResidualSummary]
    noise_sd: float
    screen: Screen
    library: dict
    candidates: list[Candidate]
    relaxation_variants: list[Candidate]
    verdict: Verdict
    structure: dict
    also: list[Candidate] = field(default_factory=list)
    secondary_tried: list[Candidate] = field(default_factory=list)
    also_alternatives: list = field(default_factory=list)  # (a kept also, those as good on top of the same part)
    slow_part: Candidate | None = None  # the named relaxation's slowest part replaced by creep (``slow_part``)
    dropped: Candidate | None = None  # the first named cause, if the secondary ones made it redundant
    experiments: list[dict] = field(default_factory=list)
    extended_fit: Fit | None = None
    after: list[RecordResidual] = field(default_factory=list)
    base_whole_fit: Fit | None = None
    base_whole: list[RecordResidual] = field(default_factory=list)
    interference_check: dict = field(default_factory=dict)
    unexplained_check: dict | None = None  # an unexplained verdict's evidence on the validation records
    also_check: list = field(default_factory=list)  # each cause under "also" on the validation records
    timings: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    trace: list = field(default_factory=list)  # every rule that decided or changed the verdict, in order (``step``)
    _gain: tuple | None = field(default=None, init=False, repr=False, compare=False)  # (inputs, gains)

    @property
    def chosen(self) -> Candidate | None:
        return self.verdict.chosen

    @property
    def cause(self) -> str:
        return self.verdict.cause

    def as_good_as(self, c: Candidate) -> list[Candidate]:
        """The causes tried on top of the same kept part that predict the held-out records as well as ``c``, a
        kept secondary cause, less those kept as well later (then the records show both); empty once a backward
        step has replaced it."""
        alike = next((alike for kept, alike in self.also_alternatives if kept is c), [])
        return [a for a in alike if a.cause not in {k.cause for k in self.also}]

    def on_top_of(self, c: Candidate) -> str:
        """What a kept secondary cause was added to: the named cause and the ones kept before it."""
        i = next(i for i, a in enumerate(self.also) if a is c)
        return " + ".join([self.cause, *(a.cause for a in self.also[:i])])

    @property
    def extended_model(self) -> str | None:
        if self.extended_fit:
            return self.extended_fit.model
        return self.chosen.model.name if self.chosen is not None else None

    @property
    def parameters(self) -> dict:
        """The named cause's parameters (identified on the identification records' whole length)."""
        c = self.chosen
        if c is None:
            return {}
        if self.extended_fit is None:
            return dict(c.estimates)
        from_fit = dict(c.estimates)
        p = self.extended_fit.params
        if c.cause == "relaxation":
            from_fit["tau_s"] = sorted(float(p[f"tau{i}"]) for i in range(1, len(c.estimates["tau_s"]) + 1))
        elif c.cause == "delay":
            from_fit["delay_s"] = float(p["delay"])
        elif c.cause == "resonance":
            from_fit.update(natural_frequency_hz=float(p["natural_frequency"]), damping_ratio=float(p["damping_ratio"]))
        elif c.cause == "creep":
            from_fit.update(size=float(p["creep_size"]), time_scale_s=float(p["creep_time"]))
        elif c.cause == "saturation":
            from_fit["level"] = float(p["saturation_level"])
        return from_fit

    @property
    def uncertainty(self) -> dict:
        return self.chosen.uncertainty if self.chosen is not None else {}

    @property
    def policy(self) -> Policy:
        """The decision policy every step used (the screen's)."""
        return self.screen.policy

    @property
    def decision_rule(self) -> str:
        p = self.policy
        return (f"leave-one-identification-record-out prediction against the base model refitted the same way: "
                f"a cause passes with held-out gain >= {p.min_explained:.0%} in a majority of folds "
                f"and z >= {p.z_pass:g} (signed-rank test over blocks) or a gain >= {p.strong_gain:.0%} in every fold "
                f"(an interference, scored on top of the base's own held-out prediction, found at one frequency and "
                f"amplitude on each fold's other records: any gain, every fold improved, z >= {p.z_pass:g}), "
                f"parameters within the cause's meaning and not at a search bound; the simplest passing cause "
                f"within z = {p.z_same:g} of the best is "
                f"named (creep rather than a relaxation slower than every drive period that creep predicts as well; "
                f"a relaxation whose slowest time constant is slower than every drive period is compared with its "
                f"faster ones plus creep, which is listed as ambiguous if it predicts as well); "
                f"if it removes < {p.explain_share:.0%} of the held-out misfit beyond white noise it is named "
                f"only if specific (z >= {p.z_pass:g}, fold estimates within {p.partial_se:.0%}: a mode's frequency, its "
                f"damping reported; every other cause within z = {p.z_same:g} removing the same part, held-out "
                f"improvements with cosine >= {p.same_slice:g}: "
                f"those are ambiguous with it) with the rest reported as unexplained remainder, else the passing "
                f"cause predicting most among those that are specific ({p.min_records_check} or more records), else the best "
                f"partial cause (if it passes) with the causes kept on top of it by held-out forward selection if "
                f"together they remove >= {p.explain_share:.0%} (two causes at once), else unexplained; "
                f"nothing passing: unexplained if the residual is structured (period-to-period "
                f"F > {p.structure_f:g} or a significant but inadmissible candidate), else none. Validation "
                f"records take no part; they confirm the named extension if it lowers their residual with "
                f"z >= {p.z_confirm:.3g} against their own noise (correlated noise counted); an unexplained verdict "
                f"resting on a candidate alone (no period-to-period structure) becomes none unless that candidate's "
                f"extension lowers the validation records' residual the same way; each cause under also is checked "
                f"the same way on top of what was kept before it (reported, the verdict unchanged)")

    def gain(self) -> dict:
        """The named extension's gain on the validation and identification records (computed once for the
        residuals it is given)."""
        if not self.after:
            return {}
        inputs = (self.base_whole, self.after, self.before)
        if self._gain is None or any(a is not b for a, b in zip(self._gain[0], inputs)):
            out = {"validation": gain(self.base_whole, self.after, "validation"),
                   "identification": gain(self.base_whole, self.after, "identification"),
                   "validation_vs_base_fitted_on_windows": gain(self.before, self.after, "validation")}
            self._gain = (inputs, out)
        return copy.deepcopy(self._gain[1])

    @property
    def confirmed(self) -> bool | None:
        """Whether the named extension lowers the validation residual against the base model refitted
        on the same whole records, on the windows and by more than the records' noise explains (z >=
        the policy's ``z_confirm``); an interference (phase fitted per validation record) by the same amplitude
        there."""
        v = self.gain().get("validation")
        if not v:
            return None
        return borne_out(v, self.cause, self.interference_check, self.policy)

    @property
    def warning(self) -> str:
        if self.confirmed is not False:
            return ""
        v = self.gain()["validation"]
        return (f"the extension does not improve the validation records beyond their noise against the base model "
                f"refitted the same way (residual sum of squares removed: {100 * v['explained_whole']:.1f} % whole, "
                f"z = {v['z_whole']:.2f} against the noise, needs {self.policy.z_confirm:.3g}; "
                f"{100 * v['explained_window']:.1f} % on the windows"
                + (f"; interference amplitude there {self.interference_check.get('validation_amplitude', 0):.3g}"
                   if self.cause == "interference" else "")
                + f"): '{self.cause}' is not confirmed on data that took no part in the fit; treat it as a hypothesis")

    @property
    def one_drive_caution(self) -> str:
        """Under one periodic drive a delay, a lag or a mode only reshapes the response's harmonics, as a static
        nonlinearity outside the vocabulary can: said when one is named or kept ("" otherwise)."""
        named = list(dict.fromkeys(c for c in (self.cause, *(a.cause for a in self.also)) if c in RESHAPING_CAUSES))
        drive = one_drive(self.dataset.records) if named else None
        if drive is None:
            return ""
        return (f"every record ({drive['records']}) has the same drive, {drive['frequency_hz']:.4g} Hz over the same "
                f"input range: under it {' and '.join(named)} only reshape{'s' if len(named) == 1 else ''} the "
                "periodic response, as a static nonlinearity outside the vocabulary (a dead band, a sensor curvature) "
                "can; a record at another amplitude or frequency would tell them apart")

    def to_json(self) -> dict:
        v = self.verdict
        evidence = {
            "noise_sd": self.noise_sd,
            "records": [s.as_dict() for s in self.summaries],
            "library_screen": self.library,
            "null": self.screen.null.summary(),
            "candidates": [c.summary() for c in sorted(self.candidates, key=lambda c: -c.heldout_gain)],
            "relaxation_variants": [c.summary() for c in self.relaxation_variants],
            "secondary_tried": [{**c.summary(), "also": any(c is a for a in self.also)} for c in self.secondary_tried],
            "slow_part_as_creep": None if self.slow_part is None else {
                **self.slow_part.summary(), "ambiguous": any(c is self.slow_part for c in self.verdict.ambiguous_with)},
            "periodic_structure": self.structure,
            "decision_rule": self.decision_rule,
            "screen_rows": self.screen.n,
        }
        extended = None
        if self.extended_fit:
            extended = {"name": self.extended_fit.model, "hyperparameters": self.extended_fit.hyperparameters,
                        "method": self.extended_fit.method, "params": self.extended_fit.params,
                        "n_params": self.extended_fit.n_params, "fitted_on": self.extended_fit.fitted_on,
                        "notes": self.extended_fit.notes}
        as_good = {c.cause: alike for c in self.also if (alike := self.as_good_as(c))}
        data = {
            "format": FORMAT, "model": self.model, "dataset": self.dataset.name,
            "dataset_hash": self.dataset.content_hash(), "seed": self.seed, "policy": self.policy.as_dict(),
            "cause": self.cause, "reason": v.reason, "parameters": self.parameters,
            "uncertainty": self.uncertainty, "not_identified": v.not_identified,
            "ambiguous_with": [c.cause for c in v.ambiguous_with], "suggested_experiments": self.experiments,
            "partial": v.partial.summary() if v.partial is not None else None,
            "unexplained_remainder": v.remainder,
            "evidence": evidence, "extended_model": self.extended_model, "extended_fit": extended,
            "base_fit": {"method": self.base_fit.method, "params": self.base_fit.params,
                         "n_params": self.base_fit.n_params, "notes": self.base_fit.notes},
            "before": scores_by_file(self.before),
            "after": scores_by_file(self.after) if self.after else {},
            "base_refit_on_whole_records": scores_by_file(self.base_whole) if self.base_whole else {},
            "gain": self.gain(), "interference_check": self.interference_check,
            "confirmed_on_validation": self.confirmed, "warning": self.warning,
            "one_drive_caution": self.one_drive_caution, "unexplained_check": self.unexplained_check,
            "also_on_validation": self.also_check,
            "also": [c.cause for c in self.also],
            "dropped_as_redundant": None if self.dropped is None else {
                "cause": self.dropped.cause, "label": self.dropped.label, "heldout": self.dropped.heldout},
            "also_as_good": {cause: [a.cause for a in alike] for cause, alike in as_good.items()},
            "also_as_good_fits": {cause: [{"cause": a.cause, "label": a.label, "estimates": a.estimates,
                                           "heldout_gain": a.heldout_gain, "uncertainty": a.uncertainty}
                                          for a in alike] for cause, alike in as_good.items()},
            "also_not_identified": {c.cause: why for c in self.also if (why := not_identified(c))},
            "trace": self.trace,
            "timings_s": self.timings, "settings": self.settings,
        }
        return jsonable(json.loads(json.dumps(data, default=_plain)))


def slow_part_twin(diag: Diagnosis, result: dict, experiments: bool, say: Callable[[str], None]) -> None:
    """Creep as ambiguous with the named relaxation's slowest part (``slow_part``), unless creep is
    already named, ambiguous, or kept on top of the relaxation ("also": then the records show both)."""
    v = diag.verdict
    if v.chosen is None or v.chosen.cause != "relaxation":
        return
    say("the slowest time constant or creep")
    comp = slow_part_composite(diag.screen, result["folds"], result["errors"], v.chosen, result["candidates"],
                               result["relaxation_variants"])
    diag.slow_part = comp
    taken = {c.cause for c in (*v.ambiguous_with, *diag.also)}
    if comp is None:
        return
    as_well = predicts_as_well(result["folds"], result["errors"], v.chosen, comp)
    ambiguous = as_well and "creep" not in taken
    diag.trace.append(step("slow-part-twin", "creep ambiguous" if ambiguous else "relaxation alone",
                           composite=comp.label, gain=comp.heldout.get("gain"), z=comp.heldout.get("z"),
                           predicts_as_well=as_well, creep_already=sorted(taken & {"creep"})))
    if not ambiguous:
        return
    v.ambiguous_with.append(comp)
    v.reason += (f"; its slowest time constant ({max(v.chosen.estimates['tau_s']):.3g} s) is longer than the longest "
                 f"drive period, and the faster ones plus a drift since the start predict the held-out records as well "
                 f"(z < {diag.policy.z_same:g}): that part may be creep")
    if experiments:
        diag.experiments.append({"causes": [v.chosen.cause, "creep"], **suggest(diag.screen, v.chosen, comp)})


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
    verdict = decide(screen, result["folds"], result["candidates"], result["relaxation_variants"],
                     result["errors"], result["errors"][id(screen.null)], structured)
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
    if extend and diag.cause == "unexplained" and diag.verdict.partial is not None and not structured:
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
                              if diag.cause == "interference" else {})))
    if diag.also:
        t1 = time.perf_counter()
        check_also(diag, say)
        timings["also_check"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    return diag
