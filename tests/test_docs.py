"""README.md and docs/: the MkDocs build passes in strict mode, every relative link resolves, and
every ``hysbench ...`` command they show runs with ``--help``."""

import argparse
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hysbench.benchmarks.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
CODE_SPAN = re.compile(r"`([^`\n]+)`")
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)


def relative_links(text: str) -> list[str]:
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t) and not t.startswith("#")]


def shown_commands(text: str) -> list[list[str]]:
    """The argument lists of every ``hysbench ...`` command in a code span or on a line of a code block."""
    lines = [span for span in CODE_SPAN.findall(FENCE.sub("", text))]
    for block in FENCE.findall(text):
        for line in block.splitlines():
            lines.extend(part.strip() for part in line.split("&&"))
    found = []
    for line in lines:
        line = line.strip().removeprefix("$ ")
        if line.startswith("hysbench "):
            found.append(line.split("#")[0].split()[1:])
    return found


def subcommand_path(args: list[str], parser: argparse.ArgumentParser) -> list[str]:
    """The leading subcommand names of ``args`` (``['report', 'bouc-wen']``), checked against the parser."""
    path = []
    for token in args:
        subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subparsers or token.startswith("-"):
            break
        if token.isupper() or token.startswith("["):  # a placeholder such as NAME: the parent's --help
            break
        assert token in subparsers[0].choices, f"hysbench {' '.join(path + [token])}: no such command"
        path.append(token)
        parser = subparsers[0].choices[token]
    return path


def test_the_readme_is_short():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 250


def test_the_docs_build_in_strict_mode(tmp_path):
    # not --quiet: it hides the warnings, and strict mode then has none to fail on
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict",
                           "-f", str(ROOT / "mkdocs.yml"), "-d", str(tmp_path / "site")],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (tmp_path / "site" / "index.html").is_file()


def test_every_docs_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert [p.name for p in PAGES[1:] if f": {p.name}" not in nav] == []


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_relative_link_resolves(page):
    dead = [t for t in relative_links(page.read_text(encoding="utf-8"))
            if not (page.parent / t.split("#")[0]).exists()]
    assert dead == []


@pytest.mark.parametrize("page", PAGES[1:], ids=lambda p: p.relative_to(ROOT).as_posix())
def test_docs_pages_link_only_inside_docs(page):
    """MkDocs cannot link to a file outside docs/: such a path is written as code text instead."""
    docs = (ROOT / "docs").resolve()
    outside = [t for t in relative_links(page.read_text(encoding="utf-8"))
               if not (page.parent / t.split("#")[0]).resolve().is_relative_to(docs)]
    assert outside == []


def test_the_link_check_sees_a_dead_link(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("[a](missing.md) [b](https://example.org) [c](#anchor) ![d](page.md)")
    assert relative_links(page.read_text()) == ["missing.md", "page.md"]


def test_the_command_scan_reads_spans_and_blocks():
    text = "Run `hysbench fit --model m`.\n```bash\npip install . && hysbench run   # main job\n```\n`hysbench.models`"
    assert shown_commands(text) == [["fit", "--model", "m"], ["run"]]


def test_every_shown_command_runs_with_help(capsys):
    parser = build_parser()
    commands = {tuple(args[:1]) if args and args[0].startswith("-") else tuple(subcommand_path(args, parser))
                for page in PAGES for args in shown_commands(page.read_text(encoding="utf-8"))}
    assert ("run",) in commands and ("dataset", "init") in commands
    failed = []
    for command in sorted(commands):
        argv = list(command) if command and command[0].startswith("-") else [*command, "--help"]
        if main(argv) != 0:
            failed.append(" ".join(argv))
    capsys.readouterr()
    assert failed == []


def test_an_unknown_shown_command_is_caught():
    with pytest.raises(AssertionError, match="no such command"):
        subcommand_path(["report", "no-such-report"], build_parser())


def table_rows(text: str, width: int) -> list[list[str]]:
    """The cells of every Markdown table row of ``width`` columns (header and rule rows included)."""
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in text.splitlines()
            if line.startswith("|")]
    return [r for r in rows if len(r) == width]


def best_cells(report: str) -> dict[str, list[str]]:
    """Each model's first (best) row of the ranking in results/report.md, by model name."""
    best: dict[str, list[str]] = {}
    for row in table_rows(report, 12):
        if row[0].isdigit():
            best.setdefault(row[1], row)
    return best


def report_is_the_committed_one() -> bool:
    """False when git says results/report.md differs from the commit (a local ``hysbench run`` rewrote it)."""
    try:
        proc = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", "results/report.md"], cwd=ROOT,
                              capture_output=True)
    except FileNotFoundError:
        return True
    return proc.returncode != 1


@pytest.mark.parametrize("page,columns", [("README.md", (1, 2, 3, 4, "e_rms", 7, 9)),
                                          ("docs/matrix.md", (1, 3, 4, "e_rms", 7, 9))])
def test_the_best_cell_tables_quote_the_committed_report(page, columns):
    """README's and docs/matrix.md's table of each model's best cell is the report's row: every column,
    the fit time included. A local ``hysbench run`` rewrites the report with its own wall-clock times (its
    other columns are the same for the same seed), so the times are compared only on the committed report."""
    best = best_cells((ROOT / "results" / "report.md").read_text(encoding="utf-8"))
    quoted = [r for r in table_rows((ROOT / page).read_text(encoding="utf-8"), len(columns)) if r[0] in best]
    assert len(quoted) >= 9
    keep = slice(None) if report_is_the_committed_one() else slice(-1)
    for row in quoted:
        cell = best[row[0]]
        expected = [f"{cell[5]} / {cell[6]}" if c == "e_rms" else cell[c] for c in columns]
        assert row[keep] == expected[keep], f"{page}: {row[0]}"


def test_the_table_check_sees_a_stale_figure():
    report = ("| rank | model | kind | method | p | mean | worst | e_m | fitness | fit | sim | at a bound |\n"
              "| 1 | mrpim | grey-box | varpro | 21 | 2.02 | 2.75 | 5.98 | 0.58 | 1.17 | 0.03 | gamma |\n"
              "| 2 | mrpim | grey-box | lsq | 21 | 2.03 | 2.76 | 5.79 | 0.58 | 6.42 | 0.05 | – |\n")
    assert best_cells(report)["mrpim"][9] == "1.17"
    assert table_rows("| mrpim | varpro | 1.36 |\n| a | b |", 3) == [["mrpim", "varpro", "1.36"]]


# --- docs/posterior.md and docs/compensation.md quote the committed results -------------------------
def committed(*paths: str) -> bool:
    """False when git says one of ``paths`` differs from the commit (a local run rewrote it)."""
    try:
        proc = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", *paths], cwd=ROOT, capture_output=True)
    except FileNotFoundError:
        return True
    return proc.returncode != 1


def compensation_quotes(page: str, result: dict) -> list[tuple[str, str, str]]:
    """(what, quoted, from the JSON) for the page's table of sine means and its bouc-wen identification time."""
    from hysbench.benchmarks.compensation.report import sine_mean
    rows = {r[0]: r for r in table_rows(page, 11)}
    header = rows["controller"][1:]
    models = ["linear" if h == "linear gain" else h for h in header]
    out = []
    for label, prefix in (("open loop (inverse)", ""), ("PI (5 Hz) + inverse as feedforward", "pi+")):
        for model, cell in zip(models, rows[label][1:]):
            quoted, actual = float(cell.strip("*")), sine_mean(result, prefix + model)
            out.append((f"{label} {model}", f"{quoted:.3g}", f"{actual:.3g}"))
    t = re.search(r"([\d.]+) s in the run that wrote results/", page)
    out.append(("bouc-wen identification", t and t.group(1), f"{result['models']['bouc-wen']['identify_s']:.1f}"))
    return out


def posterior_quotes(page: str, result: dict) -> list[tuple[str, str, str]]:
    """(what, quoted, from the JSON) for the page's default-dataset coverage, widths and mode shares, and the
    calibration model's parameter count."""
    from hysbench.models import get_model
    cov = result["predictive_coverage"]
    m = re.search(r"90 % bands cover \*\*([\d.]+) %, ([\d.]+) % and ([\d.]+) %\*\*.*?\(widths ([\d.]+), ([\d.]+), "
                  r"([\d.]+) mm\); 50 % bands ([\d.]+) / ([\d.]+) / ([\d.]+) %", page, re.S)
    quoted = list(m.groups()) if m else [None] * 9
    files = sorted(cov, key=lambda f: next(p["frequency_hz"] for p in result["predictive"]["validation"]
                                          if p["file"] == f))
    actual = ([f"{100 * cov[f]['90']:.1f}" for f in files] + [f"{cov[f]['width_90']:.3f}" for f in files]
              + [f"{100 * cov[f]['50']:.1f}" for f in files])
    out = [(f"coverage/width {i}", q, a) for i, (q, a) in enumerate(zip(quoted, actual))]
    shares = re.search(r"there are two, holding (\d+) / (\d+) % of the kept states", page)
    out.append(("mode shares", shares and "/".join(shares.groups()),
                "/".join(f"{100 * m['share_of_kept_states']:.0f}" for m in result["modes"])))
    wall = re.search(r"([\d.]+) s \(the run that wrote results/posterior.json", page)
    out.append(("wall time", wall and wall.group(1), f"{result['wall_seconds']:.1f}"))
    n = re.search(r"quadratic polynomial: (\d+) parameters", page)
    out.append(("reduced model's parameters", n and n.group(1),
                str(len(get_model("mrpim", n_operators=4, poly_order=2).param_names))))
    return out


@pytest.mark.parametrize("page,result,quotes", [("docs/compensation.md", "results/compensation.json",
                                                 compensation_quotes),
                                                ("docs/posterior.md", "results/posterior.json", posterior_quotes)])
def test_the_docs_quote_the_committed_results(page, result, quotes):
    import json
    if not committed(result):
        pytest.skip(f"{result} was rewritten by a local run")
    text = (ROOT / page).read_text(encoding="utf-8")
    got = quotes(text, json.loads((ROOT / result).read_text(encoding="utf-8")))
    wrong = [(what, q, a) for what, q, a in got if q != a]
    assert not wrong, f"{page}: (quoted, in {result}): {wrong}"


def test_the_quote_check_sees_a_stale_figure():
    import json
    result = json.loads((ROOT / "results/compensation.json").read_text(encoding="utf-8"))
    text = (ROOT / "docs/compensation.md").read_text(encoding="utf-8")
    stale = text.replace("| open loop (inverse) | 8.79 |", "| open loop (inverse) | 8.80 |")
    wrong = {w for w, q, a in compensation_quotes(stale, result) if q != a}
    assert wrong - {w for w, q, a in compensation_quotes(text, result) if q != a} == {"open loop (inverse) linear"}


def test_the_posterior_page_names_the_models_it_cannot_sample():
    """docs/posterior.md's Limitations name exactly the registered models without a linear part."""
    from hysbench.models import get_model
    from hysbench.models.registry import list_models
    text = (ROOT / "docs/posterior.md").read_text(encoding="utf-8")
    line = re.search(r"every registered\s+model but (.*?), which are refused", text, re.S).group(1)
    named = set(CODE_SPAN.findall(line))
    assert named == {n for n in list_models() if not get_model(n).has_linear_part}
