"""The diagnosis's own measured accuracy on planted effects (``planted``), not a CI test.

``run_accuracy(n_cases)`` draws a fixed plan of cases -- each vocabulary
cause alone, two at once, the out-of-vocabulary effects, nulls with white
and AR(1) noise -- over three bases (the Table 2 MRPIM, the virtual DEA's
physics, the real piezo recording when ../shared/datasets has it) and
three drives (the protocol's sines, triangles, multisines), runs
``diagnose`` (base model MRPIM) on each, stores the rows (``rows``) and
writes the plan's report (``write_report``): the confusion matrix (true effect x
verdict), each named parameter's error, per cause the detection limit, and
the benchmark's ceiling (``evidence_ceiling``, ``shares.ceiling``).

What counts as right (stated in the report):
* one vocabulary cause: that cause named. On the virtual DEA, whose physics
  relaxes by itself, also: relaxation named and the planted cause in "also".
* two causes: one of them named.
* out of vocabulary: ``unexplained``, or ``none`` when the base model
  absorbs it (on the virtual DEA also its own relaxation); never a
  vocabulary cause.
* nulls: ``none`` (the virtual DEA: its own relaxation or ``unexplained``,
  MRPIM not being its physics; the real recording: ``none`` or
  ``unexplained``, its own misfit being unknown).
* on a user's dataset (``--on DATASET``): its own verdict, the diagnosis of
  its records as they are, is what the base gives anyway. Nulls and
  out-of-vocabulary effects: ``none``, ``unexplained`` or that verdict; one
  vocabulary cause: it is named, or that verdict (a vocabulary cause) with
  the planted cause in "also".
Parameters: relative error of each named parameter (relaxation: the named
time constant nearest the planted one; creep: the drift over the longest
record; saturation: the level's error over the output's peak-to-peak; a
delay on a base other than the Table 2 MRPIM: against the planted delay less
the base's own lead on the base model, ``own_timing``, the error against the
planted delay alone kept beside it).

Command: ``hysbench accuracy run --seed 45`` (``HEADLINE_SEED``, the plan of results/diagnosis_accuracy.md);
``hysbench accuracy run --on DATASET`` plants PATTERN's effects on a user's dataset (``plan_on``). Every plan's
rows go to one file (``rows``); ``hysbench accuracy report``, ``pool``, ``limits`` and ``again`` work on it
(benchmarks/diagnosis_accuracy/README.md).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable

import numba
import numpy as np

from hysbench.data.dataset import Dataset, load_dataset
from hysbench.data.files import ensure_dir, write_atomic, write_json
from hysbench.models.errors import HysbenchError

import hysbench.benchmarks.diagnosis
import hysbench.data
import hysbench.identification
import hysbench.models
from hysbench.benchmarks.diagnosis.diagnose import diagnose
from hysbench.benchmarks.matrix.cells import source_fingerprint
from . import planted as planted_effects
from .evidence_ceiling import effect_evidence, extension_could_show, shows_evidence, shows_on_kept
from .own_timing import needs_lead, own_lead
from .planted import (ADAPTIVE_MODE_SAMPLES, BASES, NULLS, OUT_OF_VOCABULARY, PIEZO, RECORDED, VOCABULARY,
                      piezo_available, planted_case)
from .pooled import plan_span
from .rows import PLAN_DESIGNS, REPORT_KEYS, ROWS_FILE, plan_id, plan_rows, read_plans, store_plan
from .stated_limits import in_scope, minimum_strengths, out_of_scope, stated_from
from .shares import (CONFIDENCE, PLAN_STRIDE, RIGHT_SHARE, TOLERANCE, also_on_validation, ceiling, confirmed_counts,
                     detection_limit, effect_label, interval_text, judged_parameters, plan_seed_of, rule_counts,
                     rule_lines, span_text, wilson_interval, within_tolerance)

PATTERN = ([(k,) for k in VOCABULARY for _ in range(3)] + [("null-white",)] * 2 + [("null-ar1",)] * 3
           + [(k,) for k in OUT_OF_VOCABULARY]
           + [("relaxation", "interference"), ("delay", "creep"), ("resonance", "creep"), ("saturation", "relaxation")])
HEADLINE_SEED = 45  # the plan of results/diagnosis_accuracy.md


# (base, drive) in the order the plan visits them: half MRPIM, a quarter each the virtual DEA and the real
# piezo recording (its one drive: its 1 Hz sine); two thirds of the cases on the protocol's sines; any seven
# consecutive entries hold every base and every drive
COMBINATIONS = (("mrpim", "sines"), ("virtual-dea", "triangles"), ("piezo", "sines"), ("mrpim", "multisines"),
                ("mrpim", "sines"), ("virtual-dea", "sines"), ("mrpim", "triangles"), ("piezo", "sines"),
                ("mrpim", "sines"), ("virtual-dea", "multisines"), ("mrpim", "sines"), ("piezo", "sines"))
SLOT_SPREAD = 5  # consecutive slots of one effect start this far apart in COMBINATIONS
ATTEMPT_STRIDE = 1000  # within-limits: a redraw's seed is the case's seed + this times the attempt
MAX_ATTEMPTS = PLAN_STRIDE // ATTEMPT_STRIDE - 1  # the redraws stay within the plan's seeds


def plan(n_cases: int, seed: int = 0, bases: tuple[str, ...] = BASES, design: str = "balanced") -> list[dict]:
    """A fixed plan of cases: PATTERN's effects in turn. ``balanced``: the k-th case of PATTERN's slot j takes
    COMBINATIONS[(k + SLOT_SPREAD j) mod 12], so every effect meets every base and drive. ``within-limits``: as
    balanced, but a vocabulary effect is planted only on a base where it has a stated limit (``stated_limits``)
    and is drawn at or above it (``planted_within``). A base that is not here (the piezo recording), or without a
    stated limit for the slot's effects, gives its turns to the next combination."""
    if design not in PLAN_DESIGNS:
        raise ValueError(f"unknown plan design {design!r}; choose one of {', '.join(PLAN_DESIGNS)}")
    bases = tuple(b for b in bases if b != "piezo" or piezo_available())
    out = []
    limited = design == "within-limits"
    if limited and n_cases > ATTEMPT_STRIDE:
        raise ValueError(f"a within-limits plan has at most {ATTEMPT_STRIDE} cases")

    def usable(kinds, base) -> bool:
        return base in bases and (not limited or in_scope(kinds, base))

    if not any(b in bases for b, _ in COMBINATIONS):
        raise ValueError(f"no base of {list(bases)} is available")
    for kinds in PATTERN:
        if not any(usable(kinds, b) for b, _ in COMBINATIONS):
            raise ValueError(f"no base of {list(bases)} has a stated limit for {'+'.join(kinds)}")
    for i in range(n_cases):
        slot, k = i % len(PATTERN), i // len(PATTERN)
        n = (k + SLOT_SPREAD * slot) % len(COMBINATIONS)
        while not usable(PATTERN[slot], COMBINATIONS[n][0]):
            n = (n + 1) % len(COMBINATIONS)
        base, drive = COMBINATIONS[n]
        out.append({"kinds": PATTERN[slot], "base": base, "drive": drive, "seed": seed * PLAN_STRIDE + i,
                    **({"min_strength_pct": minimum_strengths(PATTERN[slot], base)} if limited else {})})
    return out


def planted_within(case: dict) -> tuple[Dataset, dict, int, int]:
    """(dataset, truth, seed, attempts): the case planted with its seed; with ``min_strength_pct`` (a
    within-limits plan) redrawn with seed + ATTEMPT_STRIDE * a, a = 1, 2, ..., until every effect's own
    strength is at or above its minimum. HysbenchError after MAX_ATTEMPTS draws."""
    least = case.get("min_strength_pct") or {}
    for a in range(MAX_ATTEMPTS if least else 1):
        seed = case["seed"] + ATTEMPT_STRIDE * a
        ds, truth = planted_case(case["kinds"], case["base"], case["drive"], seed, dataset=case.get("dataset"))
        if all(truth["strength_by_effect_pct"][k] >= v for k, v in least.items()):
            return ds, truth, seed, a + 1
    raise HysbenchError(f"no draw of {'+'.join(case['kinds'])} on {case['base']} reached its stated limits "
                        f"{least} in {MAX_ATTEMPTS} attempts (case seed {case['seed']})")


def plan_on(n_cases: int, seed: int, dataset: Dataset, model: str = "mrpim", own: str | None = None,
            segments: int | None = None, thorough: bool = False) -> list[dict]:
    """PATTERN's effects in turn, planted on a user's dataset (its records and drives as they are; diagnosed
    with ``segments`` and ``thorough`` as ``diagnose`` takes them); ``own``: its own verdict (``own_verdict``),
    carried by every case for ``judge``."""
    return [{"kinds": PATTERN[i % len(PATTERN)], "base": dataset.name, "drive": RECORDED,
             "seed": seed * PLAN_STRIDE + i, "dataset": str(dataset.path), "model": model, "own": own,
             **({"segments": segments} if segments else {}), **({"thorough": True} if thorough else {})}
            for i in range(n_cases)]


def own_verdict(dataset: Dataset, model: str = "mrpim", segments: int | None = None, thorough: bool = False) -> dict:
    """The diagnosis of a user's dataset as it is: what the base gives anyway, before anything is planted."""
    d = diagnose(dataset, model=model, experiments=False, segments=segments, thorough=thorough)
    return {"verdict": d.cause, "also": [c.cause for c in d.also], "reason": d.verdict.reason,
            "confirmed": d.confirmed}


def parameter_errors(truth: dict, cause: str, params: dict) -> dict:
    """Relative error of each named parameter against the planted effect of the named cause."""
    e = truth["effects"].get(cause)
    if not e or not params:
        return {}
    rel = lambda a, b: abs(a - b) / abs(b) if b else math.inf  # noqa: E731
    if cause == "relaxation":
        taus = params.get("tau_s") or []
        return {"tau_s": min((rel(t, e["tau_s"]) for t in taus), default=math.inf)}
    if cause == "delay":
        return {"delay_s": rel(params["delay_s"], e["delay_s"])}
    if cause == "resonance":
        return {"natural_frequency_hz": rel(params["natural_frequency_hz"], e["natural_frequency_hz"]),
                "damping_ratio": rel(params["damping_ratio"], e["damping_ratio"])}
    if cause == "creep":
        drift = params["size"] * -math.expm1(-truth["longest_s"] / params["time_scale_s"])
        return {"drift": rel(drift, e["drift"])}
    if cause == "interference":
        return {"frequency_hz": rel(params["frequency_hz"], e["frequency_hz"]),
                "amplitude": rel(params["amplitude"], e["amplitude"])}
    if cause == "saturation":
        return {"level_over_p2p": abs(params["level"] - truth["saturation_level"]) / truth["p2p"]}
    return {}


def judge(truth: dict, verdict: str, also: list[str], own: str | None = None) -> bool:
    """Right by the rules in the module docstring; ``own``: a user's dataset's own verdict (None: a fixed base)."""
    kinds, base = truth["kinds"], truth["base"]
    if own is not None:
        anyway = ("none", "unexplained", own)
        if kinds[0] in NULLS or kinds[0] in OUT_OF_VOCABULARY:
            return verdict in anyway
        return verdict in kinds or (own in VOCABULARY and verdict == own and any(k in also for k in kinds))
    if kinds[0] in NULLS:
        if base == "virtual-dea":
            return verdict in ("relaxation", "unexplained")
        return verdict == "none" or (base == "piezo" and verdict == "unexplained")
    if kinds[0] in OUT_OF_VOCABULARY:  # never a vocabulary cause (none: the base model absorbed it)
        return verdict in ("unexplained", "none") or (base == "virtual-dea" and verdict == "relaxation")
    if verdict in kinds:
        return True
    return base == "virtual-dea" and verdict == "relaxation" and any(k in also for k in kinds)


def _validation_gain(d) -> dict:
    v = d.gain().get("validation") or {}
    return {k: v[k] for k in ("explained_whole", "explained_window", "z_whole") if k in v}


def diagnosis_code() -> str:
    """The fingerprint of the code a row depends on (the models, data layer, identifiers, the diagnosis and the
    planted effects): a plan stores it, so rows of other code are told apart."""
    return source_fingerprint((hysbench.models, hysbench.data, hysbench.identification, hysbench.benchmarks.diagnosis),
                              (planted_effects.__file__,))


def run_case(case: dict) -> dict:
    ds, truth, seed, attempts = planted_within(case)
    t0 = time.perf_counter()
    d = diagnose(ds, model=case.get("model", "mrpim"), experiments=False, segments=case.get("segments"),
                 thorough=case.get("thorough", False))
    seconds = time.perf_counter() - t0
    also = [c.cause for c in d.also]
    found = {"kinds": case["kinds"], "base": case["base"], "verdict": d.cause, "also": also}
    lead = own_lead(d.screen, truth["signals"]) if needs_lead(found) else None
    judged = with_own_lead(truth, lead)
    errors = parameter_errors(judged, d.cause, d.parameters) if d.cause in case["kinds"] else {}
    also_errors = {c.cause: parameter_errors(judged, c.cause, c.estimates) for c in d.also if c.cause in case["kinds"]}
    alone = {}
    if lead:  # the errors against the planted delay alone, for comparison
        alone = {"parameter_errors_planted_alone": parameter_errors(truth, d.cause, d.parameters)
                 if d.cause in case["kinds"] else {},
                 "also_parameter_errors_planted_alone": {c.cause: parameter_errors(truth, c.cause, c.estimates)
                                                         for c in d.also if c.cause in case["kinds"]}}
    per_effect = effect_evidence(d, truth)
    return {"kinds": list(case["kinds"]), "base": case["base"], "drive": case["drive"], "seed": seed,
            "strength_pct": truth["strength_pct"], "strength_by_effect_pct": truth["strength_by_effect_pct"],
            **({"min_strength_pct": case["min_strength_pct"], "attempts": attempts}
               if case.get("min_strength_pct") else {}),
            "effects": truth["effects"], "verdict": d.cause, "trace": [[t["rule"], t["outcome"]] for t in d.trace],
            "confirmed": d.confirmed, "validation": _validation_gain(d), "also": also,
            "ambiguous_with": [c.cause for c in d.verdict.ambiguous_with],
            "remainder": d.verdict.remainder, "dropped": d.dropped.cause if d.dropped is not None else None,
            "unexplained_check": d.unexplained_check,
            "also_on_validation": [{k: a.get(k) for k in ("cause", "checked", "borne_out", "explained_whole", "z_whole")}
                                   for a in d.also_check],
            "parameters": d.parameters, "parameter_errors": errors,
            "parameters_within": within_tolerance(errors),
            "also_parameter_errors": also_errors,
            "right": judge(truth, d.cause, also, case.get("own")), "seconds": seconds,
            "effect_evidence": per_effect, "effect_shows_evidence": shows_evidence(per_effect),
            "extension_could_show": extension_could_show(per_effect),
            "shows_on_kept": shows_on_kept(per_effect),
            **({"own_lead_s": lead} if lead is not None else {}), **alone,
            **({"own": case["own"]} if "dataset" in case else {})}


def with_own_lead(truth: dict, lead: float | None) -> dict:
    """The truth a delay's estimate is judged against: the planted delay less the base's own lead on the
    base model (``own_timing.own_lead``; None or 0: the planted delay)."""
    if not lead:
        return truth
    effects = {**truth["effects"], "delay": {**truth["effects"]["delay"],
                                             "delay_s": truth["effects"]["delay"]["delay_s"] - lead}}
    return {**truth, "effects": effects}


def summary(rows: list[dict]) -> dict:
    right = sum(r["right"] for r in rows)
    with_params = judged_parameters(rows)
    return {
        "cases": len(rows), "right": right, "right_share": right / len(rows) if rows else math.nan,
        "right_interval": wilson_interval(right, len(rows)),
        "right_via_also_unrecovered": (None if any(_via_also(r) and "also_parameter_errors" not in r for r in rows)
                                       else sum(1 for r in rows if _via_also(r) and not _also_within(r))),
        **confirmed_counts(rows),
        "parameters_within_share": (sum(r["parameters_within"] for r in with_params) / len(with_params)
                                    if with_params else math.nan),
        "parameters_judged": len(with_params),
        "parameters_within_planted_alone": sum(within_tolerance(r.get("parameter_errors_planted_alone") or r["parameter_errors"])
                                               for r in with_params),
        "own_leads_s": [r["own_lead_s"] for r in rows if "own_lead_s" in r],
        "parameters_within_interval": wilson_interval(sum(r["parameters_within"] for r in with_params),
                                                      len(with_params)),
        "named_planted": len(named := [r for r in rows if r["verdict"] in VOCABULARY and r["verdict"] in r["kinds"]]),
        "named_confirmed": sum(1 for r in named if r["confirmed"]),
        "fully_right": sum(1 for r in named if r["confirmed"] and r["parameters_within"]),
        "wrong_named": len(wrong := [r for r in rows if not r["right"] and r["verdict"] in VOCABULARY]),
        "wrong_confirmed": sum(1 for r in wrong if r["confirmed"]),
        "vocabulary_cases": len(vocab := [r for r in rows if r["kinds"][0] in VOCABULARY]),
        "named_or_ambiguous": sum(1 for r in vocab if r["right"] or set(r.get("ambiguous_with", [])) & set(r["kinds"])),
        "with_remainder": len(rem := [r for r in rows if r.get("remainder") is not None]),
        "with_remainder_right": sum(r["right"] for r in rem),
        "false_also_mrpim": sum(1 for r in rows if r["base"] == "mrpim" and set(r["also"]) - set(r["kinds"])),
        "mrpim_cases": sum(1 for r in rows if r["base"] == "mrpim"),
        "also_on_validation": also_on_validation(rows),
        "also_on_vdea_nulls": dict(Counter(a for r in rows if r["base"] == "virtual-dea" and r["kinds"][0] in NULLS
                                           for a in r["also"])),
        "vdea_nulls": sum(1 for r in rows if r["base"] == "virtual-dea" and r["kinds"][0] in NULLS),
        "vdea_null_verdicts": len(alike := [r for r in rows if _null_verdict_on_vdea(r)]),
        "vdea_null_verdicts_recovered": sum(1 for r in alike if _recovered(r)),
        "detection_limits": {c: detection_limit(rows, c) for c in VOCABULARY},
        **ceiling(rows),
        **({"rules": rules} if (rules := rule_counts(rows)) else {}),  # rows that hold their rule traces
        "seconds": sum(r["seconds"] for r in rows),
    }


def _null_verdict_on_vdea(r: dict) -> bool:
    """A single planted relaxation or delay on the virtual DEA judged right with the verdict its nulls give
    (its physics' own relaxation named, a lag under "also"): right by the rule, but no evidence of the
    planted effect unless a named time constant matches it."""
    return (r["base"] == "virtual-dea" and r["right"] and r["kinds"] in (["relaxation"], ["delay"])
            and r["verdict"] == "relaxation" and (r["kinds"] == ["relaxation"] or "delay" in r["also"]))


def _via_also(r: dict) -> bool:
    """Right only through the planted cause under "also" (the virtual DEA's own relaxation named)."""
    return r["right"] and r["base"] == "virtual-dea" and r["verdict"] not in r["kinds"] and any(
        k in r["also"] for k in r["kinds"])


def _also_within(r: dict) -> bool:
    """A planted cause under "also" with every parameter within 25 %."""
    return any(within_tolerance(e) for e in r.get("also_parameter_errors", {}).values())


def _recovered(r: dict) -> bool:
    """A planted relaxation named with its time constant within 25 %, or a planted delay under "also" within
    25 % of its value."""
    if r["kinds"] == ["relaxation"]:
        return r["parameters_within"]
    return within_tolerance(r.get("also_parameter_errors", {}).get("delay", {}))


def _machine(s: dict) -> str:
    """Where the wall time was measured: cores and the 1-min load average at the run's start and end."""
    m = s.get("machine")
    if not m:
        return "machine load not recorded"
    procs = m.get("jobs", 1)
    return (f"{procs} process{'es' if procs > 1 else ''} on a {m['cpu_count']}-core machine, 1-min load average "
            f"{m['load_start']:.1f} at the start and {m['load_end']:.1f} at the end")


def markdown(rows: list[dict], s: dict, wall_s: float, note: str = "") -> str:
    lines = ["# Accuracy of `hysbench diagnose` on planted effects", ""]
    if note:
        lines += [note, ""]
    for base, why in (s.get("missing_bases") or {}).items():
        lines += [f"**No {base} cases:** {why}; their share of the plan went to the other bases, so this plan "
                  "differs from one run with it.", ""]
    on = s.get("on")
    model = on["model"] if on else "mrpim"
    other_than_own = "a cause other than the dataset's own verdict"
    lines += [
        f"{s['cases']} cases (`{plan_command(s, rows)}`), base model {'MRPIM' if model == 'mrpim' else model}; "
        "generators `hysbench.benchmarks.diagnosis_accuracy.planted` (functional forms independent of the "
        "extensions: FFT convolution, frequency-domain delay, RK45 mode, logarithmic creep, ...). "
        f"Wall time {wall_s / 60:.1f} min ({s['seconds'] / max(s['cases'], 1):.1f} s per diagnosis; {_machine(s)}). "
        + (f"Diagnosed by code `{s['code']}` (`hysbench accuracy list` shows whether it is the installed code's)."
           if s.get("code") else "The code that diagnosed it is not recorded."), "",
        *_on_lines(on),
        *_within_limits_lines(rows, s),
        "## Targets", "",
        "| measure | measured | target |", "|---|---|---|",
        f"| verdict right | {s['right']} / {s['cases']} = **{100 * s['right_share']:.1f} %**"
        f"{interval_text(s.get('right_interval'))} | >= 90 % |",
        *([] if on else [
            f"| of them right only by the virtual DEA's own relaxation named with the planted cause under `also`, "
            f"whose parameters there are not within 25 % of the planted ones | "
            f"{'not recorded in this run' if s['right_via_also_unrecovered'] is None else s['right_via_also_unrecovered']}"
            " | - |"]),
        f"| confirmed causes on nulls ({'MRPIM and piezo bases' if not on else other_than_own}, white and AR(1)) | "
        f"**{s['confirmed_on_nulls']}** of {s['nulls_checked']} | 0 |",
        f"| out-of-vocabulary effects given a confirmed vocabulary cause "
        f"({'MRPIM and piezo bases' if not on else other_than_own}) | "
        f"**{s['oov_given_confirmed_vocabulary']}** of {s['oov']} | 0 |",
        "| parameters within 25 % (right verdicts) | " + (
            f"**{100 * s['parameters_within_share']:.1f} %** of {s['parameters_judged']}"
            f"{interval_text(s.get('parameters_within_interval'))}" if s["parameters_judged"] else
            "- (no right verdict names a planted cause's parameters)") + " | >= 90 % |",
        *([f"| of them within 25 % of the planted delay alone (the base's own lead not taken off, see Parameter "
           f"errors) | {s['parameters_within_planted_alone']} of {s['parameters_judged']} | - |"]
          if s.get("own_leads_s") else []),
        f"| the planted cause named: confirmed on validation / also every parameter within 25 % | "
        f"{s['named_confirmed']} / {s['fully_right']} of {s['named_planted']} | - |",
        f"| a wrong verdict naming a vocabulary cause: confirmed on validation | {s['wrong_confirmed']} of "
        f"{s['wrong_named']} | - |",
        f"| vocabulary effects: right, or the planted cause listed as ambiguous with the named one | "
        f"{s['named_or_ambiguous']} of {s['vocabulary_cases']} | - |",
        f"| a cause named with an unexplained remainder (it removes < half of the misfit) / of them right | "
        f"{s['with_remainder']} / {s['with_remainder_right']} | - |",
        *([] if on else [
            f"| MRPIM base: a cause listed in `also` that was not planted | {s['false_also_mrpim']} of "
            f"{s['mrpim_cases']} | - |",
            *([] if not (av := s.get("also_on_validation")) else [
                f"| causes under `also` borne out on the validation records, on top of what was kept before them: "
                f"planted / not planted (the virtual DEA's own relaxation and lag count as not planted; a clip "
                f"not checked: {av['not_checked']}) | {av['planted']['borne_out']} of {av['planted']['checked']} / "
                f"{av['not_planted']['borne_out']} of {av['not_planted']['checked']} | - |"]),
            f"| virtual DEA nulls ({s['vdea_nulls']}): causes listed in `also` (its physics: relaxation and a lag) | "
            f"{', '.join(f'{k} {v}' for k, v in sorted(s['also_on_vdea_nulls'].items())) or 'none'} | - |",
            f"| virtual DEA: a planted relaxation or delay counted right with the nulls' own verdict (relaxation, "
            f"delay under `also`) / of them the planted time constant or delay found within 25 % | "
            f"{s['vdea_null_verdicts']} / {s['vdea_null_verdicts_recovered']} | - |"]), "",
        "What counts as right: " + (
            "one vocabulary cause: it is named (virtual DEA: or its own relaxation named with the planted cause in "
            "`also`); two causes: one of them named; out of vocabulary: `unexplained` or `none` (the base model "
            "absorbed it; virtual DEA: or relaxation), never a vocabulary cause; nulls: `none` (virtual DEA: "
            "relaxation, its physics' own, or `unexplained`; real piezo: `none` or `unexplained`)." if not on else
            f"the dataset's own verdict ({on['own']['verdict']}) is what the base gives anyway. One vocabulary "
            "cause: it is named, or that verdict (if a vocabulary cause) with the planted cause in `also`; two "
            "causes: one of them named, or that verdict with one of them in `also`; out of vocabulary and nulls: "
            "`none`, `unexplained` or that verdict."), "",
        f"Intervals: {100 * CONFIDENCE:.0f} % Wilson score intervals, the cases taken as independent draws from "
        "the plan's design (one plan's share can differ from the design's by about this much; "
        "`hysbench accuracy pool` pools several plans).", "",
        "## Confusion matrix (true effect x verdict, counts)", ""]
    verdicts = ["none", "unexplained", *VOCABULARY]
    lines += ["| true \\ verdict | " + " | ".join(verdicts) + " | right |", "|---" * (len(verdicts) + 2) + "|"]
    for label in dict.fromkeys(effect_label(r) for r in rows):
        sub = [r for r in rows if effect_label(r) == label]
        c = Counter(r["verdict"] for r in sub)
        lines.append(f"| {label} | " + " | ".join(str(c.get(v, 0) or "") for v in verdicts)
                     + f" | {sum(r['right'] for r in sub)}/{len(sub)} |")
    lines += ["", "By base:", "", "| base | cases | right |", "|---|---|---|"]
    for b in dict.fromkeys(r["base"] for r in rows):
        sub = [r for r in rows if r["base"] == b]
        lines.append(f"| {b} | {len(sub)} | {sum(r['right'] for r in sub)} ({100 * np.mean([r['right'] for r in sub]):.0f} %) |")
    lines += ["", "By drive:", "", "| drive | cases | right |", "|---|---|---|"]
    for dname in dict.fromkeys(r["drive"] for r in rows):
        sub = [r for r in rows if r["drive"] == dname]
        lines.append(f"| {dname} | {len(sub)} | {sum(r['right'] for r in sub)} ({100 * np.mean([r['right'] for r in sub]):.0f} %) |")
    lines += ["", "## Parameter errors (right verdicts; relative)", ""]
    if s.get("own_leads_s"):
        leads = np.array(s["own_leads_s"]) * 1e3
        lines += ["A delay found on a base other than the Table 2 MRPIM is judged against the planted delay less the "
                  "base's own lead on the base model: the delay of the unplanted records' output at which the base "
                  "model alone fits them best (`own_timing`: the generator's shift and the base refitted, not the "
                  "delay extension; leads only). A planted delay d shows beyond the base model as about d less that "
                  f"lead. Measured in {leads.size} case(s): {span_text(leads)}.", ""]
    lines += ["| cause | parameter | cases | median error | within 25 % |", "|---|---|---|---|---|"]
    for cause in VOCABULARY:
        errs: dict[str, list] = {}
        for r in rows:
            if r["right"] and r["verdict"] == cause:
                for k, v in r["parameter_errors"].items():
                    errs.setdefault(k, []).append(math.inf if v is None else v)  # null in JSON: not computed
        for k, v in errs.items():
            lines.append(f"| {cause} | {k} | {len(v)} | {100 * float(np.median(v)):.2f} % | "
                         f"{sum(x <= TOLERANCE for x in v)}/{len(v)} |")
    lines += ["", "## Detection limits", "",
              "Strength: rms of the planted effect over the identification records, % of the output's peak-to-peak. "
              "Limit: the smallest strength above which (single-cause cases, all bases) the verdict is right in "
              f">= {100 * RIGHT_SHARE:.0f} % of the cases (at least 3).", "",
              "| cause | cases | detection limit (% of p2p) | cases above it | strengths drawn |", "|---|---|---|---|---|"]
    for cause, lim in s["detection_limits"].items():
        rng = f"{lim['strengths_pct'][0]:.3g} - {lim['strengths_pct'][1]:.3g}" if lim["strengths_pct"] else "-"
        val = f"{lim['strength_pct']:.3g}" if lim["strength_pct"] is not None else "not reached"
        lines.append(f"| {cause} | {lim['cases']} | {val} | {lim['cases_above']} | {rng} |")
    lines += _ceiling_lines(s)
    lines += rule_lines(s.get("rules"))
    lines += ["", "## Wrong verdicts", "",
              "| case | base | drive | strength % | verdict | ambiguous with | also | planted effect's own evidence |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["right"]:
            lines.append(f"| {effect_label(r)} (seed {r['seed']}) | {r['base']} | {r['drive']} | {r['strength_pct']:.3g} | "
                         f"{r['verdict']} | {', '.join(r['ambiguous_with']) or '-'} | {', '.join(r['also']) or '-'} | "
                         f"{_evidence_cell(r)} |")
    return "\n".join(lines) + "\n"


def _within_limits_lines(rows: list[dict], s: dict) -> list[str]:
    """What a within-limits plan drew (nothing for another design)."""
    if s.get("plan_design") != "within-limits":
        return []
    redraws = sum(r.get("attempts", 1) - 1 for r in rows)
    source = stated_from()
    seeds = source["seeds"]
    held_out = all(r["seed"] // PLAN_STRIDE > seeds[-1] for r in rows)
    return [f"**Within the stated limits** (`hysbench.benchmarks.diagnosis_accuracy.stated_limits`, stated from the "
            f"plans {plan_span(source['plans'])}, at least {source['min_cases']} cases at or above each): every "
            "vocabulary effect is drawn at or above its stated limit on its base (each effect's own strength; a draw "
            f"below it is drawn again with the next seed: {redraws} redraws in this plan), and a cause is planted only "
            "on a base where it has a limit. Not planted, having none: "
            + ", ".join(f"{c} on {b}" for c, b in out_of_scope())
            + ". Nulls and out-of-vocabulary effects as in the balanced plans. "
            + (f"This plan took no part in stating the limits (its seed is above {seeds[-1]})." if held_out else
               "**This plan's seed is among those the limits were stated from: it does not measure them.**"), ""]


def plan_command(s: dict, rows: list[dict]) -> str:
    """The command that runs a plan (``s``: its summary; ``rows``: its cases)."""
    seed = s.get("plan_seed", plan_seed_of(rows))
    return (f"hysbench accuracy run --seed {seed} --cases {s.get('planned_cases', s['cases'])}"
            + ("" if s.get("plan_design", "balanced") == "balanced" or s.get("on") else f" --plan {s['plan_design']}")
            + _on_options(s.get("on")))


def _on_options(on: dict | None) -> str:
    """The command's options of a run on a user's dataset ("" for the fixed bases)."""
    if not on:
        return ""
    return (f" --on {on['dataset']}" + (f" --model {on['model']}" if on["model"] != "mrpim" else "")
            + (f" --segments {on['segments']}" if on.get("segments") else "") + (" --thorough" if on.get("thorough") else ""))


def _on_lines(on: dict | None) -> list[str]:
    """The dataset a run planted its effects on, and the diagnosis of it as it is."""
    if not on:
        return []
    own = on["own"]
    return [f"Effects planted on the records of **{on['name']}** ({on['dataset']}) as they are: their drives, roles "
            "and windows, their own noise (the nulls: white or AR(1) noise added). Strengths and parameters drawn as "
            "for the fixed bases, relative to its identification output's peak-to-peak and input span (a mode on a "
            f"record longer than {ADAPTIVE_MODE_SAMPLES} samples by a fixed-step RK4)"
            f"{'; every diagnosis with --thorough' if on.get('thorough') else ''}.", "",
            f"**The dataset as it is** (nothing planted): verdict **{own['verdict']}**"
            f"{' (confirmed on validation)' if own.get('confirmed') else ''}"
            f"{', also ' + ', '.join(own['also']) if own['also'] else ''}: {own['reason']}.", ""]


def _evidence_cell(r: dict) -> str:
    ev = r.get("effect_evidence")
    if not ev:
        return "-"
    prefix = "extension_at_truth_on_"

    def label(ref: str) -> str:
        return (f"extension at planted values on {ref[len(prefix):]}" if ref.startswith(prefix)
                else f"waveform on {ref}")

    def one(ref: str, v: dict) -> str:
        z = "–" if v["z"] is None else f"{v['z']:.1f}"  # null in JSON: a non-finite z
        return (f"{label(ref)} {'yes' if v['evidence'] else 'no'} (gain {100 * v['gain']:.1f} %, z {z}, "
                f"{v['folds_improved']}/{v['n_folds']})")

    return "; ".join(f"{k}: " + ", ".join(one(ref, v) for ref, v in refs.items()) for k, refs in ev.items())


def _ceiling_lines(s: dict) -> list[str]:
    e = s.get("evidence")
    if not e:
        return []
    lines = ["", "## What the planted effects show by themselves (the benchmark's ceiling)", "",
             "Each planted effect's exact waveform (what the generator added, one free gain) added as a regressor to "
             "the base model, and to the named cause's extension when another cause is named, and scored by the "
             "diagnosis's own held-out test (leave one identification record out; gain >= 1 % in a majority of folds "
             "and block z >= 3, or >= 10 % in every fold). An extension predicts an effect at best about as well as "
             "its exact waveform (better only where refitting the base's nonlinear parameters with it also removes "
             "some of the base's own misfit), so an effect without this evidence can hardly be found by a rule that "
             "names causes on held-out evidence; a case is then right only by a verdict the base gives anyway "
             "(virtual DEA: its own relaxation). For delay, resonance and saturation the waveform is the true "
             "plant output transformed, so it also carries part of what the base model misses: a generous bound "
             "there. An estimate, not a "
             "proof: the evidence is checked against the base and the named cause only"
             + (" (the third estimate below: against everything kept)." if "kept_ceiling_right" in e else "."), "",
             "| base | vocabulary cases | effect shows evidence | of them right | no evidence | of them right |",
             "|---|---|---|---|---|---|"]
    for b, v in e["by_base"].items():
        lines.append(f"| {b} | {v['cases']} | {v['with_evidence']} | {v['with_evidence_right']} | "
                     f"{v['cases'] - v['with_evidence']} | {v['without_evidence_right']} |")
    lines.append(f"| all | {e['vocabulary_cases']} | {e['with_evidence']} | {e['with_evidence_right']} | "
                 f"{e['vocabulary_cases'] - e['with_evidence']} | {e['without_evidence_right']} |")
    lines += ["", f"Ceiling: with every null and out-of-vocabulary case right and every vocabulary case with evidence "
              f"right, **{e['ceiling_right']} / {s['cases']} = {100 * e['ceiling_share']:.1f} %** (the target is 90 %)."]
    if "extension_ceiling_right" in e:
        lines += ["", "Another estimate, with the vocabulary's own extensions: a planted relaxation, delay or mode "
                  "counts only if its extension at the planted parameters (the base's nonlinear parameters "
                  "refitted with it) gives that evidence on top of the base or of the named cause; creep, interference and clips as above. "
                  f"{e['extension_cases']} vocabulary cases (of them right {e['extension_cases_right']}); ceiling "
                  f"**{e['extension_ceiling_right']} / {s['cases']} = {100 * e['extension_ceiling_share']:.1f} %**."]
    if "kept_ceiling_right" in e:
        lines += ["", "A third estimate, on top of everything the diagnosis kept: where it kept more than the named "
                  "cause (secondary causes under \"also\", none of them planted), the effect's waveform or its "
                  "extension at the planted parameters must also give that evidence on top of all of it. It counts a "
                  "plant's own causes as the diagnosis does (the virtual DEA's lag), which the two estimates above "
                  "ignore, and errs the other way: what was kept was fitted with the effect present and may have "
                  "absorbed part of it, and another choice of secondary cause might have left room for the planted "
                  f"one. {e['kept_cases']} vocabulary cases (of them right {e['kept_cases_right']}); ceiling "
                  f"**{e['kept_ceiling_right']} / {s['cases']} = {100 * e['kept_ceiling_share']:.1f} %**."]
        if "strict_ceiling_right" in e:
            lines[-1] += (" The strictest, both at once (a relaxation, delay or mode by its extension at the planted "
                          "parameters, on top of the base or the named cause and on top of everything kept): "
                          f"{e['strict_cases']} vocabulary cases (of them right {e['strict_cases_right']}); ceiling "
                          f"**{e['strict_ceiling_right']} / {s['cases']} = {100 * e['strict_ceiling_share']:.1f} %**.")
    return lines


def missing_bases(bases: tuple[str, ...]) -> dict[str, str]:
    """Bases asked for whose data are not here, with the reason (the plan gives their cases to the others)."""
    if "piezo" in bases and not piezo_available():
        return {"piezo": f"the real piezo recording is not at {PIEZO} (../shared/datasets beside the repository)"}
    return {}


def plan_summary(plan: dict) -> dict:
    """A stored plan's summary (``summary`` of its rows) with how it was run (its meta line, ``rows``)."""
    meta = plan["meta"]
    return {**summary(plan["rows"]), "plan": plan["id"], "plan_seed": meta["seed"], "planned_cases": meta["cases"],
            "wall_s": meta.get("wall_s"), "machine": meta.get("machine"), "code": meta.get("code"),
            "missing_bases": dict(meta.get("missing_bases") or {}), "plan_design": meta["design"],
            "note": meta.get("note", ""), **({"on": meta["on"]} if meta.get("on") else {})}


def write_report(plan: dict, report: str | Path) -> dict:
    """A stored plan's report (markdown at ``report``) and its summary (the same name, .json); returns it."""
    report = Path(report)
    ensure_dir(report.parent)
    s = plan_summary(plan)
    write_json(report.with_suffix(".json"), {"summary": s})
    write_atomic(report, markdown(plan["rows"], s, s["wall_s"] or s["seconds"], s["note"]))
    return s


def _one_thread() -> None:
    numba.set_num_threads(1)  # the processes share the cores, not each process's kernels


def run_accuracy(n_cases: int = 200, seed: int = 0, rows_file: str | Path = ROWS_FILE,
                 report: str | Path | None = None, bases: tuple[str, ...] = BASES,
                 progress: Callable[[str], None] | None = None, write_every: int = 10, jobs: int = 1,
                 design: str = "balanced", dataset: str | Path | Dataset | None = None, model: str = "mrpim",
                 segments: int | None = None, thorough: bool = False) -> dict:
    """Run the plan (``plan``'s ``design``; with ``dataset``, ``plan_on`` with ``model`` as the base model and
    ``segments`` and ``thorough`` as ``diagnose`` takes them), store its rows in ``rows_file`` (replacing that
    plan's rows, ``rows.store_plan``) and write its report to ``report`` (None: none); both also every
    ``write_every`` cases, so a stopped run leaves its largest honest part, its note saying so. ``jobs`` > 1
    runs the cases in that many processes (one numba thread each); the cases are independent and seeded, so the
    rows are the same. Returns the summary. A dataset or model the diagnosis cannot work with, or a row file
    that cannot be read (``rows.read_plans``), raises HysbenchError before anything is written."""
    say = progress or (lambda s: None)
    read_plans(rows_file)  # a damaged row file is refused before any case runs (storing the plan reads it)
    with contextlib.ExitStack() as stack:
        # the workers are forked before the parent runs any numba kernel (forking after OpenMP is unsafe)
        pool = stack.enter_context(ProcessPoolExecutor(jobs, initializer=_one_thread)) if jobs > 1 else None
        on = None
        if dataset is not None:
            ds = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
            say(f"diagnosing {ds.name} as it is (its own verdict)")
            args = (ds, model, segments, thorough)
            own = pool.submit(own_verdict, *args).result() if pool else own_verdict(*args)
            say(f"its own verdict: {own['verdict']}")
            on = {"dataset": str(ds.path), "name": ds.name, "model": model, "own": own,
                  **({"segments": segments} if segments else {}), **({"thorough": True} if thorough else {})}
        rows, t0 = [], time.perf_counter()
        machine = {"cpu_count": os.cpu_count(), "load_start": os.getloadavg()[0], "jobs": jobs}
        code = diagnosis_code()
        cases = (plan_on(n_cases, seed, ds, model, own["verdict"], segments, thorough) if on
                 else plan(n_cases, seed, bases, design))
        missing = missing_bases(bases) if not on else {}
        for base, why in missing.items():
            say(f"no {base} cases: {why}")
        pid = plan_id(design, seed, on)

        def keep(note: str) -> dict:
            meta = {"design": design, "seed": seed, "cases": len(cases), "wall_s": time.perf_counter() - t0,
                    "code": code, "machine": {**machine, "load_end": os.getloadavg()[0]}, "missing_bases": missing,
                    **({"note": note} if note else {}), **({"on": on} if on else {})}
            store_plan(rows_file, pid, meta, rows)
            plan_ = {"id": pid, "meta": meta, "rows": rows}
            return write_report(plan_, report) if report is not None else plan_summary(plan_)

        try:
            for i, r in enumerate(pool.map(run_case, cases) if pool else map(run_case, cases)):
                rows.append(r)
                say(f"{i + 1}/{len(cases)} {'+'.join(r['kinds'])} {r['base']} {r['drive']}: {r['verdict']} "
                    f"({'right' if r['right'] else 'WRONG'}, {r['seconds']:.1f} s)")
                if (i + 1) % write_every == 0 and i + 1 < len(cases):
                    keep(f"Partial run: {i + 1} of {len(cases)} cases.")
        except HysbenchError as e:  # a failing case: the cases before it are kept
            if rows:
                keep(f"Stopped after {len(rows)} of {len(cases)} cases: {e}")
            raise
        return keep("")


def _case_of(row: dict, meta: dict) -> dict:
    """The case a stored row was diagnosed from (``plan``'s or ``plan_on``'s form)."""
    case = {k: row[k] for k in ("kinds", "base", "drive", "seed")}
    if "min_strength_pct" in row:
        case["min_strength_pct"] = row["min_strength_pct"]
    on = meta.get("on")
    if on:
        case.update({"dataset": on["dataset"], "model": on.get("model", "mrpim"), "own": on["own"]["verdict"],
                     **({"segments": on["segments"]} if on.get("segments") else {}),
                     **({"thorough": True} if on.get("thorough") else {})})
    return case


def verdict_changes(old: list[dict], new: list[dict]) -> list[str]:
    """Per case whose named cause, "also", "ambiguous with" or confirmation differs between two scorings of a
    plan: one line saying how."""
    def key(r: dict) -> tuple:
        return r["verdict"], r["also"], r.get("ambiguous_with", []), r.get("confirmed")

    def text(r: dict) -> str:
        verdict, also, ambiguous, confirmed = key(r)
        return (f"{verdict} (also {', '.join(also) or '-'}; ambiguous with {', '.join(ambiguous) or '-'}; "
                f"{ {True: 'confirmed', False: 'not confirmed'}.get(confirmed, 'nothing to confirm')})")

    return [f"{effect_label(a)} on {a['base']} (case seed {a['seed']}): {text(a)} -> {text(b)}"
            + ("" if a["right"] == b["right"] else (", right now" if b["right"] else ", wrong now"))
            + first_rule_changed(a, b) for a, b in zip(old, new) if key(a) != key(b)]


def first_rule_changed(old: dict, new: dict) -> str:
    """Where two scorings' rule traces part ("; first rule changed: ..."), "" if either row has no trace."""
    if "trace" not in old or "trace" not in new:
        return ""
    a, b = old["trace"], new["trace"]
    i = next((i for i in range(max(len(a), len(b))) if a[i:i + 1] != b[i:i + 1]), None)
    if i is None:
        return "; the rule trace is the same"
    entry = ["-" if i >= len(t) else f"{t[i][0]}: {t[i][1]}" for t in (a, b)]
    return f"; first rule changed: {entry[0]} -> {entry[1]}"


def again(ids: list[str], rows_file: str | Path = ROWS_FILE, jobs: int = 1,
          progress: Callable[[str], None] | None = None) -> list[dict]:
    """Every case of the stored plans ``ids`` diagnosed again with the installed code (``run_case``) and the plans'
    rows replaced, each plan stored as soon as its last case is done (the cases of all plans share ``jobs``
    processes). A within-limits row keeps its redraw count. Returns per plan {plan, right_before, right_after,
    changes} (``verdict_changes``)."""
    say = progress or (lambda m: None)
    plans = plan_rows(read_plans(rows_file), ids, rows_file, REPORT_KEYS)  # every plan read first: a missing or
    # damaged one stops before any run
    code = diagnosis_code()
    todo = [_case_of(r, p["meta"]) for p in plans for r in p["rows"]]
    done = []
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(ProcessPoolExecutor(jobs, initializer=_one_thread)) if jobs > 1 else None
        results = pool.map(run_case, todo) if pool else map(run_case, todo)
        t0 = time.perf_counter()
        for p in plans:
            load_start, rows = os.getloadavg()[0], []
            for r in p["rows"]:
                rows.append({**next(results), **({"attempts": r["attempts"]} if "attempts" in r else {})})
            meta = {**p["meta"], "wall_s": time.perf_counter() - t0, "code": code,
                    "machine": {"cpu_count": os.cpu_count(), "load_start": load_start, "load_end": os.getloadavg()[0],
                                "jobs": jobs}}
            meta.pop("note", None)
            store_plan(rows_file, p["id"], meta, rows)
            t0 = time.perf_counter()
            changes = verdict_changes(p["rows"], rows)
            done.append({"plan": p["id"], "right_before": sum(r["right"] for r in p["rows"]),
                         "right_after": sum(r["right"] for r in rows), "changes": changes})
            say(f"{p['id']}: {done[-1]['right_before']} -> {done[-1]['right_after']} right, "
                f"{len(changes)} case(s) changed (cause, also, ambiguous with or confirmation)")
            for line in changes:
                say(f"  {line}")
    return done
