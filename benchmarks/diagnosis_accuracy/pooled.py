"""Several accuracy plans pooled: the share right with its interval, and where the diagnosis can be trusted.

One plan of 200 cases measures the share right to about +-5 points and has only about seven single-cause
cases per cause and base, too few for a detection limit by base. Pooled over plans scored with the same
rule, the report gives per effect and base the share right (95 % Wilson interval) and, per vocabulary cause
and base, the detection limit (``shares.detection_limit``: the smallest strength above which >= 95 % of
the single-cause cases are right). A user whose plant is like one of the bases reads there what the
diagnosis can find on it, and from which strength.

A limit is a claim, chosen on the pooled plans; ``check_limits`` tests it on plans that took no part in
choosing it: their single-cause cases at or above their cause and base's limit, and how many are right.

The benchmark's ceiling (``shares.ceiling``) is pooled too: per reading of the planted effects' own held-out
evidence, the share a rule that names causes only on such evidence could reach at most, with its interval.

Command: ``hysbench accuracy pool PLAN ... [--check PLAN ...] [--report FILE.md]`` (the plans' rows read from
the row file, ``rows``).
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

from hysbench.data.files import ensure_dir, write_atomic, write_json
from hysbench.models.errors import HysbenchError

from .planted import BASES, DRIVES, NULLS, OUT_OF_VOCABULARY, RECORDED, VOCABULARY
from .rows import REPORT_KEYS, checked_rows
from .stated_limits import stated_from
from .shares import (CONFIDENCE, RIGHT_SHARE, ceiling, confirmed_counts, detection_limit, effect_label, interval_text,
                     judged_parameters, plan_seed_of, rule_counts, rule_lines, span_text, wilson_interval,
                     within_tolerance)


def _share(rows: list[dict]) -> dict:
    right = sum(bool(r["right"]) for r in rows)
    return {"cases": len(rows), "right": right, "interval": list(wilson_interval(right, len(rows)))}


def _effect_order(label: str) -> tuple:
    kinds = label.split("+")
    group = (0 if kinds[0] in VOCABULARY and len(kinds) == 1 else 1 if kinds[0] in NULLS
             else 2 if kinds[0] in OUT_OF_VOCABULARY else 3)
    return group, label


def _read_plans(plans: list[dict], seen: set, why: str = "") -> tuple[list[dict], list[dict]]:
    """(per plan its id, seed, cases, right and totals; all their cases) of stored plans (``rows.plan_rows``); a
    plan seed in ``seen`` (or given twice) raises HysbenchError (``why``: added to its message)."""
    out, rows = [], []
    for plan in plans:
        plan_rows = checked_rows(plan, REPORT_KEYS)
        seed = plan_seed_of(plan_rows)
        if seed in seen:
            raise HysbenchError(f"plan seed {seed} is given twice ({plan['id']}){why}")
        seen.add(seed)
        out.append({"plan": plan["id"], "seed": seed, "cases": len(plan_rows),
                    "right": sum(bool(r["right"]) for r in plan_rows),
                    **confirmed_counts(plan_rows), **_ceilings(plan_rows)})
        rows += plan_rows
    return out, rows


# the ceiling readings (``shares.ceiling``): its keys for the ceiling, the cases with the evidence, of them right,
# and right without it; the label
_READINGS = (("ceiling_right", "with_evidence", "with_evidence_right", "without_evidence_right",
              "its waveform, on top of the base or the named cause"),
             ("extension_ceiling_right", "extension_cases", "extension_cases_right", "extension_without_right",
              "the vocabulary's extension at the planted values (a relaxation, delay or mode; other effects by their "
              "waveform), on top of the base or the named cause"),
             ("kept_ceiling_right", "kept_cases", "kept_cases_right", "kept_without_right",
              "1, and on top of everything the diagnosis kept by its waveform or extension"),
             ("strict_ceiling_right", "strict_cases", "strict_cases_right", "strict_without_right",
              "2, and on top of everything the diagnosis kept by the same rule (the strictest)"))


def _ceilings(rows: list[dict]) -> dict:
    """A plan's ceiling readings (``shares.ceiling``: cases right at best), those its rows hold."""
    e = ceiling(rows).get("evidence", {})
    return {q[0]: e[q[0]] for q in _READINGS if q[0] in e}


def pooled_ceiling(rows: list[dict]) -> dict:
    """``shares.ceiling`` over the pooled cases, each reading with its interval; empty if a plan lacks them."""
    e = ceiling(rows).get("evidence")
    if not e:
        return {}
    return {**e, "intervals": {q[0]: list(wilson_interval(e[q[0]], len(rows))) for q in _READINGS if q[0] in e}}


def check_limits(limits: dict, rows: list[dict]) -> dict:
    """Detection limits (per cause and base, ``pool``'s) checked on other plans' cases: per cause and base with
    a limit, the single-cause cases at or above it, how many are right (the limit claims >= ``RIGHT_SHARE``)
    with the interval, and the cases below it; and the same summed over every cause and base."""
    out, above_all, right_all = {}, 0, 0
    for cause, per in limits.items():
        for base, q in per.items():
            if q["strength_pct"] is None:
                continue
            cases = [r for r in rows if r["kinds"] == [cause] and r["base"] == base]
            above = [r for r in cases if r["strength_pct"] >= q["strength_pct"]]
            right = sum(bool(r["right"]) for r in above)
            interval = wilson_interval(right, len(above))
            out.setdefault(cause, {})[base] = {
                "limit_pct": q["strength_pct"], "cases": len(cases), "above": len(above), "right_above": right,
                "interval": list(interval), "holds": bool(above) and interval[1] >= RIGHT_SHARE,
                "below": len(cases) - len(above), "right_below": sum(bool(r["right"]) for r in cases) - right}
            above_all, right_all = above_all + len(above), right_all + right
    return {"by_cause_and_base": out, "above": above_all, "right_above": right_all,
            "interval": list(wilson_interval(right_all, above_all))}


def pool(plans: list[dict], check: list[dict] | None = None) -> dict:
    """Several stored plans (``rows.plan_rows``) pooled: per plan its seed, cases and verdicts right; over all of them the
    share right with its interval (the cases taken as independent draws from one design; pool plans scored
    with the same rule), per effect and base and per base and drive the share right, and per vocabulary
    cause and base the detection limit; with ``check``, those limits checked on these other plans
    (``check_limits``). Raises HysbenchError for a plan without rows or given twice (also: both pooled and
    checked, which would not be held out)."""
    seen: set = set()
    plans, rows = _read_plans(plans, seen)
    checked = _read_plans(check, seen, ": a plan pooled for the limits cannot check them") if check else None
    cases, right = sum(p["cases"] for p in plans), sum(p["right"] for p in plans)
    by_effect, by_drive = defaultdict(lambda: defaultdict(list)), defaultdict(lambda: defaultdict(list))
    for r in rows:
        by_effect[effect_label(r)][r["base"]].append(r)
        by_drive[r["base"]][r["drive"]].append(r)
    bases = [b for b in BASES if any(r["base"] == b for r in rows)]
    bases += list(dict.fromkeys(r["base"] for r in rows if r["base"] not in BASES))  # users' datasets
    judged = judged_parameters(rows)
    limits = {c: {b: detection_limit([r for r in rows if r["base"] == b], c) for b in bases} for c in VOCABULARY}
    within = sum(bool(r["parameters_within"]) for r in judged)
    leads = [r["own_lead_s"] for r in rows if r.get("own_lead_s") is not None]
    alone = sum(within_tolerance(r.get("parameter_errors_planted_alone") or r["parameter_errors"]) for r in judged)
    return {
        "plans": plans, "cases": cases, "right": right, "right_share": right / cases if cases else math.nan,
        "right_interval": wilson_interval(right, cases), **confirmed_counts(rows),
        "parameters_judged": len(judged), "parameters_within": within,
        "parameters_within_interval": wilson_interval(within, len(judged)),
        **({"parameters_within_planted_alone": alone, "own_leads_s": leads} if leads else {}),
        "bases": bases,
        "by_effect_and_base": {e: {b: _share(v) for b, v in per.items()}
                               for e, per in sorted(by_effect.items(), key=lambda kv: _effect_order(kv[0]))},
        "by_base_and_drive": {b: {d: _share(by_drive[b][d]) for d in (*DRIVES, RECORDED) if by_drive[b][d]} for b in bases},
        "detection_limits": limits, "ceiling": pooled_ceiling(rows),
        **({"rules": rules} if (rules := rule_counts(rows)) else {}),  # rows that hold their rule traces
        **({"checked": {"plans": checked[0], "all_cases": _share(checked[1]),
                        **confirmed_counts(checked[1]),
                        **check_limits(limits, checked[1])}} if checked else {}),
    }


def _cell(q: dict | None) -> str:
    if not q or not q["cases"]:
        return "-"
    lo, hi = q["interval"]
    return f"{q['right']}/{q['cases']} ({100 * q['right'] / q['cases']:.0f} %, {100 * lo:.0f}-{100 * hi:.0f})"


def _limit_cell(q: dict) -> str:
    if not q["cases"]:
        return "-"
    drawn = f"drawn {q['strengths_pct'][0]:.3g}-{q['strengths_pct'][1]:.3g}"
    if q["strength_pct"] is None:
        return f"not reached ({q['cases']} case{'s' if q['cases'] > 1 else ''}; {drawn})"
    right = f"{q['right_above']} of {q['cases_above']} right"
    if q["cases_above"] == q["cases"]:  # >= 95 % right down to the weakest drawn: the limit is at most that
        return f"**<= {q['strength_pct']:.3g}** (every case at or above it: {right}; {drawn})"
    return f"**{q['strength_pct']:.3g}** ({q['cases_above']} of {q['cases']} cases at or above it, {right}; {drawn})"


def pooled_markdown(p: dict) -> str:
    readings = [r[0] for r in _READINGS if all(r[0] in q for q in p["plans"])]
    lines = ["| plan seed | cases | right | share |" + "".join(f" ceiling {i + 1} |" for i in range(len(readings))),
             "|---|---|---|---|" + "---|" * len(readings)]
    lines += [f"| {q['seed']} | {q['cases']} | {q['right']} | {100 * q['right'] / q['cases']:.1f} % |"
              + "".join(f" {q[k]} |" for k in readings) for q in p["plans"]]
    lines += ["", f"Pooled over {len(p['plans'])} plans: {p['right']} / {p['cases']} = "
              f"**{100 * p['right_share']:.1f} %**{interval_text(p['right_interval'])}; confirmed causes on "
              f"nulls {p['confirmed_on_nulls']} of {p['nulls_checked']}, out-of-vocabulary effects given a confirmed "
              f"vocabulary cause {p['oov_given_confirmed_vocabulary']} of {p['oov']}."]
    if p.get("parameters_judged"):
        lines[-1] += (f" Parameters of right verdicts within 25 %: {p['parameters_within']} / {p['parameters_judged']}"
                      f" = **{100 * p['parameters_within'] / p['parameters_judged']:.1f} %**"
                      f"{interval_text(p['parameters_within_interval'])}.")
        if p.get("own_leads_s"):
            positive = [1e3 * v for v in p["own_leads_s"] if v > 0]
            lines[-1] += (f" A delay on a base other than the Table 2 MRPIM is judged against the planted delay less "
                          f"the base's own lead on the base model (measured in {len(p['own_leads_s'])} cases, positive "
                          f"in {len(positive)}" + (f": {span_text(positive)}" if positive else "")
                          + f"); against the planted delay alone {p['parameters_within_planted_alone']} / "
                          f"{p['parameters_judged']} within 25 %.")
    if not p.get("by_effect_and_base"):
        return "\n".join(lines) + "\n"
    bases = p["bases"]
    lines += ["", f"### Right verdicts by planted effect and base (right/cases, share, {100 * CONFIDENCE:.0f} % "
                  "interval)", "", "| effect | " + " | ".join(bases) + " |", "|---" * (len(bases) + 1) + "|"]
    lines += [f"| {e} | " + " | ".join(_cell(per.get(b)) for b in bases) + " |"
              for e, per in p["by_effect_and_base"].items()]
    drives = [d for d in (*DRIVES, RECORDED) if any(d in per for per in p["by_base_and_drive"].values())]
    lines += ["", "### Right verdicts by base and drive", "", "| base | " + " | ".join(drives) + " |",
              "|---" * (len(drives) + 1) + "|"]
    lines += [f"| {b} | " + " | ".join(_cell(per.get(d)) for d in drives) + " |"
              for b, per in p["by_base_and_drive"].items()]
    lines += ["", "### Detection limits by base (single-cause cases; strength: rms of the planted effect over the "
                  "identification records, % of the output's peak-to-peak; limit: the smallest strength above "
                  "which >= 95 % of the cases, at least 3, are right; <=: so down to the weakest drawn)", "",
              "| cause | " + " | ".join(bases) + " |", "|---" * (len(bases) + 1) + "|"]
    lines += [f"| {c} | " + " | ".join(_limit_cell(per[b]) for b in bases) + " |"
              for c, per in p["detection_limits"].items()]
    lines += _pooled_ceiling_lines(p)
    lines += rule_lines(p.get("rules"), "###")
    if "checked" in p:
        lines += ["", *_checked_lines(p["checked"])]
    return "\n".join(lines) + "\n"


def _pooled_ceiling_lines(p: dict) -> list[str]:
    e = p.get("ceiling")
    if not e:
        return []
    n = p["cases"]
    lines = ["", "### The benchmark's ceiling, pooled (the readings numbered as in the plan table)", "",
             "Per vocabulary case, whether the planted effect gives held-out evidence by itself, by the diagnosis's "
             "own test (each plan's report says how). A rule that names causes only on held-out evidence is right "
             "at most in every null and out-of-vocabulary case, every vocabulary case with that evidence, and "
             "those without it that it gets right anyway (a verdict the base gives). The first reading is generous "
             "(for a delay, mode or clip the waveform is the true output transformed, so it carries part of the "
             "base's own misfit); those on top of what was kept err low (it was fitted with the effect present, and "
             "another choice of secondary cause might have left room for the planted one).", "",
             "| reading: the effect shows on held-out records as | vocabulary cases with it | of them right | ceiling | "
             f"{100 * CONFIDENCE:.0f} % interval |", "|---|---|---|---|---|"]
    readings = [(i + 1, q) for i, q in enumerate(_READINGS) if q[0] in e]
    for i, (k, cases, right, _, label) in readings:
        lo, hi = e["intervals"][k]
        lines.append(f"| {i}. {label} | {e[cases]} of {e['vocabulary_cases']} | {e[right]} | "
                     f"**{e[k]} / {n} = {100 * e[k] / n:.1f} %** | {100 * lo:.1f}-{100 * hi:.1f} % |")
    lines += ["", f"Right by the diagnosis: {p['right']} / {n} = {100 * p['right_share']:.1f} %; "
                  "the target is 90 %."]
    lines += ["", "By base, the vocabulary cases right and at most right by each reading:", "",
              "| base | vocabulary cases | right | " + " | ".join(f"reading {i}" for i, _ in readings) + " |",
              "|---|---|---|" + "---|" * len(readings)]
    for b, v in e["by_base"].items():
        right = v["with_evidence_right"] + v["without_evidence_right"]
        lines.append(f"| {b} | {v['cases']} | {right} | "
                     + " | ".join(str(v[cases] + v[rest]) for _, (_, cases, _, rest, _) in readings) + " |")
    return lines


def _checked_lines(c: dict) -> list[str]:
    seeds = ", ".join(q["seed"] for q in c["plans"])
    n = sum(q["cases"] for q in c["plans"])
    lines = [f"### The detection limits checked on held-out plans (seed{'s' if len(c['plans']) > 1 else ''} "
             f"{seeds}, {n} cases, none pooled above)", "",
             f"Each limit above claims that >= {100 * RIGHT_SHARE:.0f} % of the single-cause cases at or above it "
             "are right. Below, the cases at or above each limit in plans that took no part in choosing it. Holds: "
             f"the {100 * CONFIDENCE:.0f} % interval of their share right reaches {100 * RIGHT_SHARE:.0f} %.", "",
             "| cause | base | limit | cases at or above it: right | share (95 % interval) | holds | below it: right |",
             "|---|---|---|---|---|---|---|"]
    for cause, per in c["by_cause_and_base"].items():
        for base, q in per.items():
            share = (f"{100 * q['right_above'] / q['above']:.0f} % ({100 * q['interval'][0]:.0f}-"
                     f"{100 * q['interval'][1]:.0f})" if q["above"] else "-")
            holds = ("-" if not q["above"] else "yes" if q["holds"] else f"**no** (below {100 * RIGHT_SHARE:.0f} %)")
            below = f"{q['right_below']} of {q['below']}" if q["below"] else "-"
            lines.append(f"| {cause} | {base} | {q['limit_pct']:.3g} | {q['right_above']} of {q['above']} | {share} | "
                         f"{holds} | {below} |")
    if c["above"]:
        lines += ["", f"Every cause and base with a limit: {c['right_above']} of {c['above']} cases at or above "
                      f"their limit right = **{100 * c['right_above'] / c['above']:.1f} %**"
                      f"{interval_text(c['interval'])}."]
    a = c["all_cases"]
    lines += ["", f"Every case of these plans, at any strength: {a['right']} / {a['cases']} right = "
                      f"**{100 * a['right'] / a['cases']:.1f} %**{interval_text(a['interval'])}; confirmed causes "
                      f"on nulls {c['confirmed_on_nulls']} of {c['nulls_checked']}, out-of-vocabulary effects given "
                      f"a confirmed vocabulary cause {c['oov_given_confirmed_vocabulary']} of {c['oov']}."]
    return lines


def write_pooled(p: dict, report: str | Path, title: str = "Accuracy of `hysbench diagnose`, plans pooled",
                 note: str = "", command: str = "") -> None:
    """The pooled report as markdown (``report``) and JSON (same name, .json), each written whole; under the
    title the plans pooled and checked, ``command`` (the one that writes it) and ``note``."""
    report = Path(report)
    ensure_dir(report.parent)
    pooled = f"Plans pooled: {plan_span([q['plan'] for q in p['plans']])} ({p['cases']} cases)"
    if "checked" in p:
        pooled += (f"; the detection limits checked on {plan_span([q['plan'] for q in p['checked']['plans']])}, "
                   "pooled nowhere above")
    head = [f"# {title}", "", pooled + "." + (f" Command: `{command}`." if command else ""), "",
            "The cases are taken as independent draws from one design; what counts as right is stated in each "
            "plan's report (`hysbench accuracy report PLAN`).", ""]
    if any(q["plan"].startswith("within-limits-") for q in p["plans"]):
        source = stated_from()
        head += [f"Each vocabulary effect is drawn at or above its stated limit (stated from the plans "
                 f"{plan_span(source['plans'])}: `hysbench accuracy limits`, stated_limits.json) and planted only on "
                 "a base that has one. The detection limits below are these plans' own, not the stated ones.", ""]
    head += [note.rstrip(), ""] if note else []
    write_json(report.with_suffix(".json"), {**p, "command": command})
    write_atomic(report, "\n".join(head) + "\n" + pooled_markdown(p))


def plan_span(ids: list[str]) -> str:
    """Plan ids with runs of consecutive seeds of one design shortened: ``balanced-35..44, within-limits-63``."""
    out, run = [], []
    for pid in ids + [None]:
        name, _, seed = (pid or "").rpartition("-")
        if run and pid is not None and seed.isdigit() and name == run[-1][0] and int(seed) == run[-1][1] + 1:
            run.append((name, int(seed)))
            continue
        if run:
            out.append(f"{run[0][0]}-{run[0][1]}" + (f"..{run[-1][1]}" if len(run) > 1 else ""))
            run = []
        if pid is None:
            break
        if seed.isdigit() and name:
            run = [(name, int(seed))]
        else:
            out.append(pid)
    return ", ".join(out)
