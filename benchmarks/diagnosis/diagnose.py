"""``diagnose(dataset, model)``: show where a model departs from the data, name the cause, extend, measure.

1. The base model is identified with varpro on the identification records
   (their scored windows, as the benchmark does): the "before" model.
2. It is simulated over every record, whole; residuals, noise level and
   whiteness per record (``residuals``).
3. Candidate causes are screened on the identification records' whole
   length (``causes``): a pysindy library screen, then each cause's extension
   fitted explicitly, all compared with the base model alone by BIC.
4. The cause is the candidate with the lowest BIC if it beats the base model
   by ``bic_threshold`` and explains at least ``min_explained`` of its
   residual sum of squares; otherwise ``none``. The validation records take
   no part in this choice: each candidate's share of the validation residual
   explained is printed as evidence only.
5. The named extension (a registered model, e.g. ``mrpim+relaxation``) is
   identified with the identifiers on the identification records' whole
   length, every parameter free, from the screen's estimate; the base model
   is refitted the same way. e_m / e_rms per record before and after, and the
   gain on the validation records, which took part in no fit and no choice.
6. The strongest ``max_secondary`` other causes that pass the test of 4.
   alone are tried on top of the named extension at its identified
   parameters (composite extension, refined on the screen's rows); those
   that pass it again against the named one alone are "also".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from hysbench.data.dataset import Dataset, load_dataset
from hysbench.identification import Fit, data_scale, identify
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel
from hysbench.models.errors import HysbenchError

from .causes import BIC_THRESHOLD, MAX_RELAXATION, MAX_ROWS, MIN_EXPLAINED, Candidate, Screen, decide, estimates_of, run_screen
from .extensions import gain, identify_whole, registered_extension, residuals_of_fit, scores_by_file
from .residuals import RecordResidual, ResidualSummary, summarise

FORMAT = "hysbench-diagnosis/1"


class DiagnosisError(HysbenchError):
    """A dataset or model the diagnosis cannot work with."""


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
    chosen: Candidate | None
    also: list[Candidate]
    secondary_tried: list[Candidate] = field(default_factory=list)
    extended_fit: Fit | None = None
    after: list[RecordResidual] = field(default_factory=list)
    base_whole_fit: Fit | None = None
    base_whole: list[RecordResidual] = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    @property
    def cause(self) -> str:
        return self.chosen.cause if self.chosen else "none"

    @property
    def extended_model(self) -> str | None:
        return self.extended_fit.model if self.extended_fit else None

    @property
    def parameters(self) -> dict:
        if not self.extended_fit:
            return {}
        return estimates_of(self.cause, self.extended_fit.params, self.extended_fit.model_instance())

    @property
    def decision_rule(self) -> str:
        return (f"the candidate with the lowest BIC, if BIC(base alone) - BIC > {self.settings['bic_threshold']:g}, "
                f"it explains >= {self.settings['min_explained']:.1%} of the base-alone identification residual "
                "sum of squares and its parameters are within the cause's meaning (a resonance underdamped, creep "
                "slower than twice the longest drive period), else none; the validation records take no part")

    def gain(self) -> dict:
        if not self.after:
            return {}
        out = {"validation": gain(self.before, self.after, "validation"),
               "identification": gain(self.before, self.after, "identification")}
        if self.base_whole:
            out["validation_vs_base_refit_on_whole_records"] = gain(self.base_whole, self.after, "validation")
        return out

    @property
    def confirmed(self) -> bool | None:
        """Whether the named extension lowers the validation residual, over whole records and on the
        windows (None when nothing was named)."""
        v = self.gain().get("validation")
        if not v:
            return None
        return bool(v["explained_whole"] > 0 and v["explained_window"] > 0)

    @property
    def warning(self) -> str:
        if self.confirmed is not False:
            return ""
        v = self.gain()["validation"]
        return (f"the extension does not improve the validation records (residual sum of squares removed: "
                f"{100 * v['explained_whole']:.1f} % whole, {100 * v['explained_window']:.1f} % on the windows): "
                f"'{self.cause}' is not confirmed on data that took no part in the fit; treat it as a hypothesis")

    def to_json(self) -> dict:
        from hysbench.identification.fit import _jsonable

        def cand(c: Candidate) -> dict:
            return c.summary()

        evidence = {
            "noise_sd": self.noise_sd,
            "records": [s.as_dict() for s in self.summaries],
            "library_screen": self.library,
            "null": cand(self.screen.null),
            "candidates": [cand(c) for c in sorted(self.candidates, key=lambda c: c.bic)],
            "relaxation_variants": [cand(c) for c in self.relaxation_variants],
            "secondary_tried": [{**cand(c), "also": any(c is a for a in self.also)} for c in self.secondary_tried],
            "decision_rule": self.decision_rule,
            "screen_rows": self.screen.n,
        }
        extended = None
        if self.extended_fit:
            extended = {"name": self.extended_fit.model, "hyperparameters": self.extended_fit.hyperparameters,
                        "method": self.extended_fit.method, "params": self.extended_fit.params,
                        "n_params": self.extended_fit.n_params, "fitted_on": self.extended_fit.fitted_on,
                        "notes": self.extended_fit.notes}
        return _jsonable({
            "format": FORMAT,
            "model": self.model,
            "dataset": self.dataset.name,
            "dataset_hash": self.dataset.content_hash(),
            "seed": self.seed,
            "cause": self.cause,
            "parameters": self.parameters,
            "evidence": evidence,
            "extended_model": self.extended_model,
            "extended_fit": extended,
            "base_fit": {"method": self.base_fit.method, "params": self.base_fit.params,
                         "n_params": self.base_fit.n_params, "notes": self.base_fit.notes},
            "before": scores_by_file(self.before),
            "after": scores_by_file(self.after) if self.after else {},
            "base_refit_on_whole_records": scores_by_file(self.base_whole) if self.base_whole else {},
            "gain": self.gain(),
            "confirmed_on_validation": self.confirmed,
            "warning": self.warning,
            "also": [c.cause for c in self.also],
            "timings_s": self.timings,
            "settings": self.settings,
        })


def secondary_causes(diag: Diagnosis, max_secondary: int, bic_threshold: float, min_explained: float,
                     say: Callable[[str], None]) -> None:
    """The strongest other candidates, each added to the named extension (composite) and refined on the
    screen from the identified parameters; "also" if it passes the test against the named one alone
    (at its identified parameters, linear ones re-solved on the screen)."""
    screen, chosen = diag.screen, diag.chosen
    primary = chosen
    if chosen.cause != "saturation":
        nl = {k: diag.extended_fit.params[k] for k in chosen.model.nonlinear_names}
        identified = screen.candidate(chosen.cause, chosen.label, chosen.model, nl, chosen.hyperparameters,
                                      stage="identified")
        if identified.bic < primary.bic:
            primary = identified
    others = sorted([c for c in diag.candidates if c.cause not in (chosen.cause, "saturation")
                     and c.delta_bic < -bic_threshold and c.explained >= min_explained and not c.limit],
                    key=lambda c: c.bic)[:max_secondary]  # (no composite with clipping: not separable)
    for c in others:
        say(f"trying {chosen.cause} + {c.cause}")
        comp = screen.composite(primary, c)
        if comp is None:
            continue
        diag.secondary_tried.append(comp)
        if comp.delta_bic < -bic_threshold and comp.explained >= min_explained and not comp.limit:
            diag.also.append(comp)


def diagnose(dataset: Dataset | str, model: str | HysteresisModel = "mrpim", seed: int = 0,
             max_rows: int = MAX_ROWS, max_relaxation: int = MAX_RELAXATION, bic_threshold: float = BIC_THRESHOLD,
             min_explained: float = MIN_EXPLAINED, max_secondary: int = 3, extend: bool = True,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Diagnose ``model`` on ``dataset``; see the module docstring."""
    with threadpool_limits(1, user_api="blas"):  # small dense algebra: threads only contend
        return _diagnose(dataset, model, seed, max_rows, max_relaxation, bic_threshold, min_explained,
                         max_secondary, extend, progress)


def _diagnose(dataset, model, seed, max_rows, max_relaxation, bic_threshold, min_explained, max_secondary, extend,
              progress) -> Diagnosis:
    say = progress or (lambda s: None)
    if isinstance(dataset, (str,)) or hasattr(dataset, "__fspath__"):
        dataset = load_dataset(dataset)
    base = get_model(model) if isinstance(model, str) else model
    if base.name.count("+"):
        raise DiagnosisError(f"diagnose the base model, not an extended one ({base.name!r})")
    if not base.has_linear_part:
        raise DiagnosisError(f"model {base.name!r} has no linear part: the diagnosis needs a model varpro can identify")
    if not dataset.identification:
        raise DiagnosisError(f"dataset {dataset.name!r} has no identification records")
    if not dataset.validation:
        raise DiagnosisError(f"dataset {dataset.name!r} has no validation records: the gain cannot be measured")
    timings = {}
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
    say("screening candidate causes on the identification records' whole length")
    screen = Screen(base, base_fit.params, base_fit.input_range, dataset.identification, dataset.validation,
                    data_scale(dataset.identification), noise_sd=noise, max_rows=max_rows, seed=seed)
    result = run_screen(screen, before, max_relaxation=max_relaxation, bic_threshold=bic_threshold, progress=say)
    candidates = result["candidates"]
    chosen = decide(screen.null, candidates, bic_threshold, min_explained)
    timings["screen"] = time.perf_counter() - t1

    diag = Diagnosis(dataset=dataset, model=base.name, seed=seed, base_fit=base_fit, before=before,
                     summaries=summaries, noise_sd=noise, screen=screen, library=result["library"],
                     candidates=candidates, relaxation_variants=result["relaxation_variants"], chosen=chosen,
                     also=[], secondary_tried=[], timings=timings,
                     settings={"max_rows": max_rows, "max_relaxation": max_relaxation, "bic_threshold": bic_threshold,
                               "min_explained": min_explained})
    if chosen is None or not extend:
        timings["total"] = time.perf_counter() - t0
        return diag

    t1 = time.perf_counter()
    fit_on = [r.file for r in dataset.identification]
    ext = registered_extension(base.name, chosen.cause, chosen.hyperparameters, base.get_hyperparameters())
    say(f"identifying {ext.name} on the identification records' whole length")
    bounds = {n: list(screen.bounds_of(ext, n)) for n in ("creep_time", "damping_ratio") if n in ext.param_names}
    rows = {p.record.file: p.rows for p in screen.parts}
    diag.extended_fit = identify_whole(ext, dataset, chosen.params, seed, fit_on, bounds, rows)
    diag.after = residuals_of_fit(diag.extended_fit, dataset)
    timings["extended_fit"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    secondary_causes(diag, max_secondary, bic_threshold, min_explained, say)
    timings["secondary"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    say(f"refitting {base.name} on the identification records' whole length (for comparison)")
    diag.base_whole_fit = identify_whole(base, dataset, base_fit.params, seed, fit_on, rows=rows)
    diag.base_whole = residuals_of_fit(diag.base_whole_fit, dataset)
    timings["base_refit"] = time.perf_counter() - t1
    timings["total"] = time.perf_counter() - t0
    return diag
