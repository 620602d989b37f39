"""The second protocol: identify on the seven sines, validate on drives the model never saw.

Every finished cell stores its Fit. For the cells identified on ``IDENTIFIED_ON`` (the
virtual DEA's seven sines), the model is rebuilt from that Fit and simulated, from the
record's first sample, on each record of the unseen-waveform dataset (by default the
shipped data/virtual_dea_waveforms): no refit, so this costs one simulation per record.
Each record is scored (e_m, e_rms of eq. 10) on its window, the unseen drive after the
sine run-in. A prediction that is not finite is reported with the record named, never
scored.
"""

from __future__ import annotations

import csv
import functools
import hashlib
import io
import json
import math
from pathlib import Path

import numpy as np

from hysbench.data.dataset import Dataset
from hysbench.data.files import write_atomic
from hysbench.data.metrics import e_m, e_rms
from hysbench.identification import Fit

from .report import best_per_model, ranking

IDENTIFIED_ON = "virtual-dea"
UNSEEN_CSV = "matrix_unseen.csv"
CACHE_FILE = "unseen_scores.json"  # in the cell store's folder
CSV_COLUMNS = ("identified_on", "dataset", "model", "method", "record", "status", "e_m", "e_rms")


def score_unseen(result: dict, dataset: Dataset) -> dict:
    """The stored Fit of one finished cell scored on every record of ``dataset`` (not refitted)."""
    out = {"identified_on": result["dataset"], "dataset": dataset.name, "model": result["model"],
           "method": result["method"], "records": [], "nonfinite_records": [], "error": ""}
    try:
        fit = Fit.from_dict(result["fit"])
        for rec in dataset.records:
            y = fit.predict(rec)
            if not np.all(np.isfinite(y)):
                out["nonfinite_records"].append(rec.file)
                continue
            s = rec.scored
            out["records"].append({"file": rec.file, "e_m": e_m(y[s], rec.y[s]), "e_rms": e_rms(y[s], rec.y[s])})
    except Exception as exc:  # a Fit that cannot be rebuilt or simulated is reported, not fatal
        out["error"] = f"{type(exc).__name__}: {exc}"
        out["status"] = "failed"
        return out
    if out["nonfinite_records"]:
        out["error"] = f"non-finite model output on {', '.join(out['nonfinite_records'])}"
    out["status"] = "nonfinite" if out["nonfinite_records"] else "ok"
    return out


def score_cells(results: list[dict], dataset: Dataset, identified_on: str = IDENTIFIED_ON,
                cache: Path | None = None) -> list[dict]:
    """Every finished (status ok) cell identified on ``identified_on``, scored on ``dataset``. With ``cache``
    (a JSON file), a cell already scored on this dataset (same cell key, same dataset content) is read from
    it, not simulated again; the file is rewritten with the scores of these cells."""
    cells = [r for r in results if r["dataset"] == identified_on and r["status"] == "ok" and r.get("fit")]
    stored = _read_cache(cache)
    digest = f"{dataset.content_hash()}:{_scoring_code()}"  # the cell key covers the Fit's code, not this file
    scored = {}
    for r in sorted(cells, key=lambda r: (r["model"], r["method"])):
        key = f"{r['key']}:{digest}"
        scored[key] = stored[key] if key in stored else score_unseen(r, dataset)
    if cache is not None:
        write_atomic(cache, json.dumps(scored, sort_keys=True))
    return list(scored.values())


@functools.lru_cache(maxsize=1)
def _scoring_code() -> str:
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]


def _read_cache(path: Path | None) -> dict:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8")) if path is not None else {}
    except (OSError, ValueError):
        return {}  # absent or unreadable: every cell is scored again
    return data if isinstance(data, dict) else {}


def unseen_csv(scored: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    w.writeheader()
    for res in scored:
        base = {k: res[k] for k in ("identified_on", "dataset", "model", "method")}
        for rec in res["records"]:
            w.writerow({**base, "record": rec["file"], "status": "ok", "e_m": repr(rec["e_m"]),
                        "e_rms": repr(rec["e_rms"])})
        for file in res["nonfinite_records"]:
            w.writerow({**base, "record": file, "status": "nonfinite", "e_m": "", "e_rms": ""})
    return buf.getvalue()


def write_unseen_csv(out: Path, scored: list[dict]) -> None:
    write_atomic(Path(out) / UNSEEN_CSV, unseen_csv(scored))


def _mean_erms(res: dict) -> float:
    vals = [r["e_rms"] for r in res["records"]]
    return float(np.mean(vals)) if vals and res["status"] == "ok" else math.nan


def unseen_section(results: list[dict], scored: list[dict], dataset: Dataset) -> list[str]:
    """report.md's table: each model's best seven-sine cell, scored per unseen waveform."""
    by_cell = {(s["model"], s["method"]): s for s in scored}
    best = best_per_model(ranking(results, IDENTIFIED_ON))
    files = [r.file for r in dataset.records]
    lines = [f"## Unseen waveforms: identified on `{IDENTIFIED_ON}` (seven sines), validated on `{dataset.name}`", "",
             "Each model's best cell of the seven-sine ranking above, its stored Fit simulated (not refitted) on "
             "drives it was not identified on; each record is scored on the drive after a 0.2 Hz sine run-in "
             "through most of the creep transition. e_m / e_rms in % of each window's measured peak-to-peak; "
             "ratio = mean unseen e_rms / mean seven-sine validation e_rms. Sorted by mean unseen e_rms.", ""]
    if not best:
        return lines + ["No cell identified on the seven sines finished.", ""]
    rows = []
    for res, summ in best:
        s = by_cell.get((res["model"], res["method"]))
        if s is None:
            continue
        mean = _mean_erms(s)
        rows.append((math.inf if math.isnan(mean) else mean, res, summ, s, mean))
    rows.sort(key=lambda r: (r[0], r[1]["model"]))
    head = "| model (method) | sines: validation e_rms mean | " + " | ".join(Path(f).stem for f in files) \
        + " | unseen e_rms mean | ratio |"
    lines += [head, "|---|---:|" + "---:|" * len(files) + "---:|---:|"]
    for _, res, summ, s, mean in rows:
        recs = {r["file"]: r for r in s["records"]}
        cells = [f"{recs[f]['e_m']:.2f} / {recs[f]['e_rms']:.2f}" if f in recs
                 else ("non-finite" if f in s["nonfinite_records"] else "–") for f in files]
        ratio = mean / summ["val_mean"] if math.isfinite(mean) and summ["val_mean"] > 0 else math.nan
        lines.append(f"| {res['model']} ({res['method']}) | {summ['val_mean']:.2f} | " + " | ".join(cells)
                     + f" | {'–' if math.isnan(mean) else f'{mean:.2f}'} | "
                     + f"{'–' if math.isnan(ratio) else f'{ratio:.2f}'} |")
    bad = [s for s in scored if s["status"] != "ok"]
    if bad:
        lines += ["", "Cells whose prediction of an unseen waveform is not finite or failed (not scored):", ""]
        lines += [f"- {s['model']} / {s['method']}: {s['status']}: {s['error']}" for s in bad]
    lines += ["", f"Every cell's scores: `{UNSEEN_CSV}`.", ""]
    return lines

