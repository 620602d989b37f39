"""The diagnosis's decision policy: every threshold that decides a verdict, in one frozen, versioned object.

``Policy()`` is the rule of docs/diagnosis.md, whose table "The policy" gives each field's meaning in full;
``Policy(z_pass=2.5)`` is a variant (``diagnose(..., policy=...)``, ``hysbench diagnose --policy KEY=VALUE``),
printed in every report and JSON. ``version`` changes when a field is added, removed or changes meaning.
Constants that only set numerics (grid sizes, iteration caps) stay beside the code they tune.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Iterable

from scipy import stats

from hysbench.models.errors import HysbenchError
from hysbench.models.extended import DAMPING_BOUNDS

VERSION = 1
KINDS = {  # the values a field of each kind takes: (test, what it needs)
    "version": (lambda v: v == VERSION, f"{VERSION} (this code's rule)"),
    "share": (lambda v: 0.0 < v <= 1.0, "a number in (0, 1]"),
    "positive": (lambda v: 0.0 < v < math.inf, "a number > 0"),
    "angle": (lambda v: 0.0 < v <= math.pi, "an angle in (0, pi] rad"),
    "count": (lambda v: isinstance(v, int) and v >= 1, "an integer >= 1"),
    "damping": (lambda v: DAMPING_BOUNDS[0] < v <= DAMPING_BOUNDS[1], "a number in ({:g}, {:g}] (the mode's damping "
                "search range)".format(*DAMPING_BOUNDS)),
}


class PolicyError(HysbenchError):
    """An unknown policy field or a value it cannot take."""


def _field(default, kind: str, doc: str):
    return field(default=default, metadata={"doc": doc, "kind": kind})


@dataclass(frozen=True)
class Policy:
    """The thresholds of the decision rule (docs/diagnosis.md, "The decision rule"), each with its meaning
    (``doc``) and kind (``KINDS``)."""

    version: int = _field(VERSION, "version", "the rule these fields belong to")

    # held-out evidence (selection.evidence)
    n_blocks: int = _field(8, "count", "blocks each left-out record is cut into for the signed-rank test")
    min_explained: float = _field(0.01, "share", "least held-out gain (share of the base's held-out SSE removed) "
                                  "for evidence; also the in-sample share for the costlier searches")
    z_pass: float = _field(3.0, "positive", "least block-test z for held-out evidence")
    strong_gain: float = _field(0.10, "share", "a held-out gain this large in every record is evidence whatever z")
    z_same: float = _field(2.0, "positive", "two candidates predict the held-out records as well unless one is "
                           "better by at least this z")
    at_bound: float = _field(0.01, "share", "relative distance (log scale for log parameters) to a search bound "
                             "that counts as at the bound")
    min_records_check: int = _field(3, "count", "records needed before evidence is checked without its best record")

    # a cause that removes only part of the misfit (selection.decide, secondary)
    explain_share: float = _field(0.5, "share", "share of the base's held-out misfit beyond white noise a named "
                                  "cause must remove to be a verdict by itself")
    partial_se: float = _field(0.25, "share", "fold estimates of an identifying parameter agree within this")
    same_slice: float = _field(0.9, "share", "two held-out improvements remove the same part from this cosine")
    structure_f: float = _field(4.0, "positive", "period-to-period F ratio of the base's residual above which it "
                                "is structured")

    # what a cause's parameters must be to keep its meaning (Screen.limit_of)
    creep_periods: float = _field(2.0, "positive", "creep's time scale is at least this many drive periods")
    creep_limit_margin: float = _field(1.02, "positive", "creep with its time scale at or below this times its "
                                       "least time scale is not slow")
    max_damping: float = _field(1.0, "damping", "a resonance is a mode: its damping ratio is searched up to this")
    damping_limit_share: float = _field(0.98, "share", "a resonance with its damping ratio at or above this share "
                                        "of max_damping is no mode")
    duplicate_tau_ratio: float = _field(1.25, "positive", "relaxation time constants closer than this are one")
    interference_min_cycles: float = _field(2.0, "positive", "an interference completes at least this many "
                                            "cycles in the shortest record")
    locked_phase: float = _field(math.pi / 4, "angle", "an interference at a drive harmonic whose phases in the "
                                 "records agree within this is locked to the drive ...")
    locked_turn: float = _field(math.pi / 16, "angle", "... unless it turns in phase from drive period to period "
                                "by more than this (rad per period) ...")
    locked_turn_z: float = _field(4.0, "positive", "... and by more than this many standard errors")
    max_clipped_slope: float = _field(0.5, "positive", "where a clip cuts, the output follows the unclipped model "
                                      "with a slope within plus or minus this")
    min_clipped_samples: int = _field(3, "count", "a clip's level must cut at least this many samples")
    line_amplitude: float = _field(0.25, "positive", "an interference's amplitudes fitted on the folds agree "
                                   "within this (relative to their mean)")

    # held-out targets (screen.held_out_windows)
    beyond_range: float = _field(0.05, "share", "a record whose input goes beyond the other records' range by "
                                 "more than this share of the span is predicted up to there")

    # causes on top of the named one (secondary)
    max_secondary: int = _field(4, "count", "most causes kept on top of the named one (also)")
    bic_threshold: float = _field(10.0, "positive", "one more relaxation time constant is fitted only while it "
                                  "lowers BIC by this much")

    # validation (validation.borne_out)
    confirm_p: float = _field(0.05, "share", "one-sided level of the validation test (z_confirm)")
    interference_amplitude_tolerance: float = _field(0.3, "positive", "an interference is confirmed if its "
                                                     "amplitude on the validation records is within this")

    def __post_init__(self):
        for f in dataclasses.fields(self):
            ok, need = KINDS[f.metadata["kind"]]
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not ok(value):
                raise PolicyError(f"policy field {f.name} = {value!r}: needs {need}")

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
        fields = {f.name: f for f in dataclasses.fields(self) if f.name != "version"}
        changes = {}
        for a in assignments:
            key, sep, text = a.partition("=")
            key = key.strip().replace("-", "_")
            if not sep:
                raise PolicyError(f"--policy {a!r}: expected KEY=VALUE")
            if key not in fields:
                raise PolicyError(f"--policy {a!r}: unknown policy field {key!r} (fields: {', '.join(fields)})")
            count = fields[key].metadata["kind"] == "count"
            try:
                changes[key] = int(text) if count else float(text)
            except ValueError:
                raise PolicyError(f"--policy {a!r}: {key} takes {'an integer' if count else 'a number'}, "
                                  f"not {text.strip()!r}") from None
        return dataclasses.replace(self, **changes)
