"""matrix.csv, report.md and figures from finished cells."""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from pathlib import Path

import numpy as np

from hysbench.benchmarks.plots import (axis_label, figure_legend, legend_outside, plain_log_labels, pyplot, save_figure,
                                      series_style, ticks_at)
from hysbench.data.files import write_atomic
from hysbench.data.dataset import Dataset
from hysbench.identification import Fit
from hysbench.models import get_model
from hysbench.models.errors import HysbenchError

CSV_COLUMNS = ("dataset", "model", "method", "record", "frequency_hz", "role", "e_m", "e_rms", "fitness",
               "fit_seconds", "simulate_seconds", "n_params", "n_evaluations", "seed")
TIMING_COLUMNS = ("fit_seconds", "simulate_seconds")


def _ordered(results: list[dict]) -> list[dict]:
    return sorted(results, key=lambda r: (r["dataset"], r["model"], r["method"]))


def matrix_rows(results: list[dict]) -> list[dict]:
    rows = []
    for res in _ordered(results):
        if res["status"] != "ok":
            continue
        for rec in res["records"]:
            rows.append({
                "dataset": res["dataset"], "model": res["model"], "method": res["method"], "record": rec["file"],
                "frequency_hz": rec["frequency_hz"], "role": rec["role"], "e_m": rec["e_m"], "e_rms": rec["e_rms"],
                "fitness": res["fitness"], "fit_seconds": res["fit_seconds"],
                "simulate_seconds": res["simulate_seconds"], "n_params": res["n_params"],
                "n_evaluations": res["n_evaluations"], "seed": res["seed"],
            })
    return rows


def matrix_csv(results: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in matrix_rows(results):
        w.writerow({k: ("" if row[k] is None else (repr(row[k]) if isinstance(row[k], float) else row[k]))
                    for k in CSV_COLUMNS})
    return buf.getvalue()


def write_matrix_csv(out: Path, results: list[dict], name: str = "matrix.csv") -> None:
    write_atomic(out / name, matrix_csv(results))


def seconds_per_cell(path: Path) -> dict[str, float]:
    """Fit plus simulate seconds of each cell ("dataset/model/method") of a matrix CSV an earlier run wrote
    ({} when there is none or it cannot be read): how long each cell is likely to take again."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        seconds = {f"{r['dataset']}/{r['model']}/{r['method']}": float(r["fit_seconds"]) + float(r["simulate_seconds"])
                   for r in rows}
    except (OSError, KeyError, TypeError, ValueError, csv.Error):
        return {}
    return {name: s for name, s in seconds.items() if math.isfinite(s)}


# --- summaries ------------------------------------------------------------
def cell_summary(res: dict) -> dict:
    val = [r for r in res["records"] if r["role"] == "validation"]
    ide = [r for r in res["records"] if r["role"] == "identification"]
    scored = val or ide  # a dataset without validation records is ranked on identification
    return {
        "val_mean": float(np.mean([r["e_rms"] for r in scored])),
        "val_worst": float(np.max([r["e_rms"] for r in scored])),
        "val_em_worst": float(np.max([r["e_m"] for r in scored])),
        "id_mean": float(np.mean([r["e_rms"] for r in ide])) if ide else math.nan,
        "ranked_on": "validation" if val else "identification",
    }


def ranking(results: list[dict], dataset: str) -> list[tuple[dict, dict]]:
    cells = [r for r in results if r["dataset"] == dataset and r["status"] == "ok"]
    scored = [(r, cell_summary(r)) for r in cells]
    return sorted(scored, key=lambda rs: (rs[1]["val_mean"], rs[1]["val_worst"], rs[0]["model"], rs[0]["method"]))


def best_per_model(ranked: list[tuple[dict, dict]]) -> list[tuple[dict, dict]]:
    seen, best = set(), []
    for res, summ in ranked:
        if res["model"] not in seen:
            seen.add(res["model"])
            best.append((res, summ))
    return best


def _fmt(x, nd=2) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def _secs(x) -> str:
    return "–" if x is None or math.isnan(x) else (f"{x:.3g}" if x < 100 else f"{x:.0f}")


def _freq_label(rec: dict, shared: bool = False) -> str:
    """The row's frequency; with the file beside it when another row has the same one (``shared``)."""
    if not rec["frequency_hz"]:
        return rec["file"]
    return f"{rec['frequency_hz']:g} ({rec['file']})" if shared else f"{rec['frequency_hz']:g}"


def kind_of(model_name: str) -> str:
    """grey-box (a structure of hysteresis or of the physics) or black-box (a learner, docs/black_box.md)."""
    try:
        return getattr(get_model(model_name), "kind", "grey-box")
    except HysbenchError:
        return "–"


def at_bounds(res: dict) -> list[str]:
    """The parameters a cell's fit left at a bound of its search (its Fit's diagnostics)."""
    return list((res.get("fit") or {}).get("diagnostics", {}).get("at_bounds", []))


def cell_notes(res: dict) -> list[str]:
    """What a cell's fit says about itself (parameters at bounds, non-finite candidates, training stopped)."""
    return list((res.get("fit") or {}).get("notes", []))


def ranking_table(ranked) -> list[str]:
    on = ranked[0][1]["ranked_on"] if ranked else "validation"
    lines = [
        f"| rank | model | kind | method | parameters | {on} e_rms mean (%) | {on} e_rms worst (%) | {on} e_m worst (%) "
        "| fitness (eq. 9) | fit (s) | simulate all records (s) | at a bound |",
        "|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for i, (res, s) in enumerate(ranked, 1):
        lines.append(
            f"| {i} | {res['model']} | {kind_of(res['model'])} | {res['method']} | {res['n_params']} | {_fmt(s['val_mean'])} | "
            f"{_fmt(s['val_worst'])} | {_fmt(s['val_em_worst'])} | {res['fitness']:.4g} | "
            f"{_secs(res['fit_seconds'])} | {_secs(res['simulate_seconds'])} | {', '.join(at_bounds(res)) or '–'} |"
        )
    return lines


def notes_section(ranked) -> list[str]:
    """Every ranked cell's notes, so a score whose fit stopped at a bound or short of converging is read with it."""
    noted = [(res, cell_notes(res)) for res, _ in ranked]
    noted = [(res, notes) for res, notes in noted if notes]
    if not noted:
        return []
    lines = ["### Notes of ranked cells (parameters at a search bound, non-finite candidates, training stopped)", ""]
    for res, notes in noted:
        lines += [f"- {res['model']} / {res['method']}: {_shortened(note)}" for note in notes]
    return lines + [""]


def _shortened(note: str, limit: int = 300) -> str:
    """A note as the report shows it: a long one (e.g. varpro's list of weak directions) cut at a clause."""
    if len(note) <= limit:
        return note
    cut = max(note.rfind(sep, 0, limit) for sep in ("; ", ": ", ", "))
    return note[:cut if cut > limit // 2 else limit] + " ... (the whole note: the cell's file in cells/)"


def paper_layout(best, role: str) -> list[str]:
    """Tables 3/4 of the paper: per frequency e_m / e_rms, one column per model's best cell."""
    if not best:
        return []
    recs = [r for r in best[0][0]["records"] if r["role"] == role]
    if not recs:
        return []
    head = "| frequency (Hz) | " + " | ".join(f"{res['model']} ({res['method']})" for res, _ in best) + " |"
    lines = [head, "|---:|" + "---:|" * len(best)]
    freqs = Counter(r["frequency_hz"] for r in recs)
    for rec in recs:
        cells = []
        for res, _ in best:
            match = next((r for r in res["records"] if r["file"] == rec["file"]), None)
            cells.append(f"{match['e_m']:.2f} / {match['e_rms']:.2f}" if match else "–")
        lines.append(f"| {_freq_label(rec, freqs[rec['frequency_hz']] > 1)} | " + " | ".join(cells) + " |")
    return lines


def dataset_section(ds_name: str, results: list[dict], failed: list[dict], figures: dict) -> list[str]:
    ranked = ranking(results, ds_name)
    best = best_per_model(ranked)
    lines = [f"## Dataset `{ds_name}`", ""]
    if not ranked:
        return lines + ["No cell finished on this dataset.", ""]
    on = ranked[0][1]["ranked_on"]
    lines += [f"Ranked by mean {on} e_rms (ties by worst). e_m and e_rms in % of the measured peak-to-peak "
              "of each scored window (eq. 10).", ""]
    if on == "identification":  # in-sample: more parameters score better whether or not they predict better
        lines += ["**No validation records: every score is on the data its model was fitted to**, so this ranking "
                  "favours more parameters and says nothing of prediction; give a record the role `validation` "
                  "(docs/datasets.md) for a ranking on data no fit saw.", ""]
    lines += ranking_table(ranked) + [""]
    lines += notes_section(ranked)
    lines += ["### Identification errors, best cell of each model (layout of the paper's Table 3: e_m / e_rms, %)",
              ""] + paper_layout(best, "identification") + [""]
    val = paper_layout(best, "validation")
    if val:
        lines += ["### Prediction errors on validation records (layout of the paper's Table 4: e_m / e_rms, %)",
                  ""] + val + [""]
    for title, fname in figures.items():
        lines += [f"![{title}]({fname})", ""]
    fails = [f for f in failed if f["dataset"] == ds_name]
    if fails:
        lines += ["### Cells that failed or predicted non-finite values (not ranked)", ""]
        lines += [f"- {f['model']} / {f['method']}: {f['status']}: {f['error']}" for f in fails] + [""]
    return lines


# --- figures ---------------------------------------------------------------
def _slug(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in s)


EXCERPT_SAMPLES = 500  # of a record without a drive period: the end of its scored window, drawn against time


def _role(role: str) -> str:
    return "id" if role == "identification" else "val"


def _periodic(records) -> bool:
    """Every record has its own drive frequency: records are placed and told apart by it."""
    freqs = [r.frequency_hz for r in records]
    return all(freqs) and len(set(freqs)) == len(freqs)


def _record_tick(rec: dict) -> str:
    name = f"{rec['frequency_hz']:g} Hz" if rec["frequency_hz"] else Path(rec["file"]).stem
    return f"{name} ({_role(rec['role'])})"


def _record_order(rec: dict):
    return rec["frequency_hz"] or 0, rec["file"]


def loops_figure(ds: Dataset, best, out: Path, n_models: int = 3) -> str:
    plt = pyplot()
    recs = ds.records
    loops = all(r.frequency_hz for r in recs)  # input-output loops; other drives overlay into a blot
    ncol = min(4, len(recs))
    nrow = int(math.ceil(len(recs) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.4 * ncol, 2.9 * nrow + 0.9), squeeze=False, layout="constrained")
    for ax in axes.flat[len(recs):]:
        ax.set_visible(False)
    fits = [(res, Fit.from_dict(res["fit"])) for res, _ in best[:n_models]]  # the models rebuilt from the stored Fits
    for ax, rec in zip(axes.flat, recs):
        s = rec.scored if loops else slice(max(rec.start, rec.stop - EXCERPT_SAMPLES), rec.stop)
        x = rec.u[s] if loops else rec.t[s]
        ax.plot(x, rec.y[s], color="black", lw=1.4, label="measured")
        for i, (res, fit) in enumerate(fits):
            ax.plot(x, fit.predict(rec)[s], lw=0.9, label=f"{res['model']} ({res['method']})",
                    **series_style(i, marker=False))
        ax.set_title(f"{rec.label} ({rec.role})", fontsize=9)
        ax.tick_params(labelsize=7)
    figure_legend(fig, axes.flat[0])
    what = ("against the input, scored windows" if loops
            else f"against time, last {EXCERPT_SAMPLES} samples of each scored window")
    fig.suptitle(f"{ds.name}: measured and predicted output {what}; best {len(fits)} models", fontsize=10)
    fig.supxlabel(axis_label("input", ds.input_unit) if loops else "time (s)", fontsize=9)
    fig.supylabel(axis_label("output", ds.output_unit), fontsize=9)
    name = f"loops_{_slug(ds.name)}.png"
    save_figure(fig, out / name)
    return name


def error_figure(ds: Dataset, best, out: Path) -> str:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    periodic = _periodic(ds.records)
    for i, (res, _) in enumerate(best):
        recs = sorted(res["records"], key=_record_order)
        x = [r["frequency_hz"] if periodic else j for j, r in enumerate(recs)]
        style = series_style(i)
        ax.plot(x, [r["e_rms"] for r in recs], ms=4, lw=1, label=f"{res['model']} ({res['method']})", **style)
        val = [(xi, r["e_rms"]) for xi, r in zip(x, recs) if r["role"] == "validation"]
        if val:  # open markers over the filled ones
            ax.plot(*zip(*val), ls="none", marker=style["marker"], color=style["color"], mfc="white", ms=4)
    if periodic:
        ax.set_xscale("log")
        ax.set_xlabel("drive frequency (Hz)")
        ticks_at(ax, [r.frequency_hz for r in ds.records])
        for r in ds.validation:
            ax.axvline(r.frequency_hz, color="0.85", lw=3, zorder=0)
    elif best:
        recs = sorted(best[0][0]["records"], key=_record_order)
        ax.set_xticks(range(len(recs)), [_record_tick(r) for r in recs],
                      fontsize=7, rotation=20 if len(recs) > 3 else 0)
        ax.set_xlabel("record")
    ax.set_yscale("log")  # e_rms spans decades between the best and the worst model; every e_rms figure alike
    plain_log_labels(ax)
    ax.set_ylabel("e_rms (% of measured peak-to-peak)")
    per = "drive frequency" if periodic else "record"
    mark = "open markers and grey lines" if periodic and ds.validation else "open markers"
    ax.set_title(f"{ds.name}: e_rms per {per}, best cell of each model\n({mark}: validation)", fontsize=9)
    legend_outside(ax)
    name = f"erms_{_slug(ds.name)}.png"
    save_figure(fig, out / name)
    return name


def write_report(out: Path, results: list[dict], datasets: list[Dataset], header: list[str],
                 extra: list[str] = (), name: str = "report.md") -> None:
    """report.md: a section per dataset, then ``extra`` lines (e.g. the unseen-waveform protocol)."""
    ok = [r for r in results if r["status"] == "ok"]
    failed = [r for r in results if r["status"] != "ok"]
    lines = ["# hysbench benchmark matrix", ""] + header + [""]
    for ds in datasets:
        best = best_per_model(ranking(ok, ds.name))
        figures = {}
        if best:
            figures["measured vs predicted loops"] = loops_figure(ds, best, out)
            figures["e_rms per frequency"] = error_figure(ds, best, out)
        lines += dataset_section(ds.name, ok, failed, figures)
    write_atomic(out / name, "\n".join(lines + list(extra)) + "\n")
