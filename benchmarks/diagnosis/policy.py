"""The diagnosis's decision policy: every threshold that decides a verdict, in one frozen, versioned object.

``Policy()`` is the rule as documented in docs/diagnosis.md; ``Policy(z_pass=2.5)`` is a variant, passed as
``diagnose(..., policy=...)``, printed in every report and JSON and selected on the command line with
``hysbench diagnose --policy KEY=VALUE`` (``Policy.with_overrides``). Each field's meaning is its ``doc``
metadata (``Policy.described``); ``version`` changes when a field is added, removed or changes meaning.
Constants that only set numerics (grid sizes, iteration caps) stay beside the code they tune.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Iterable

from scipy import stats

from hysbench.models.errors import HysbenchError

VERSION = 1


class PolicyError(HysbenchError):
    """An unknown policy field or a value it cannot take."""


def _doc(text: str, kind: str = "share") -> dict:
    return {"doc": text, "kind": kind}


@dataclass(frozen=True)
class Policy:
    """The thresholds of the decision rule (docs/diagnosis.md, "The decision rule"). Kinds: ``share`` (a
    number in (0, 1]), ``positive`` (a number > 0), ``count`` (an integer >= 1), ``angle`` (radians > 0)."""

    version: int = field(default=VERSION, metadata=_doc("the rule these fields belong to", "version"))

    # held-out evidence (selection.evidence)
    n_blocks: int = field(default=8, metadata=_doc(
        "blocks each left-out record is cut into for the signed-rank test of the held-out log ratios", "count"))
    min_explained: float = field(default=0.01, metadata=_doc(
        "least held-out gain (share of the base's held-out sum of squares removed) a cause needs to count as "
        "evidence; also the in-sample share a fit must remove for the costlier searches to be run"))
    z_pass: float = field(default=3.0, metadata=_doc(
        "least block-test z for held-out evidence (with a gain in more than half of the records)", "positive"))
    strong_gain: float = field(default=0.10, metadata=_doc(
        "a held-out gain this large in every record is evidence whatever its z (a transient misfit); as large "
        "in all records though not in most, it marks the residual as structured"))
    z_same: float = field(default=2.0, metadata=_doc(
        "two candidates predict the held-out records as well unless one is better by at least this z "
        "(parsimony, ambiguity, redundancy)", "positive"))
    at_bound: float = field(default=0.01, metadata=_doc(
        "relative distance (log scale for log parameters) to a search bound that counts as at the bound: "
        "a parameter there is not identified"))
    min_records_check: int = field(default=3, metadata=_doc(
        "records needed before evidence is checked without the record it improves most, and before a "
        "specific part other than the best-predicting one may be named", "count"))

    # a cause that removes only part of the misfit (selection.decide, secondary)
    explain_share: float = field(default=0.5, metadata=_doc(
        "share of the base's held-out misfit beyond white noise a named cause must remove to be a verdict by "
        "itself; below it, only a specific cause is named, with the rest as unexplained remainder"))
    partial_se: float = field(default=0.25, metadata=_doc(
        "fold estimates of an identifying parameter agree if their jackknife spread is within this (relative; "
        "a clipping level relative to the output's range)"))
    same_slice: float = field(default=0.9, metadata=_doc(
        "two held-out improvements remove the same part of the misfit if their cosine is at least this"))
    structure_f: float = field(default=4.0, metadata=_doc(
        "period-to-period F ratio of the base's residual above which it is structured (then nothing passing "
        "gives unexplained, not none)", "positive"))

    # what a cause's parameters must be to keep its meaning (Screen.limit_of)
    creep_periods: float = field(default=2.0, metadata=_doc(
        "creep's time scale is at least this many of the longest drive period; a relaxation slower than "
        "creep's least time scale divided by this is compared with creep", "positive"))
    creep_limit_margin: float = field(default=1.02, metadata=_doc(
        "creep with its time scale at or below this times its least time scale is not slow (outside its "
        "meaning)", "positive"))
    max_damping: float = field(default=1.0, metadata=_doc(
        "a resonance is a mode: its damping ratio is searched up to this", "positive"))
    damping_limit_share: float = field(default=0.98, metadata=_doc(
        "a resonance with its damping ratio at or above this share of max_damping is no mode"))
    duplicate_tau_ratio: float = field(default=1.25, metadata=_doc(
        "relaxation time constants closer than this factor are one (a band-pass, not a relaxation; merged "
        "into the variant with one fewer)", "positive"))
    interference_min_cycles: float = field(default=2.0, metadata=_doc(
        "an interference completes at least this many cycles in the shortest record", "positive"))
    locked_phase: float = field(default=math.pi / 4, metadata=_doc(
        "an interference at a drive harmonic whose phases in the records agree within this is locked to the "
        "drive (a misfit, not a disturbance) ...", "angle"))
    locked_turn: float = field(default=math.pi / 16, metadata=_doc(
        "... unless it turns in phase from drive period to period by more than this (rad per period) ...",
        "angle"))
    locked_turn_z: float = field(default=4.0, metadata=_doc(
        "... and by more than this many standard errors", "positive"))
    max_clipped_slope: float = field(default=0.5, metadata=_doc(
        "where a clip cuts, the output follows the unclipped model with a slope within plus or minus this "
        "(else: not a clip)", "positive"))
    min_clipped_samples: int = field(default=3, metadata=_doc(
        "a clip's level must cut at least this many samples of the prediction", "count"))
    line_amplitude: float = field(default=0.25, metadata=_doc(
        "an interference's amplitudes fitted on the folds agree within this (relative to their mean): one line",
        "positive"))

    # held-out targets (screen.held_out_windows)
    beyond_range: float = field(default=0.05, metadata=_doc(
        "a record whose input goes beyond the other records' range by more than this share of the span is "
        "predicted only up to where it first does"))

    # causes on top of the named one (secondary)
    max_secondary: int = field(default=4, metadata=_doc(
        "most causes kept on top of the named one (also)", "count"))
    bic_threshold: float = field(default=10.0, metadata=_doc(
        "one more relaxation time constant is fitted only while it lowers BIC (effective sample size) by this "
        "much", "positive"))

    # validation (validation.borne_out)
    confirm_p: float = field(default=0.05, metadata=_doc(
        "one-sided level of the validation test: a cause is confirmed if it lowers the validation records' "
        "residual with z >= the normal quantile of 1 - confirm_p against their own noise (z_confirm)"))
    interference_amplitude_tolerance: float = field(default=0.3, metadata=_doc(
        "an interference is confirmed if its amplitude on the validation records is within this (relative)",
        "positive"))

    def __post_init__(self):
        for f in dataclasses.fields(self):
            check(f, getattr(self, f.name))

    @property
    def z_confirm(self) -> float:
        """The validation test's z threshold: the normal quantile of 1 - ``confirm_p``."""
        return float(stats.norm.isf(self.confirm_p))

    def as_dict(self) -> dict:
        """Every field, then ``z_confirm`` (derived)."""
        return {**dataclasses.asdict(self), "z_confirm": self.z_confirm}

    def changed(self) -> dict:
        """The fields that differ from ``Policy()``."""
        default = Policy()
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if getattr(self, f.name) != getattr(default, f.name)}

    def summary(self) -> str:
        """One line: the version and what differs from the default rule."""
        diff = self.changed()
        if not diff:
            return f"policy v{self.version}: the default rule (docs/diagnosis.md)"
        return (f"policy v{self.version}, changed from the default rule: "
                + ", ".join(f"{k} = {v:g}" for k, v in diff.items()))

    @classmethod
    def described(cls) -> list[tuple[str, object, str]]:
        """(name, default value, meaning) of every field, in order."""
        return [(f.name, f.default, f.metadata["doc"]) for f in dataclasses.fields(cls)]

    def with_overrides(self, assignments: Iterable[str]) -> "Policy":
        """A copy with ``KEY=VALUE`` assignments applied (``PolicyError`` for an unknown key or a bad value)."""
        fields = {f.name: f for f in dataclasses.fields(self)}
        changes = {}
        for a in assignments:
            key, sep, text = a.partition("=")
            key = key.strip().replace("-", "_")
            if not sep:
                raise PolicyError(f"--policy {a!r}: expected KEY=VALUE")
            if key not in fields or key == "version":
                raise PolicyError(f"--policy {a!r}: unknown policy field {key!r} (fields: "
                                  f"{', '.join(n for n in fields if n != 'version')})")
            f = fields[key]
            count = f.metadata["kind"] == "count"
            try:
                value = int(text) if count else float(text)
            except ValueError:
                raise PolicyError(f"--policy {a!r}: {key} takes {'an integer' if count else 'a number'}, "
                                  f"not {text.strip()!r}") from None
            changes[key] = value
        return dataclasses.replace(self, **changes)


def check(f: dataclasses.Field, value) -> None:
    kind = f.metadata["kind"]
    ok = {"version": lambda v: v == VERSION,
          "share": lambda v: 0.0 < v <= 1.0,
          "positive": lambda v: 0.0 < v < math.inf,
          "angle": lambda v: 0.0 < v <= math.pi,
          "count": lambda v: isinstance(v, int) and v >= 1}[kind]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not ok(value):
        need = {"version": f"{VERSION} (this code's rule)", "share": "a number in (0, 1]", "positive": "a number > 0",
                "angle": "an angle in (0, pi] rad", "count": "an integer >= 1"}[kind]
        raise PolicyError(f"policy field {f.name} = {value!r}: needs {need}")
