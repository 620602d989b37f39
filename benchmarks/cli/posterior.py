"""``hysbench posterior DATASET``: the posterior of a model's parameters with emcee.

Writes, in ``--out`` (default results/): posterior.md (parameter table,
priors, convergence, correlations and identifiability, predictive bands),
posterior.json (``--json`` to put it elsewhere), posterior_corner.png,
posterior_predictive.png, posterior_correlation.png, posterior_trace.png, and
the chain in emcee's HDF5 backend (posterior_chain.h5, ``--chain``).

Resuming: when the chain file exists and holds a chain for the same dataset,
model, noise model, walkers, seed, moves and priors, the run continues it (up
to ``--steps`` in total, stopping early as usual); for other settings it is
refused unless ``--restart``. An interrupted run (Ctrl-C) keeps every step
sampled so far. See ``hysbench.identification.posterior`` for the method.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from hysbench.benchmarks.cli.common import (add_dataset_argument, add_seed_argument, dataset_paths, nonnegative_int,
                                           positive_int)

from hysbench.data.files import check_output_dir, check_output_file, ensure_dir, write_atomic, write_json
from hysbench.data.dataset import load_dataset
from hysbench.models import get_model

from hysbench.identification.errors import IdentificationError
from hysbench.identification.posterior import (DISCREPANCY_KINDS, MOVES, NOISE_MODELS, predictive,
                                               predictive_coverage, sample_posterior)
from hysbench.benchmarks.reports.posterior import (corner_figure, correlation_figure, identifiability, predictive_figure,
                               render_markdown, trace_figure)

EXAMPLE = "hysbench posterior data/virtual_dea --walkers 16 --steps 8000 --out results"


def _burn(text: str):
    return "auto" if text == "auto" else nonnegative_int(text)


def _non_negative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not v >= 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return v


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_dataset_argument(parser)
    parser.add_argument("--model", default="mrpim", help="registry name of a partly linear model (default mrpim)")
    parser.add_argument("--noise", default="ar1", choices=NOISE_MODELS,
                        help="residual noise model: ar1 (default) or iid (independent, for contrast)")
    parser.add_argument("--discrepancy", default="relaxation", choices=DISCREPANCY_KINDS,
                        help="model discrepancy added to the model's output: relaxation (default; first-order "
                             "relaxations of the input, integrated out) or none")
    parser.add_argument("--no-calibration", action="store_true",
                        help="predictive scale 1 instead of the one set by in-sample and leave-one-record-out coverage")
    parser.add_argument("--walkers", type=positive_int, default=16, help="emcee walkers (even, default 16)")
    parser.add_argument("--steps", type=positive_int, default=8000,
                        help="most steps in total (default 8000); sampling stops earlier once converged "
                             "with --min-ess effective samples, unless --fixed-steps")
    parser.add_argument("--min-ess", type=_non_negative_float, default=1000.0,
                        help="effective samples every parameter needs before stopping early (default 1000)")
    parser.add_argument("--fixed-steps", action="store_true", help="run exactly --steps steps")
    parser.add_argument("--burn", type=_burn, default="auto",
                        help="burn-in steps, or auto (default: the larger of 5 autocorrelation times and the step "
                             "where the walkers' median log posterior reaches its second-half median, plus 2 "
                             "autocorrelation times)")
    parser.add_argument("--moves", default="de", choices=sorted(MOVES),
                        help="emcee moves: de (differential evolution 0.8 + snooker 0.2, default) or stretch")
    add_seed_argument(parser, what="the sampler and the predictive draws")
    parser.add_argument("--draws", type=positive_int, default=200,
                        help="posterior draws for the predictive bands (default 200)")
    parser.add_argument("--out", default="results", help="output folder (default results/)")
    parser.add_argument("--json", default=None, help="JSON summary file (default OUT/posterior.json)")
    parser.add_argument("--chain", default=None, help="HDF5 chain file (default OUT/posterior_chain.h5)")
    parser.add_argument("--no-chain", action="store_true", help="keep the chain in memory only (no resuming)")
    parser.add_argument("--restart", action="store_true", help="discard an existing chain file")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures (faster)")
    parser.add_argument("--quiet", action="store_true", help="no progress messages")


def canonical_command(args) -> str:
    """The command line that reproduces this run (every sampling setting spelled out)."""
    parts = ["hysbench", "posterior", str(dataset_paths(args.dataset)[0]), "--model", args.model, "--noise", args.noise,
             "--discrepancy", args.discrepancy, "--walkers",
             str(args.walkers), "--steps", str(args.steps), "--min-ess", f"{args.min_ess:g}", "--burn", str(args.burn),
             "--moves", args.moves, "--seed", str(args.seed), "--draws", str(args.draws), "--out", args.out]
    if args.fixed_steps:
        parts.append("--fixed-steps")
    if args.no_calibration:
        parts.append("--no-calibration")
    if args.no_figures:
        parts.append("--no-figures")
    return " ".join(shlex.quote(str(p)) for p in parts)


def main(args) -> int:
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    dataset = load_dataset(dataset_paths(args.dataset)[0])
    model = get_model(args.model)
    if args.burn != "auto" and args.burn >= args.steps:
        raise IdentificationError(f"--burn {args.burn} leaves no step of the at most {args.steps} steps (--steps)")
    check_output_dir(args.out)
    json_path = check_output_file(args.json) if args.json else Path(args.out) / "posterior.json"
    chain = None if args.no_chain else Path(args.chain) if args.chain else Path(args.out) / "posterior_chain.h5"
    if chain is not None and chain.exists() and chain.is_dir():
        raise IdentificationError(f"chain file {chain} is a folder")
    out = ensure_dir(args.out)
    if json_path.parent != out:
        ensure_dir(json_path.parent)
    if chain is not None:
        ensure_dir(chain.parent)
    run = sample_posterior(model, dataset, noise=args.noise, n_walkers=args.walkers, max_steps=args.steps,
                           min_ess=args.min_ess, fixed_steps=args.fixed_steps, burn=args.burn, seed=args.seed,
                           moves=args.moves, chain_file=chain, restart=args.restart,
                           progress=None if not args.quiet else False, discrepancy=args.discrepancy,
                           calibrate=not args.no_calibration, log=say)
    say("summarising, predictive bands, figures ...")
    summary = run.summary()
    pred = {"identification": predictive(run, dataset.identification, args.draws, seed=args.seed),
            "validation": predictive(run, dataset.validation, args.draws, seed=args.seed)}
    summary["predictive"] = {k: [{a: b for a, b in p.items() if not a.startswith("_")} for p in v]
                             for k, v in pred.items()}
    summary["predictive_coverage"] = predictive_coverage(pred["validation"])
    summary["predictive_coverage_identification"] = predictive_coverage(pred["identification"])
    ident = identifiability(run, summary["parameters"])
    summary["identifiability"] = ident
    files = {}
    if not args.no_figures:
        files = {"corner": "posterior_corner.png", "predictive": "posterior_predictive.png",
                 "correlation": "posterior_correlation.png", "trace": "posterior_trace.png"}
        files["corner_names"] = ", ".join(corner_figure(run, out / files["corner"]))
        correlation_figure(run, out / files["correlation"])
        trace_figure(run, out / files["trace"])
        if pred["validation"]:
            predictive_figure(pred["validation"], out / files["predictive"], dataset.output_unit)
    command = canonical_command(args)
    summary["command"] = command
    write_json(json_path, summary)
    write_atomic(out / "posterior.md", render_markdown(summary, ident, files, command,
                                                       dataset.description and f"Dataset: {dataset.description}"))
    print(f"{'parameter':<10} {'mean':>11} {'sd':>10} {'q05':>11} {'q95':>11} {'ESS':>7} {'tau':>6}")
    for n, v in summary["parameters"].items():
        ess = "-" if v["ess"] is None else f"{v['ess']:.0f}"
        tau = "-" if v["tau"] is None else f"{v['tau']:.1f}"
        print(f"{n:<10} {v['mean']:>11.5g} {v['sd']:>10.3g} {v['q05']:>11.5g} {v['q95']:>11.5g} {ess:>7} {tau:>6}")
    unit = f" {dataset.output_unit}" if dataset.output_unit else ", in the output's unit"  # a dataset may name none
    for p in summary["predictive"]["validation"]:
        c = p["coverage"]
        if c is None:
            print(f"validation {p['file']}: no posterior draw gave a finite model output", file=sys.stderr)
            continue
        print(f"validation {p['file']}: {c['90']:.1%} of measured samples inside the 90 % predictive band "
              f"(mean width {c['width_90']:.4g}{unit}), {c['50']:.1%} inside the 50 % band"
              + (f"; {p['nonfinite_draws']} draws with non-finite output left out" if p["nonfinite_draws"] else ""))
    outside = [p["file"] for p in summary["predictive"]["validation"] if p.get("inside_fitted_range") is False]
    if outside:
        print(f"hysbench posterior: WARNING: {', '.join(outside)} outside the identification records' frequency "
              "range: extrapolated bands, not calibrated (see posterior.md)", file=sys.stderr)
    bad = summary["nonfinite_model_outputs"]["log_posterior_evaluations"]
    if bad:
        print(f"hysbench posterior: WARNING: {bad} log-posterior evaluations had non-finite model outputs "
              "(rejected, counted in the JSON under nonfinite_model_outputs)", file=sys.stderr)
    for name, b in (summary.get("at_prior_bound") or {}).items():
        print(f"hysbench posterior: NOTE: {name}: {b['share']:.0%} of the kept states at the prior's {b['bound']} "
              f"bound {b['value']:g} (the prior cuts the posterior off; see posterior.md)", file=sys.stderr)
    if len(summary.get("modes") or []) > 1:
        print(f"modes: {len(summary['modes'])} separated; kept states "
              + ", ".join(f"{m['share_of_kept_states']:.0%}" for m in summary["modes"]) + " (see posterior.md)")
    print(f"converged: {'yes' if summary['converged'] else 'NO'}; wall {summary['wall_seconds']:.1f} s; "
          f"wrote {out / 'posterior.md'} and {json_path}")
    if not summary["converged"]:
        print("hysbench posterior: WARNING: the chain has NOT converged: "
              + "; ".join(summary["convergence_problems"]), file=sys.stderr)
    elif not summary["ess_target_met"]:
        print(f"hysbench posterior: WARNING: smallest ESS {summary['min_ess']:.0f} is below the target "
              f"{args.min_ess:g}", file=sys.stderr)
    return 0
