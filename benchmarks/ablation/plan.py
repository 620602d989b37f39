"""The variants of the ablation: MRPIM configurations, the reference, the work plan."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Sequence


from hysbench.data.dataset import Dataset
from hysbench.models import get_model
from hysbench.models.errors import HysbenchError

ORDERS = tuple(range(7))
N_OPERATORS = (3, 5, 9, 13, 17, 25)
FACTORS = ("order", "q_term", "envelopes", "n_operators")
# A difference between two variants' cross-validated e_rms counts when it exceeds
# one standard error of the paired per-frequency differences and this fraction
# of the smaller of the two.
TIE_RELATIVE = 0.02
# varpro settings: (gamma, lambda) searched from the default start and 8 Sobol
# candidates, one local search from the best. A cross-validation fit repeats
# exactly this: starting it from the full fit's optimum would let the left-out
# record steer the fold's search (the full fit saw it).
FULL_FIT_OPTIONS = {"n_candidates": 8, "n_starts": 1}
CV_FIT_OPTIONS = dict(FULL_FIT_OPTIONS)
TRIM_CHECK_RTOL = 1e-9


class AblationError(HysbenchError):
    """A dataset or setting the ablation cannot work with."""


@dataclass(frozen=True, order=True)
class Variant:
    """One MRPIM configuration."""

    order: int
    q_term: bool
    envelopes: bool
    n_operators: int

    @property
    def name(self) -> str:
        return f"o{self.order}{'-q' if self.q_term else ''}{'-env' if self.envelopes else ''}-N{self.n_operators}"

    def model(self):
        return get_model("mrpim", poly_order=self.order, q_term=self.q_term, envelopes=self.envelopes,
                         n_operators=self.n_operators)

    def with_(self, **changes) -> "Variant":
        d = {"order": self.order, "q_term": self.q_term, "envelopes": self.envelopes,
             "n_operators": self.n_operators}
        d.update(changes)
        return Variant(**d)


PAPER = Variant(4, True, True, 13)


def plan_variants(reference: Variant = PAPER, orders: Sequence[int] = ORDERS,
                  n_operators: Sequence[int] = N_OPERATORS, factors: Iterable[str] = FACTORS,
                  grid: bool = True) -> list[tuple[Variant, list[str]]]:
    """Distinct variants and the families they belong to ("order", "q_term",
    "envelopes", "n_operators": one factor varied around ``reference``; "grid":
    order x q x envelopes at the reference's N)."""
    factors = list(factors)
    unknown = [f for f in factors if f not in FACTORS]
    if unknown:
        raise AblationError(f"unknown factor(s) {', '.join(unknown)}; factors: {', '.join(FACTORS)}")
    families: dict[Variant, list[str]] = {reference: []}

    def add(v: Variant, family: str):
        fams = families.setdefault(v, [])
        if family not in fams:
            fams.append(family)

    for f in factors:
        add(reference, f)
        if f == "order":
            for k in orders:
                add(reference.with_(order=int(k)), f)
        elif f == "q_term":
            add(reference.with_(q_term=not reference.q_term), f)
        elif f == "envelopes":
            add(reference.with_(envelopes=not reference.envelopes), f)
        else:
            for n in n_operators:
                add(reference.with_(n_operators=int(n)), f)
    if grid:
        for k in orders:
            for q in (False, True):
                for e in (False, True):
                    add(Variant(int(k), q, e, reference.n_operators), "grid")
    for v in families:
        v.model()  # refuses bad settings early (ModelError)
    return list(families.items())

def frequency_groups(dataset: Dataset) -> list[tuple[str, list[str]]]:
    """(label, files) of each frequency (records without one are their own group)."""
    groups: dict[str, list[str]] = {}
    for r in dataset.records:
        label = f"{r.frequency_hz:g} Hz" if r.frequency_hz else r.file
        groups.setdefault(label, []).append(r.file)
    return list(groups.items())

def plan_tasks(variants: Sequence[Variant]) -> list[list[Variant]]:
    """Tasks, costly first (envelopes mean a nonlinear search; cost grows with N), for load balance."""
    tasks = [[v] for v in sorted((v for v in variants if v.envelopes),
                                 key=lambda v: (-v.n_operators, not v.q_term, -v.order))]
    by_n: dict[int, list[Variant]] = {}
    for v in variants:
        if not v.envelopes:
            by_n.setdefault(v.n_operators, []).append(v)
    tasks += [sorted(vs) for _, vs in sorted(by_n.items(), reverse=True)]
    return tasks
