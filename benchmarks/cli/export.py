"""``hysbench export MODEL.json --out DIR --prefix NAME``: C99 code for a fitted model and its inverse.

Writes DIR/NAME.h and DIR/NAME.c (models/export_c.py describes the code): ``NAME_init``,
``NAME_step`` (the model) and ``NAME_inverse_step`` (its causal inverse), with the parameters
and the sample time as constants and the model file's name, SHA-256 and the hysbench version
in a comment at the top. Options of the inverse: ``--input-limits LO HI`` (default: the fit's
input range), ``--max-rate`` (largest |du/dt|, input units per second; default none),
``--u-start`` (the input before the first sample; default the lower limit), ``--inverse``
(exact, reference-driven or auto; models/inverse.py), ``--guide-time`` (the reference-driven
inverse's follower time constant). A model that
cannot be exported says so in one line (exit status 2) and nothing is written.

Before writing, the inverse is checked (``export_c.check_inverse``: the exact inverse must give back
the input of sines over the input range that the model itself answers, the reference-driven one
must not ring); where it does not, the export still
writes both (the forward model is unaffected) and says so on stderr and in the header.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from hysbench.data.files import check_output_dir, ensure_dir, write_atomic
from hysbench.models.export_c import check_exportable, check_inverse, export_c
from hysbench.models.inverse import DEFAULT_GUIDE_TIME, INVERSES
from hysbench.models.model_file import file_sha256, load_model

from .common import CommandError

EXAMPLE = "hysbench export m.json --out c --prefix dea"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model_file", metavar="MODEL.json", help="a model file (hysbench fit ... --save MODEL.json)")
    parser.add_argument("--out", required=True, metavar="DIR", help="folder to write NAME.h and NAME.c in")
    parser.add_argument("--prefix", required=True, metavar="NAME", help="C identifier prefixing every name")
    parser.add_argument("--input-limits", nargs=2, type=float, metavar=("LO", "HI"),
                        help="the inverse's input limits (default: the fit's input range)")
    parser.add_argument("--max-rate", type=float, help="the inverse's largest |du/dt| (input units per second)")
    parser.add_argument("--inverse", choices=INVERSES, default="auto",
                        help="which causal inverse to export: exact (gives a reachable input back exactly where its "
                             "error recursion is stable), reference-driven (rate and relaxation terms from the "
                             "reference: no ringing, approximate) or auto (reference-driven for a model with rate or "
                             "relaxation terms, else exact; default)")
    parser.add_argument("--guide-time", type=float, default=DEFAULT_GUIDE_TIME,
                        help="the reference-driven inverse's follower time constant in seconds (0: none; default "
                             f"{DEFAULT_GUIDE_TIME:g})")
    parser.add_argument("--u-start", type=float, help="the input before the first sample (default: the lower limit)")


def _version() -> str:
    try:
        return version("hysbench")
    except PackageNotFoundError:
        return "0+unknown"


def main(args) -> int:
    if not args.prefix.isidentifier() or not args.prefix.isascii():
        raise CommandError(f"--prefix must be a C identifier (letters, digits, _), got {args.prefix!r}")
    fitted = load_model(args.model_file)
    check_exportable(fitted)
    check_output_dir(args.out)
    options = {"input_limits": args.input_limits, "max_rate": args.max_rate, "inverse": args.inverse,
               "guide_time": args.guide_time}
    check = check_inverse(fitted, **options, **({} if args.u_start is None else {"u_start": args.u_start}))
    note = check.message(fitted.name)
    header, source = export_c(fitted, args.prefix, model_file=Path(args.model_file).name,
                              model_sha256=file_sha256(args.model_file), version=_version(), u_start=args.u_start,
                              inverse_note=note, **options)
    out = ensure_dir(args.out)
    for name, text in ((f"{args.prefix}.h", header), (f"{args.prefix}.c", source)):
        write_atomic(out / name, text)
        print(f"wrote {out / name}")
    print(note if check.stable else f"hysbench export: warning: {note}", file=None if check.stable else sys.stderr)
    return 0
