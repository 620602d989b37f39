"""The counting the accuracy reports share: a plan's cases, shares with their intervals, detection limits."""

from __future__ import annotations

import math
from operator import itemgetter

from collections import Counter

from scipy import stats

from hysbench.benchmarks.diagnosis.rules import AFTER_SELECTION
from hysbench.benchmarks.diagnosis.selection import SELECTION

from .evidence_ceiling import extension_on_kept
from .planted import NULLS, OUT_OF_VOCABULARY, VOCABULARY

PLAN_STRIDE = 100_000  # a case's seed: plan seed * PLAN_STRIDE + its index
RIGHT_SHARE = 0.95  # a detection limit: the share right at and above it
CONFIDENCE = 0.95  # the intervals on the reports' shares (Wilson score)
TOLERANCE = 0.25  # a named parameter is right within this relative error (a clip's level: of the peak-to-peak)


def confirmed_counts(rows: list[dict]) -> dict:
    """The two "never" targets, counted from the cases: nulls given a confirmed cause (the MRPIM's and the
    piezo recording's, or a user dataset's beyond its own verdict; not the virtual DEA's, whose own relaxation
    is its physics) and out-of-vocabulary effects given a confirmed vocabulary cause (not on the virtual DEA)."""
    nulls = [r for r in rows if r["kinds"][0] in NULLS and (r["base"] != "virtual-dea" or "own" in r)]
    oov = [r for r in rows if r["kinds"][0] in OUT_OF_VOCABULARY]
    return {
        "confirmed_on_nulls": sum(1 for r in nulls if r["verdict"] not in ("none", "unexplained", r.get("own"))
                                  and r["confirmed"]),
        "nulls_checked": len(nulls),
        "oov_given_confirmed_vocabulary": sum(1 for r in oov if r["verdict"] in VOCABULARY and r["confirmed"]
                                              and r["base"] != "virtual-dea" and r["verdict"] != r.get("own")),
        "oov": len(oov),
    }


def also_on_validation(rows: list[dict]) -> dict | None:
    """The causes kept under "also" checked on the validation records, split by whether the cause was planted:
    borne out, and checked (None: no row has the check)."""
    if not any("also_on_validation" in r for r in rows):
        return None
    checked = [(a, r) for r in rows for a in r.get("also_on_validation", []) if a["checked"]]
    out = {}
    for key, planted in (("planted", True), ("not_planted", False)):
        mine = [a for a, r in checked if (a["cause"] in r["kinds"]) == planted]
        out[key] = {"borne_out": sum(1 for a in mine if a["borne_out"]), "checked": len(mine)}
    out["not_checked"] = sum(1 for r in rows for a in r.get("also_on_validation", []) if not a["checked"])
    return out


def effect_label(r: dict) -> str:
    """A case's planted effects, e.g. "delay+creep"."""
    return "+".join(r["kinds"])


def detection_limit(rows: list[dict], cause: str, min_cases: int = 3) -> dict:
    """The smallest strength s such that, among single-cause cases of at least s (at least ``min_cases`` of
    them), >= 95 % are right; with the range of strengths drawn (None without cases)."""
    cases = sorted([r for r in rows if r["kinds"] == [cause]], key=lambda r: r["strength_pct"])
    drawn = {"cases": len(cases),
             "strengths_pct": [cases[0]["strength_pct"], cases[-1]["strength_pct"]] if cases else None}
    for i, r in enumerate(cases):
        rest = cases[i:]
        if len(rest) >= min_cases and sum(x["right"] for x in rest) >= RIGHT_SHARE * len(rest):
            return {"strength_pct": r["strength_pct"], "cases_above": len(rest),
                    "right_above": sum(x["right"] for x in rest), **drawn}
    return {"strength_pct": None, "cases_above": 0, "right_above": 0, **drawn}


def wilson_interval(k: int, n: int, level: float = CONFIDENCE) -> tuple[float, float]:
    """The Wilson score interval for a share k / n: the shares p whose score test |k - n p| / sqrt(n p (1-p))
    does not reject at ``level`` (two-sided). (nan, nan) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    z = float(stats.norm.isf((1.0 - level) / 2.0))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (0.0 if k == 0 else centre - half), (1.0 if k == n else centre + half)


def judged_parameters(rows: list[dict]) -> list[dict]:
    """The right verdicts on a vocabulary cause with named parameters: those whose parameters are judged."""
    return [r for r in rows if r["right"] and r["kinds"][0] in VOCABULARY and r["parameter_errors"]]


def plan_seed_of(rows: list[dict]) -> str:
    """The plan's seed, from the cases' seeds (``plan``: seed * PLAN_STRIDE + index)."""
    return ", ".join(str(k) for k in sorted({r["seed"] // PLAN_STRIDE for r in rows})) or "-"


def interval_text(interval) -> str:
    """ " (95 % interval a-b %)" for a share's interval (nothing if there is none)."""
    if not interval or any(v is None or math.isnan(v) for v in interval):
        return ""
    return f" ({100 * CONFIDENCE:.0f} % interval {100 * interval[0]:.1f}-{100 * interval[1]:.1f} %)"


def span_text(values, unit: str = "ms", fmt: str = ".2f") -> str:
    """"a-b ms" for a span of values, "a ms" when they are all one value."""
    lo, hi = format(min(values), fmt), format(max(values), fmt)
    return f"{lo} {unit}" if lo == hi else f"{lo}-{hi} {unit}"


def within_tolerance(errors: dict) -> bool:
    """Parameter errors (``accuracy.parameter_errors``), every one within ``TOLERANCE`` (none: not within)."""
    return bool(errors) and all(v <= TOLERANCE for v in errors.values())


def ceiling(rows: list[dict]) -> dict:
    """The vocabulary cases whose planted effect, its exact waveform as a regressor, gives held-out evidence
    (``evidence_ceiling``), and the best verdict share a rule that names causes only on such evidence could
    reach: every other case right, and among the rest only those already right (by a verdict the base gives
    anyway); the same with the vocabulary's own extensions at the planted parameters (``extension_*``), on
    top of everything the diagnosis kept (``kept_*``), and both at once, the strictest (``strict_*``,
    ``evidence_ceiling.extension_on_kept``). Empty if a vocabulary row has no ``effect_shows_evidence``; a reading
    is left out if a vocabulary row lacks its field."""
    vocab = [r for r in rows if r["kinds"][0] in VOCABULARY]
    if not vocab or any("effect_shows_evidence" not in r for r in vocab):
        return {}

    def reach(sub: list[dict], has) -> tuple[int, int, int]:
        """(cases for which ``has(row)``, of them right, right among the others)"""
        flags = [bool(has(r)) for r in sub]
        return (sum(flags), sum(r["right"] for r, f in zip(sub, flags) if f),
                sum(r["right"] for r, f in zip(sub, flags) if not f))

    others = len(rows) - len(vocab)
    seen, seen_right, unseen_right = reach(vocab, itemgetter("effect_shows_evidence"))
    out = {"vocabulary_cases": len(vocab), "with_evidence": seen, "with_evidence_right": seen_right,
           "without_evidence_right": unseen_right, "ceiling_right": others + seen + unseen_right,
           "ceiling_share": (others + seen + unseen_right) / len(rows), "by_base": {}}
    for b in dict.fromkeys(r["base"] for r in vocab):
        sub = [r for r in vocab if r["base"] == b]
        n, right, rest = reach(sub, itemgetter("effect_shows_evidence"))
        out["by_base"][b] = {"cases": len(sub), "with_evidence": n, "with_evidence_right": right,
                             "without_evidence_right": rest}
    readings = [("extension", "extension_could_show", itemgetter("extension_could_show")),
                ("kept", "shows_on_kept", itemgetter("shows_on_kept")),
                ("strict", "shows_on_kept", lambda r: extension_on_kept(r.get("effect_evidence") or {}))]
    for name, needs, has in readings:
        if all(needs in r for r in vocab):
            n, right, rest = reach(vocab, has)
            out.update({f"{name}_cases": n, f"{name}_cases_right": right, f"{name}_ceiling_right": others + n + rest,
                        f"{name}_ceiling_share": (others + n + rest) / len(rows)})
            for b, v in out["by_base"].items():
                n, right, rest = reach([r for r in vocab if r["base"] == b], has)
                v.update({f"{name}_cases": n, f"{name}_cases_right": right, f"{name}_without_right": rest})
    return {"evidence": out}


def rule_counts(rows: list[dict]) -> dict | None:
    """Per rule id, in the decision rule's order: the cases whose trace holds it (the rule decided or changed their
    verdict), of them judged right, and its outcomes counted; over the rows that hold a trace (None: no row does)."""
    traced = [r for r in rows if "trace" in r]
    if not traced:
        return None
    order = [rule.id for rule in (*SELECTION, *AFTER_SELECTION)]
    out: dict = {}
    for r in traced:
        for rule in dict.fromkeys(rule for rule, _ in r["trace"]):
            entry = out.setdefault(rule, {"cases": 0, "right": 0, "outcomes": Counter()})
            entry["cases"] += 1
            entry["right"] += bool(r["right"])
            entry["outcomes"].update(outcome for rid, outcome in r["trace"] if rid == rule)
    ranked = sorted(out, key=lambda rule: order.index(rule) if rule in order else len(order))
    rules = {rule: {**out[rule], "outcomes": dict(out[rule]["outcomes"].most_common())} for rule in ranked}
    return {"traced": len(traced), "cases": len(rows), "never": [rule for rule in order if rule not in out],
            "rules": rules}


def rule_lines(rules: dict | None, heading: str = "##") -> list[str]:
    """How often each rule decided or changed a verdict (nothing when no row holds a trace)."""
    if not rules:
        return []
    lines = ["", f"{heading} The rules that decided", "",
             f"Each row holds its diagnosis's rule trace ({rules['traced']} of {rules['cases']} rows here): the rules "
             "that decided or changed its verdict, by the ids of docs/diagnosis.md's \"The decision rule\". A rule "
             "that decides few cases is where a simpler rule set costs least.", "",
             "| rule | cases it decided or changed | of them right | outcomes |", "|---|---|---|---|"]
    for rule, c in rules["rules"].items():
        outcomes = "; ".join(f"{k} {v}" for k, v in c["outcomes"].items())
        lines.append(f"| `{rule}` | {c['cases']} | {c['right']} | {outcomes} |")
    if rules["never"]:
        lines += ["", "Rules that decided or changed no verdict here: " + ", ".join(f"`{r}`" for r in rules["never"])
                  + "."]
    return lines
