"""Every public attribute of the result objects is documented in one place, its class docstring's
``Attributes`` section, and that section names no attribute the class does not have."""

from __future__ import annotations

import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from hysbench.benchmarks.compensation.references import Reference
from hysbench.benchmarks.compensation.run import Tracking
from hysbench.benchmarks.diagnosis.result import Diagnosis
from hysbench.benchmarks.matrix.cells import CellResult
from hysbench.data.dataset import Dataset, Record
from hysbench.data.protocol import RecordScore
from hysbench.identification.fit import Fit
from hysbench.identification.posterior import Calibration, Convergence, PosteriorRun
from hysbench.models.inverse import Inversion
from hysbench.models.model_file import FittedModel

RESULTS = [Fit, RecordScore, Dataset, Record, Diagnosis, PosteriorRun, Convergence, Calibration, CellResult,
           Tracking, Reference, FittedModel, Inversion]
ROOT = Path(__file__).resolve().parents[1]


def public_attributes(cls) -> set[str]:
    """Dataclass fields and properties whose names do not start with an underscore."""
    names = {f.name for f in dataclasses.fields(cls)}
    names |= {n for n, v in inspect.getmembers(cls) if isinstance(v, property)}
    return {n for n in names if not n.startswith("_")}


def documented_attributes(cls) -> set[str]:
    """The names of the class docstring's ``Attributes`` section (``name : type`` or ``a, b : type``)."""
    doc = inspect.cleandoc(cls.__doc__ or "")
    match = re.search(r"^Attributes\n-+\n(.*)", doc, re.S | re.M)
    if not match:
        return set()
    names = set()
    for line in match.group(1).splitlines():
        entry = re.match(r"(\w+(?:, \w+)*) : \S", line)
        if entry:
            names.update(entry.group(1).split(", "))
    return names


@pytest.mark.parametrize("cls", RESULTS, ids=lambda c: c.__name__)
def test_every_public_attribute_is_documented_and_nothing_else(cls):
    public, documented = public_attributes(cls), documented_attributes(cls)
    assert sorted(public - documented) == [], "undocumented"
    assert sorted(documented - public) == [], "documented but not an attribute"


def test_the_check_sees_an_undocumented_attribute():
    @dataclasses.dataclass
    class Result:
        """A result.

        Attributes
        ----------
        a, b : float
            Two numbers.
        """

        a: float
        b: float
        c: float = 0.0

        @property
        def d(self) -> float:
            return self.a

    assert documented_attributes(Result) == {"a", "b"}
    assert public_attributes(Result) - documented_attributes(Result) == {"c", "d"}


def test_the_api_page_names_every_fit_attribute_and_only_real_ones():
    """docs/api.md's list of what a Fit holds covers every public attribute and names nothing Fit lacks."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    section = text.split("## What a `Fit` holds", 1)[1].split("The other result objects", 1)[0]
    spans = [re.fullmatch(r"([\w.]+)(\(.*\))?", span) for span in re.findall(r"`([^`]+)`", section)]
    named = {m.group(1).removeprefix("Fit.") for m in spans if m}
    named = {n for n in named if "." not in n and n != "help"}
    assert sorted(public_attributes(Fit) - named) == []
    assert sorted(n for n in named if not hasattr(Fit, n) and n not in public_attributes(Fit)
                  and n not in {"file", "frequency_hz", "role", "e_m", "e_rms"}) == []
