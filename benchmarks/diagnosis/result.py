"""``Diagnosis``: what ``diagnose`` found, in one result object (its JSON: ``Diagnosis.to_json``)."""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field

from hysbench.data.dataset import Dataset
from hysbench.data.files import jsonable
from hysbench.identification import Fit

from .candidates import Candidate
from .causes import CAUSES
from .experiment import one_drive
from .extensions import gain, scores_by_file
from .policy import Policy
from .residuals import RecordResidual, ResidualSummary
from .screen import Screen
from .secondary import not_identified
from .rule import Verdict
from .rules import rule_text
from .validation import borne_out

FORMAT = "hysbench-diagnosis/3"  # 3: the thresholds in "policy" (not "settings"), the rule "trace"


def _plain(obj):
    """JSON fallback for numpy values."""
    return obj.tolist() if hasattr(obj, "tolist") else str(obj)


@dataclass
class Diagnosis:
    """What ``diagnose`` found, in one result object (its JSON: ``to_json``; docs/diagnosis.md).

    Attributes
    ----------
    dataset : Dataset
        The records diagnosed (own samples; cut into segments if asked).
    model : str
        The base model's registry name.
    seed : int
        The seed of the fits and of the screen's row subset.
    base_fit : Fit
        The base model identified with varpro on the identification records' scored windows.
    before : list[RecordResidual]
        The base fit's residual over every record, whole.
    summaries : list[ResidualSummary]
        Per record: noise sd, rms, whiteness of ``before``.
    noise_sd : float
        Measurement noise sd, output unit: the median over the identification records (from first differences).
    screen : Screen
        The candidate fits on a row subset of the identification records (and the ``policy``).
    library : dict
        The pysindy library screen of the base residual (``library_screen``).
    candidates : list[Candidate]
        Each cause's best candidate (relaxation: its best variant), scored held out.
    relaxation_variants : list[Candidate]
        Relaxation with each number of time constants tried.
    verdict : Verdict
        The cause named, why, and the trace of the rules that decided it.
    structure : dict
        Whether the residual repeats from period to period (``residuals.periodic_structure``).
    secondary_tried : list[Candidate]
        Causes tried on top of the named one.
    also_alternatives : list[tuple[Candidate, list[Candidate]]]
        For each cause kept under ``also``: the causes tried on top of the same part that were as good (see
        ``as_good_as``).
    slow_part : Candidate | None
        The named relaxation's slowest part replaced by creep (``slow_part``).
    experiments : list[dict]
        Suggested experiments (``experiment.suggest``).
    extended_fit : Fit | None
        The named extension identified on the identification records' whole length.
    after : list[RecordResidual]
        The extended model's residual over every record.
    base_whole_fit : Fit | None
        The base refitted on the identification records' whole length.
    base_whole : list[RecordResidual]
        That refit's residual over every record.
    interference_check : dict
        A named interference's amplitude on validation.
    unexplained_check : dict | None
        An unexplained verdict's evidence on the validation records.
    also_check : list
        Each cause under "also" on the validation records.
    timings : dict
        Wall time per step, s.
    settings : dict
        The run's settings and the records held out in part.
    chosen : Candidate | None
        The named cause's candidate (None for none or unexplained). (a property)
    cause : str
        The cause named: a cause of the vocabulary, "none" or "unexplained". (a property)
    also : list[Candidate]
        The causes kept on top of the named one, in the order kept. (a property)
    dropped : Candidate | None
        The first named cause, if the causes kept on top of it made it redundant. (a property)
    trace : list[dict]
        Every rule that decided or changed the verdict, in order (``rule.step``). (a property)
    extended_model : str | None
        The registry name of the base model extended by the named cause. (a property)
    parameters : dict
        The named cause's parameters (identified on the identification records' whole length). (a property)
    uncertainty : dict
        The named cause's parameters' jackknife uncertainty over the held-out folds. (a property)
    policy : Policy
        The decision policy every step used (the screen's). (a property)
    decision_rule : str
        The decision rule with this diagnosis's policy values (``rules.rule_text``). (a property)
    confirmed : bool | None
        Whether the named extension lowers the validation residual (whole and on the windows, against the
        base refitted the same way) by z >= ``policy.z_confirm``; an interference: by the same amplitude
        there. (a property)
    warning : str
        Why the named cause is not confirmed on the validation records ("" if it is or was not checked). (a
        property)
    one_drive_caution : str
        Under one periodic drive a delay, a lag or a mode only reshapes the response's harmonics, as a
        static nonlinearity outside the vocabulary can: said when one is named or kept ("" otherwise). (a
        property)
    """

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
    secondary_tried: list[Candidate] = field(default_factory=list)
    also_alternatives: list = field(default_factory=list)
    slow_part: Candidate | None = None
    experiments: list[dict] = field(default_factory=list)
    extended_fit: Fit | None = None
    after: list[RecordResidual] = field(default_factory=list)
    base_whole_fit: Fit | None = None
    base_whole: list[RecordResidual] = field(default_factory=list)
    interference_check: dict = field(default_factory=dict)
    unexplained_check: dict | None = None
    also_check: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    _gain: tuple | None = field(default=None, init=False, repr=False, compare=False)  # (inputs, gains)

    @property
    def chosen(self) -> Candidate | None:
        """The named cause's candidate (None for none or unexplained)."""
        return self.verdict.chosen

    @property
    def cause(self) -> str:
        """The cause named: a cause of the vocabulary, "none" or "unexplained"."""
        return self.verdict.cause

    @property
    def also(self) -> list[Candidate]:
        """The causes kept on top of the named one, in the order kept."""
        return list(self.verdict.also)

    @property
    def dropped(self) -> Candidate | None:
        """The first named cause, if the causes kept on top of it made it redundant."""
        return self.verdict.dropped

    @property
    def trace(self) -> list[dict]:
        """Every rule that decided or changed the verdict, in order (``rule.step``)."""
        return list(self.verdict.trace)

    def as_good_as(self, c: Candidate) -> list[Candidate]:
        """The causes tried on top of the same kept part that predict the held-out records as well as ``c`` (a kept
        secondary cause), less those kept as well later; empty once a backward step has replaced it."""
        alike = next((alike for kept, alike in self.also_alternatives if kept is c), [])
        return [a for a in alike if a.cause not in {k.cause for k in self.also}]

    def on_top_of(self, c: Candidate) -> str:
        """What a kept secondary cause was added to: the named cause and the ones kept before it."""
        i = next(i for i, a in enumerate(self.also) if a is c)
        return " + ".join([self.cause, *(a.cause for a in self.also[:i])])

    @property
    def extended_model(self) -> str | None:
        """The registry name of the base model extended by the named cause."""
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
        return c.kind.from_fit(dict(c.estimates), self.extended_fit.params)

    @property
    def uncertainty(self) -> dict:
        """The named cause's parameters' jackknife uncertainty over the held-out folds."""
        return self.chosen.uncertainty if self.chosen is not None else {}

    @property
    def policy(self) -> Policy:
        """The decision policy every step used (the screen's)."""
        return self.screen.policy

    @property
    def decision_rule(self) -> str:
        """The decision rule with this diagnosis's policy values (``rules.rule_text``)."""
        return rule_text(self.policy)

    def gain(self) -> dict:
        """The named extension's gain on the validation and identification records (computed once per residuals)."""
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
        """Whether the named extension lowers the validation residual (whole and on the windows, against the base
        refitted the same way) by z >= ``policy.z_confirm``; an interference: by the same amplitude there."""
        v = self.gain().get("validation")
        return borne_out(v, self.cause, self.interference_check, self.policy) if v else None

    @property
    def warning(self) -> str:
        """Why the named cause is not confirmed on the validation records ("" if it is or was not checked)."""
        if self.confirmed is not False:
            return ""
        v = self.gain()["validation"]
        return (f"the extension does not improve the validation records beyond their noise against the base model "
                f"refitted the same way (residual sum of squares removed: {100 * v['explained_whole']:.1f} % whole, "
                f"z = {v['z_whole']:.2f} against the noise, needs {self.policy.z_confirm:.3g}; "
                f"{100 * v['explained_window']:.1f} % on the windows"
                + (f"; interference amplitude there {self.interference_check.get('validation_amplitude', 0):.3g}"
                   if self.chosen.kind.disturbance else "")
                + f"): '{self.cause}' is not confirmed on data that took no part in the fit; treat it as a hypothesis")

    @property
    def one_drive_caution(self) -> str:
        """Under one periodic drive a delay, a lag or a mode only reshapes the response's harmonics, as a static
        nonlinearity outside the vocabulary can: said when one is named or kept ("" otherwise)."""
        named = list(dict.fromkeys(c for c in (self.cause, *(a.cause for a in self.also))
                                   if c in CAUSES and CAUSES[c].reshapes))
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
            "noise_sd": self.noise_sd, "records": [s.as_dict() for s in self.summaries],
            "library_screen": self.library, "null": self.screen.null.summary(),
            "candidates": [c.summary() for c in sorted(self.candidates, key=lambda c: -c.heldout_gain)],
            "relaxation_variants": [c.summary() for c in self.relaxation_variants],
            "secondary_tried": [{**c.summary(), "also": any(c is a for a in self.also)} for c in self.secondary_tried],
            "slow_part_as_creep": None if self.slow_part is None else {
                **self.slow_part.summary(), "ambiguous": any(c is self.slow_part for c in v.ambiguous_with)},
            "periodic_structure": self.structure, "decision_rule": self.decision_rule, "screen_rows": self.screen.n,
        }
        x = self.extended_fit
        extended = {"name": x.model, "hyperparameters": x.hyperparameters, "method": x.method, "params": x.params,
                    "n_params": x.n_params, "fitted_on": x.fitted_on, "notes": x.notes} if x else None
        as_good = {c.cause: alike for c in self.also if (alike := self.as_good_as(c))}
        data = {
            "format": FORMAT, "model": self.model, "dataset": self.dataset.name,
            "dataset_hash": self.dataset.content_hash(), "seed": self.seed, "policy": self.policy.as_dict(),
            "cause": self.cause, "reason": v.reason, "parameters": self.parameters, "uncertainty": self.uncertainty,
            "not_identified": v.not_identified, "ambiguous_with": [c.cause for c in v.ambiguous_with],
            "suggested_experiments": self.experiments,
            "partial": v.partial.summary() if v.partial is not None else None, "unexplained_remainder": v.remainder,
            "evidence": evidence, "extended_model": self.extended_model, "extended_fit": extended,
            "base_fit": {"method": self.base_fit.method, "params": self.base_fit.params,
                         "n_params": self.base_fit.n_params, "notes": self.base_fit.notes},
            "before": scores_by_file(self.before), "after": scores_by_file(self.after) if self.after else {},
            "base_refit_on_whole_records": scores_by_file(self.base_whole) if self.base_whole else {},
            "gain": self.gain(), "interference_check": self.interference_check,
            "confirmed_on_validation": self.confirmed, "warning": self.warning,
            "one_drive_caution": self.one_drive_caution, "unexplained_check": self.unexplained_check,
            "also_on_validation": self.also_check, "also": [c.cause for c in self.also],
            "dropped_as_redundant": None if self.dropped is None else {
                "cause": self.dropped.cause, "label": self.dropped.label, "heldout": self.dropped.heldout},
            "also_as_good": {cause: [a.cause for a in alike] for cause, alike in as_good.items()},
            "also_as_good_fits": {cause: [{"cause": a.cause, "label": a.label, "estimates": a.estimates,
                                           "heldout_gain": a.heldout_gain, "uncertainty": a.uncertainty}
                                          for a in alike] for cause, alike in as_good.items()},
            "also_not_identified": {c.cause: why for c in self.also if (why := not_identified(c))},
            "trace": self.trace, "timings_s": self.timings, "settings": self.settings,
        }
        return jsonable(json.loads(json.dumps(data, default=_plain)))
