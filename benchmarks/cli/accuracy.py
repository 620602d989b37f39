"""``hysbench accuracy ACTION``: the diagnosis accuracy study (``hysbench.benchmarks.diagnosis_accuracy``).

``run`` diagnoses a plan of planted cases and stores its rows in the row file (results/
diagnosis_accuracy_rows.jsonl.gz; a plan stored again replaces its rows) and writes its report; ``report``
rewrites a stored plan's report; ``pool`` pools stored plans (and checks their detection limits on others);
``limits`` states the detection limits from stored plans; ``again`` diagnoses stored plans again with the
installed code; ``list`` lists the stored plans. See benchmarks/diagnosis_accuracy/README.md.
"""

from __future__ import annotations

import argparse
import os

from hysbench.benchmarks.diagnosis_accuracy import accuracy, pooled, rows, stated_limits
from hysbench.data.dataset import load_dataset
from hysbench.data.files import check_output_file, shown_path
from hysbench.models import get_model

from .common import CommandError, OneLineParser, integer_at_least, nonnegative_int, positive_int

EXAMPLE = "hysbench accuracy run --seed 45 --cases 200 --jobs 2"

ROWS_DEFAULT = "results/diagnosis_accuracy_rows.jsonl.gz"
HEADLINE_REPORT = "results/diagnosis_accuracy.md"
ACTIONS = {
    "run": ("diagnose a plan of planted cases, store its rows and write its report",
            "hysbench accuracy run --seed 70 --plan within-limits --jobs 2"),
    "report": ("rewrite a stored plan's report from its rows", "hysbench accuracy report balanced-45"),
    "pool": ("pool stored plans; check their detection limits on other stored plans",
             "hysbench accuracy pool balanced-35..44 --check balanced-45..62 "
             "--report results/diagnosis_accuracy_pooled.md"),
    "limits": ("state the detection limits from stored plans (writes stated_limits.json)",
               "hysbench accuracy limits balanced-35..62"),
    "again": ("diagnose every case of stored plans again with the installed code and replace their rows",
              "hysbench accuracy again within-limits-63..65 --jobs 2"),
    "list": ("list the stored plans", "hysbench accuracy list"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", parser_class=OneLineParser)
    sub.required = True
    p = {name: sub.add_parser(name, help=text, description=text, epilog=f"example:\n  {example}",
                              formatter_class=argparse.RawDescriptionHelpFormatter)
         for name, (text, example) in ACTIONS.items()}
    for q in p.values():
        q.add_argument("--rows", default=ROWS_DEFAULT, metavar="FILE",
                       help=f"the row file every plan is stored in (default {ROWS_DEFAULT})")
    run = p["run"]
    run.add_argument("--seed", type=nonnegative_int, default=45,
                     help="the plan's seed (a non-negative integer, default 45: the headline plan)")
    run.add_argument("--cases", type=positive_int, default=200, help="cases in the plan (default 200)")
    run.add_argument("--plan", choices=("balanced", "within-limits"), default="balanced",
                     help="balanced: every effect on every base and drive (default); within-limits: each vocabulary "
                          "effect drawn at or above its stated limit, only on bases that have one")
    run.add_argument("--on", metavar="DATASET",
                     help="plant the effects on this dataset's records (a folder with dataset.toml) instead of "
                          "the fixed bases")
    run.add_argument("--model", default=None, help="with --on: the base model diagnosed (default: mrpim)")
    run.add_argument("--segments", type=integer_at_least(2), default=None, metavar="K",
                     help="with --on: cut each identification record into K records, as diagnose --segments")
    run.add_argument("--thorough", action="store_true", help="with --on: as diagnose --thorough")
    run.add_argument("--jobs", type=positive_int, default=os.cpu_count() or 1,
                     help="processes running cases at once (default: every core)")
    run.add_argument("--report", metavar="FILE.md",
                     help=f"the plan's report (and FILE.json, its summary); default {HEADLINE_REPORT} for the "
                          "headline plan, results/diagnosis_accuracy_PLAN.md for another")
    p["report"].add_argument("plan", metavar="PLAN", help="a stored plan's id (hysbench accuracy list)")
    p["report"].add_argument("--report", metavar="FILE.md", help="as for run")
    pool = p["pool"]
    pool.add_argument("plans", nargs="+", metavar="PLAN", help="stored plans' ids; NAME-A..B for a range of seeds")
    pool.add_argument("--check", nargs="+", metavar="PLAN",
                      help="check the pooled detection limits on these other stored plans (held out)")
    pool.add_argument("--report", metavar="FILE.md",
                      help="write the pooled report here (and FILE.json) instead of printing it")
    pool.add_argument("--title", default="Accuracy of `hysbench diagnose`, plans pooled", help="the report's title")
    pool.add_argument("--note", default="", help="a paragraph under the title")
    limits = p["limits"]
    limits.add_argument("plans", nargs="*", metavar="PLAN", help="stored plans' ids (default balanced-35..62)")
    limits.add_argument("--min-cases", type=positive_int, default=None,
                        help="single-cause cases at or above a limit, at least (default 20)")
    limits.add_argument("--out", metavar="FILE.json", default=None,
                        help="where to write them (default: stated_limits.json in the installed package, the file "
                             "the within-limits plans read)")
    again = p["again"]
    again.add_argument("plans", nargs="+", metavar="PLAN", help="stored plans' ids; NAME-A..B for a range of seeds")
    again.add_argument("--jobs", type=positive_int, default=os.cpu_count() or 1,
                       help="processes running cases at once (default: every core)")


def default_report(pid: str) -> str:
    """The report a plan's run or ``report`` writes by default."""
    return HEADLINE_REPORT if pid == f"balanced-{accuracy.HEADLINE_SEED}" else f"results/diagnosis_accuracy_{pid}.md"


def _say(message: str) -> None:
    print(message, flush=True)


def main(args) -> int:
    if args.action in ("run", "again"):
        check_output_file(args.rows)
    if args.action == "run":
        return _run(args)
    plans = rows.read_plans(args.rows)
    if args.action == "list":
        installed = accuracy.diagnosis_code()
        for pid, plan in plans.items():
            code = plan["meta"].get("code")
            print(f"{pid}: {len(plan['rows'])} cases, {sum(bool(r['right']) for r in plan['rows'])} right; "
                  + ("code not recorded" if not code else f"code {code}"
                     + (" (the installed code)" if code == installed else " (not the installed code)")))
        if not plans:
            print(f"no plans in {args.rows}")
        return 0
    if args.action == "report":
        report = args.report or default_report(args.plan)
        check_output_file(report)
        s = accuracy.write_report(rows.plan_rows(plans, [args.plan], args.rows, rows.REPORT_KEYS)[0], report)
        print(f"{args.plan}: {s['right']} / {s['cases']} right; report {report}")
        return 0
    if args.action == "pool":
        chosen = rows.plan_rows(plans, rows.expand(args.plans), args.rows)
        check = rows.plan_rows(plans, rows.expand(args.check), args.rows) if args.check else None
        if args.report:
            check_output_file(args.report)
        p = pooled.pool(chosen, check=check)
        if not args.report:
            print(pooled.pooled_markdown(p), end="")
            return 0
        command = " ".join(["hysbench accuracy pool", *args.plans, *(["--check", *args.check] if args.check else []),
                            "--report", args.report, *(["--rows", args.rows] if args.rows != ROWS_DEFAULT else [])])
        pooled.write_pooled(p, args.report, title=args.title, note=args.note, command=command)
        print(f"pooled {len(chosen)} plans: {p['right']} / {p['cases']} right; report {args.report}")
        return 0
    if args.action == "limits":
        ids = rows.expand(args.plans or stated_limits.STATING_PLANS)
        out = args.out or stated_limits.LIMITS_FILE
        check_output_file(out)
        data = stated_limits.state(rows.plan_rows(plans, ids, args.rows),
                                   min_cases=args.min_cases or stated_limits.MIN_CASES)
        stated_limits.write_limits(data, out)
        reached = sum(q["limit_pct"] is not None for q in data["limits"])
        print(f"{reached} of {len(data['limits'])} causes and bases have a limit; written to {shown_path(out)}")
        return 0
    done = accuracy.again(rows.expand(args.plans), args.rows, jobs=args.jobs, progress=_say)  # "again"
    print(f"{len(done)} plan(s) diagnosed again; rows replaced in {shown_path(args.rows)}")
    return 0


def _run(args) -> int:
    if (args.model is not None or args.segments is not None or args.thorough) and not args.on:
        raise CommandError("--model, --segments and --thorough go with --on (the fixed bases are scored as they are)")
    if args.on and args.plan != "balanced":
        raise CommandError("--plan goes with the fixed bases, not --on")
    if args.plan == "within-limits" and args.cases > accuracy.ATTEMPT_STRIDE:
        raise CommandError(f"a within-limits plan has at most {accuracy.ATTEMPT_STRIDE} cases")
    dataset, on = None, None
    if args.on:
        get_model(args.model or "mrpim")  # an unknown model fails here, before any work
        dataset = load_dataset(args.on)
        on = {"name": dataset.name, "model": args.model or "mrpim", "segments": args.segments,
              "thorough": args.thorough}
    report = args.report or default_report(rows.plan_id(args.plan, args.seed, on))
    check_output_file(report)
    s = accuracy.run_accuracy(args.cases, args.seed, args.rows, report, progress=_say, jobs=args.jobs,
                              design=args.plan, dataset=dataset, model=args.model or "mrpim",
                              segments=args.segments, thorough=args.thorough)
    print(f"{s['plan']}: {s['right']} / {s['cases']} right; rows in {shown_path(args.rows)}; report {report}")
    return 0
