"""``hysbench diagnose DATASET``: show where a model departs from the data, name the cause, extend, measure.

Writes diagnosis.md, its PNG figures and diagnosis.json into ``--out``
(default results/), or the JSON where ``--json`` says. The verdict is
printed: the cause (one of none, relaxation, delay, resonance, creep,
interference, saturation), its parameters, each candidate's score and the
validation gain of the extended model.
"""

from __future__ import annotations

import argparse
import sys
import time

from hysbench.benchmarks.cli.common import nonnegative_int, positive_int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="dataset folder (holding dataset.toml)")
    parser.add_argument("--model", default="mrpim", help="base model (registry name, default mrpim)")
    parser.add_argument("--out", default="results", help="folder for diagnosis.md, figures and JSON (default results/)")
    parser.add_argument("--json", default=None, metavar="FILE", help="write the JSON here (default OUT/diagnosis.json)")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the identifiers and the row subset")
    parser.add_argument("--max-rows", type=positive_int, default=None,
                        help="samples per record in the candidate screen (default 10000)")
    parser.add_argument("--note", default="", help="a line put at the top of diagnosis.md")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def main(args) -> int:
    from hysbench.models import get_model

    from hysbench.benchmarks.diagnosis.candidates import MAX_ROWS
    from hysbench.benchmarks.diagnosis.diagnose import diagnose
    from hysbench.benchmarks.diagnosis.report import write_report

    model = get_model(args.model)  # an unknown name fails here, before any work
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    diag = diagnose(args.dataset, model=model, seed=args.seed, max_rows=args.max_rows or MAX_ROWS, progress=say)
    say("writing the report")
    data = write_report(diag, args.out, args.json, note=args.note)
    print(verdict(diag, data))
    return 0


def verdict(diag, data: dict) -> str:
    lines = [f"cause: {diag.cause}"]
    if diag.parameters:
        lines.append("parameters: " + ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
                                                for k, v in diag.parameters.items()))
    lines.append(f"also: {', '.join(data['also']) if data['also'] else 'none'}")
    lines.append(f"extended model: {diag.extended_model or '-'}")
    lines.append("evidence (BIC - BIC(base alone) on the identification records; share of the validation residual "
                 "explained, not used to choose):")
    for c in sorted(diag.candidates, key=lambda c: c.bic):
        est = ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in c.estimates.items()
                        if not isinstance(v, list)) or ", ".join(f"{k} {[round(x, 4) for x in v]}"
                                                                 for k, v in c.estimates.items())
        lines.append(f"  {c.cause:<13} {c.delta_bic:>14.1f}   validation {100 * c.validation_explained:8.3f} %   {est}")
    g = diag.gain()
    if g:
        v = g["validation"]
        lines.append(f"validation gain: {100 * v['explained_whole']:.2f} % of the residual sum of squares removed "
                     f"(whole records), {100 * v['explained_window']:.2f} % (windows); mean e_rms "
                     f"{v['mean_e_rms_before']:.3g} % -> {v['mean_e_rms_after']:.3g} % (windows)")
    if diag.warning:
        lines.append(f"warning: {diag.warning}")
    return "\n".join(lines)
