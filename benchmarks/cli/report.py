"""``hysbench report NAME``: regenerate one of the report files under results/.

Reports: ``identification`` (every identifier on MRPIM and classical P-I),
``baselines`` (the baselines in the layout of the paper's Tables 3 and 4),
``virtual-dea`` (the virtual DEA against the paper's figures), ``bouc-wen``
(the Bouc-Wen benchmark's league table with hysbench's models), ``amplitude``
(the virtual DEA's best fits driven beyond their identified voltage range) and
``calibrate-virtual-dea`` (re-run the calibration of the virtual DEA's
parameters; prints the parameter set). Adding a report is one entry in
``REPORTS``: a help line, an ``add_arguments`` and a ``run`` function.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hysbench.benchmarks.reports import amplitude, baselines, bouc_wen, identification, virtual_dea
from hysbench.data import calibrate_virtual_dea as calibration
from hysbench.data.virtual_dea import DEFAULT_SEED

from .common import CommandError, OneLineParser, add_dataset_argument, add_seed_argument, comma_list, dataset_paths, positive_int

EXAMPLE = "hysbench report identification data/virtual_dea --out results"


def _out_folder(parser):
    parser.add_argument("--out", default="results", help="output folder (default results/)")


def _identification_arguments(parser):
    add_dataset_argument(parser)
    _out_folder(parser)
    add_seed_argument(parser)


def _baselines_arguments(parser):
    add_dataset_argument(parser)
    parser.add_argument("--out", default="results/baselines.md", help="output file, or a folder to write baselines.md in (default results/baselines.md)")
    add_seed_argument(parser)
    parser.add_argument("--models", help="comma-separated models (default: the five baselines, classical-pi, mrpim)")
    parser.add_argument("--methods", help="comma-separated methods tried per model (default: varpro)")


def _virtual_dea_arguments(parser):
    _out_folder(parser)
    add_seed_argument(parser, default=DEFAULT_SEED, what="the sensor noise")


def _bouc_wen_arguments(parser):
    parser.add_argument("dataset", metavar="DATASET", nargs="?", default=str(bouc_wen.DEFAULT_DATASET),
                        help="the Bouc-Wen benchmark's folder (default ../shared/datasets/bouc_wen_benchmark)")
    _out_folder(parser)
    add_seed_argument(parser)


def _amplitude_arguments(parser):
    parser.add_argument("--results", default="results",
                        help="the output folder of `hysbench run` whose cells/ are read; the report is written there "
                             "(default results/)")


def _amplitude(args) -> int:
    results = Path(args.results)
    if not (results / "cells").is_dir():
        raise CommandError(f"{results}: no cells/ folder (run `hysbench run --out {results}` first)")
    if not amplitude.best_cells(results):
        raise CommandError(f"{results}/cells: no finished cell identified on the dataset {amplitude.IDENTIFIED_ON}")
    print(f"wrote {amplitude.write(results)}")
    return 0


def _calibration_arguments(parser):
    parser.add_argument("--start", choices=("issue", "perturbed"), default="issue",
                        help="start from the known-good starting set, or from it perturbed (default: issue)")
    parser.add_argument("--max-nfev", type=positive_int, default=30, help="residual evaluations (default 30)")


def _calibrate(args) -> int:
    start = calibration.ISSUE_START if args.start == "issue" else calibration.perturbed(calibration.ISSUE_START)
    print(f"start:  {calibration.describe(start)}")
    r = calibration.calibrate(start, args.max_nfev)
    figs = r["figures"]
    print(f"found:  {calibration.describe(r['found'])}")
    print(f"final (3 significant digits): {calibration.describe(r['final'])}")
    print(f"  p2p change 0.02->1 Hz {figs['p2p_change_pct']:+.2f} %, width change {figs['width_change_pct']:+.2f} %, "
          f"creep transition at 0.1 Hz {figs['creep_transition_s'][0.1]:.0f} s, "
          f"max displacement {figs['max_displacement_mm']:.2f} mm")
    print("  p2p (mm):   " + ", ".join(f"{f:g} Hz {v:.3f}" for f, v in figs["p2p_mm"].items()))
    print("  width (mm): " + ", ".join(f"{f:g} Hz {v:.3f}" for f, v in figs["width_mm"].items()))
    ok = calibration.meets_targets(figs)
    print("  targets met: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in ok.items()))
    print(f"  {r['evaluations']} parameter sets simulated in {r['seconds']:.0f} s ({r['status']})")
    p = r["final"]
    print("\nDEAParameters(mu={!r}, J={!r}, eta_v={!r}, mu_k={!r}, tau_k={!r})".format(
        p.mu, p.J, p.eta_v, p.mu_k, p.tau_k))
    return 0 if all(ok.values()) else 1


# name -> (help, add_arguments, run)
REPORTS = {
    "identification": ("every identifier on MRPIM and classical P-I (results/identification.md)",
                       _identification_arguments,
                       lambda a: identification.write_report(dataset_paths(a.dataset)[0], Path(a.out), a.seed)),
    "baselines": ("the baselines in the layout of the paper's Tables 3 and 4 (results/baselines.md)",
                  _baselines_arguments,
                  lambda a: baselines.write_report(dataset_paths(a.dataset)[0], Path(a.out), a.seed,
                                                   comma_list(a.models, "--models"),
                                                   comma_list(a.methods, "--methods"))),
    "virtual-dea": ("the virtual DEA against the paper's figures (results/virtual_dea.md)",
                    _virtual_dea_arguments, lambda a: virtual_dea.write_report(Path(a.out), a.seed)),
    "bouc-wen": ("the Bouc-Wen benchmark's league table with hysbench's models (results/bouc_wen_benchmark.md)",
                 _bouc_wen_arguments, lambda a: bouc_wen.write_report(Path(a.out), a.seed, Path(a.dataset))),
    "amplitude": ("the virtual DEA's best fits driven beyond their identified voltage range "
                  "(results/amplitude_extrapolation.md)", _amplitude_arguments, _amplitude),
    "calibrate-virtual-dea": ("re-run the calibration of the virtual DEA's parameters (prints them)",
                              _calibration_arguments, _calibrate),
}

SUMMARY = f"regenerate a report: {', '.join(REPORTS)}"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="report", metavar="NAME", parser_class=OneLineParser)
    sub.required = True
    for name, (help_text, arguments, _) in REPORTS.items():
        arguments(sub.add_parser(name, help=help_text, description=help_text,
                                 epilog=f"example (every argument at its default):\n  hysbench report {name}",
                                 formatter_class=argparse.RawDescriptionHelpFormatter))


def main(args) -> int:
    return REPORTS[args.report][2](args)
