"""diagnosis.md, its PNG figures (``figures``) and the JSON of a ``Diagnosis``."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hysbench.data.files import ensure_dir, write_atomic, write_json

from .candidates import at_bound
from .causes import OUTPUT_UNIT
from .extensions import scores_by_file
from .figures import FIGURES
from .residuals import LAGS
from .secondary import not_identified


def _fmt(v, digits: int = 4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x, digits) for x in v) + "]"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _estimates(c) -> str:
    return ", ".join(f"{k} = {_fmt(v)}" for k, v in c.estimates.items())


def base_bound_caution(fit) -> str:
    """What a base fit pinned at its search bounds (``Fit.diagnostics["at_bounds"]``) means ("" if none is)."""
    pinned = fit.diagnostics.get("at_bounds") or []
    if not pinned:
        return ""
    values = ", ".join(f"{n} = {fit.params[n]:.4g}" for n in pinned)
    return (f"the base model's fit has parameters at their search bounds ({values}): part of the misfit the "
            "diagnosis explains may be that bound's, not the actuator's")


def not_held_out_lines(d) -> list[str]:
    """The records the held-out test predicts only in part (``screen.held_out_windows``), with why."""
    names = []
    for s in d.settings.get("not_held_out") or []:
        t, share = s.get("held_out_until_s"), s.get("predicted_share")
        of = f", {100 * share:.0f} % of it" if share is not None else ""
        until = "not predicted" if t is None else f"predicted up to t = {t:.4g} s{of}"
        names.append(f"{s['record']} ({until}; beyond by {100 * s['beyond_others_range']:.0f} % of the input span)")
    if not names:
        return []
    return ["", f"Held out in part: {', '.join(names)}. A record that goes beyond the other identification records' "
                f"input range by more than {100 * d.policy.beyond_range:.0f} % of the span is predicted only up to "
                "where it first does (a fit on the others would extrapolate beyond); it takes part whole in every "
                "other fold's fit, and the held-out scores cover the rows predicted."]


def _spread(name: str, u: dict, shown: str, units: dict, open_: bool, pinned: bool) -> str:
    """One parameter's fold spread, named by the mean of its fold estimates (a relaxation's time constants are
    reported sorted, their names are the fit's own order)."""
    unit = units.get(shown, units.get(next((k for k in units if shown.startswith(k.split("_")[0])), ""), ""))
    v = np.asarray(u["folds"], dtype=float)
    mean = float(np.exp(np.log(v).mean()) if "relative_se" in u and np.all(v > 0) else v.mean())
    head = f"{shown} ({_fmt(mean)}{f' {unit}' if unit else ''})"
    if open_ or pinned:
        return f"{head}: not identified" + (" (at a search bound on every fold)" if pinned else "")
    return head + (f" ±{100 * u['relative_se']:.2g} %" if "relative_se" in u else
                   f" ±{_fmt(u['se'], 2)}{f' {unit}' if unit else ''}")


def _pinned_on_every_fold(d) -> set:
    """The named cause's parameters at a search bound in every fold's refit (their spread says nothing)."""
    c, folds = d.chosen, [dict(zip(d.uncertainty, f)) for f in zip(*(u["folds"] for u in d.uncertainty.values()))]
    at = [set(at_bound(d.screen, SimpleNamespace(kind=c.kind, model=c.model, params={**c.params, **f})))
          for f in folds]
    return set.intersection(*at) if at else set()


def _also_on_validation(check: dict | None) -> str:
    """What a cause kept under "also" did on the validation records, on top of what was kept before it."""
    if not check:
        return ""
    if not check["checked"]:
        return f" (validation: {check['note']})"
    return (f" (validation, on top of what was kept before it: {100 * check['explained_whole']:.1f} % removed, "
            f"z = {check['z_whole']:.2f}; " + ("borne out)" if check["borne_out"] else "NOT borne out)"))


def verdict_lines(d, strong=lambda text: text, code=lambda text: text) -> list[str]:
    """The verdict as plain lines (the report bullets them, the CLI prints them): the cause, its parameters and
    uncertainty, ambiguity and suggested experiments, the validation gain."""
    unit = d.dataset.output_unit or "output units"
    lines = [f"cause: {strong(d.cause)} ({d.verdict.reason})"]
    if d.chosen is not None:  # the named parameters (per-record phases and diagnostics are in the JSON)
        kind = d.chosen.kind
        units = {k: unit if u is OUTPUT_UNIT else u for k, u in kind.units.items()}
        open_ = set(d.chosen.heldout.get("open_ended") or [])  # its folds at the bound agree trivially
        unidentified = {kind.reported_as.get(n, n) for n in open_}
        lines.append("parameters: " + ", ".join(f"{k} = {_fmt(v)}" + (f" {units[k]}" if units[k] else "")
                                                + (" (not identified)" if k in unidentified else "")
                                                for k, v in d.parameters.items() if k in units))
        if d.uncertainty:
            pinned = _pinned_on_every_fold(d)
            lines.append("uncertainty (jackknife over the held-out folds; the folds' mean after each name): "
                         + ", ".join(_spread(k, v, kind.reported_as.get(k, k), units, k in open_, k in pinned)
                                     for k, v in d.uncertainty.items()))
        how = (f"identified with {d.extended_fit.method} on the identification records' whole length"
               if d.extended_fit else "phase fitted per record")
        lines.append(f"extended model: {code(d.extended_model)} ({how})")
    if (p := d.verdict.partial) is not None:
        share = p.heldout.get("share_of_misfit")
        lines.append(f"best partial candidate: {p.label} (held-out gain {100 * p.heldout_gain:.2f} %"
                     + (f", {100 * share:.0f} % of the misfit beyond noise)" if share is not None else ")"))
    if u := d.unexplained_check:
        lines.append(f"the best partial candidate on the validation records (records {', '.join(u['records'])}, "
                     f"fitted on the identification records' whole length): {100 * u['explained_whole']:.2f} % of "
                     f"their residual removed, z = {u['z_whole']:.2f} "
                     + ("(borne out: the verdict stays unexplained)" if u["borne_out"] else
                        f"(not borne out, needs {d.policy.z_confirm:.3g}: the verdict is none)"))
    for c in d.verdict.ambiguous_with:
        lines.append(strong(f"ambiguous with {c.cause}") + f": {c.label} predicts the held-out records as well "
                     f"(gain {100 * c.heldout_gain:.2f} %; {_estimates(c)})")
    for e in d.experiments:
        pair = " vs ".join(e["causes"]) + (f", on top of {e['on_top_of']}" if e.get("on_top_of") else "")
        if e.get("frequency_hz"):
            lines.append(f"suggested experiment ({pair}): drive with a {e['drive']} at {_fmt(e['frequency_hz'], 3)} "
                         f"Hz, where the two fits differ most ({_fmt(e['separation'], 3)} {unit} rms, noise sd "
                         f"{_fmt(e['noise_sd'], 3)})")
        else:
            lines.append(f"suggested experiment ({pair}): {e['drive'] or 'none'}"
                         + (f" (the two fits differ by {_fmt(e['separation'], 3)} {unit} rms)"
                            if e.get("separation") else "")
                         + (f": {e['note']}" if e.get("note") else ""))
    lines += [f"not identified: {n}" for n in d.verdict.not_identified]
    also = []
    for c, check in zip(d.also, d.also_check or [None] * len(d.also)):  # one check per cause under also once checked
        text, why, fits = c.cause, not_identified(c), d.as_good_as(c)
        if fits:
            text += f" (or, as good on these records: {'; '.join(f'{a.cause}: {_estimates(a)}' for a in fits)})"
        also.append(text + (f" (not identified: {why})" if why else "") + _also_on_validation(check))
    lines.append(f"also: {', '.join(also) if also else 'none'}")
    f = d.structure.get("F")
    lines.append(f"measurement noise sd (from first differences): {_fmt(d.noise_sd)} {unit}; residual "
                 "period-to-period F = " + (_fmt(f, 3) if d.structure.get("records") else
                                            "- (no record repeats its drive period)"))
    g = d.gain()
    if g:
        v = g["validation"]
        lines.append(f"validation gain (records {', '.join(v['records'])}, against the base model refitted on the "
                     "same whole records): " + strong(f"{100 * v['explained_whole']:.2f} %") + " of its residual sum "
                     f"of squares removed over whole records (z = {v['z_whole']:.2f} against the records' own noise, "
                     f"correlated noise counted; confirmed from {d.policy.z_confirm:.3g}), "
                     f"{100 * v['explained_window']:.2f} % on the scored windows; mean e_rms on the windows "
                     f"{v['mean_e_rms_before']:.3g} % -> {v['mean_e_rms_after']:.3g} %.")
        vw = g["validation_vs_base_fitted_on_windows"]
        lines.append("against the base model fitted on the windows (the benchmark's): "
                     f"{100 * vw['explained_whole']:.2f} % whole, {100 * vw['explained_window']:.2f} % on the windows.")
    if d.warning:
        lines.append(strong("warning:") + f" {d.warning}.")
    lines += [strong("caution:") + f" {c}" for c in (base_bound_caution(d.base_fit), d.one_drive_caution) if c]
    return lines


SHARES = ("gain", "share_of_misfit", "explained_whole", "explained_window")  # fractions, shown in %


def _inputs_text(value, key: str = "") -> str:
    """A trace entry's inputs in one line: numbers to 3 significant digits, shares in %, a candidate's score by
    its cause and label (a cause can have several candidates)."""
    if isinstance(value, dict):
        if "cause" in value and "gain" in value:
            label = value.get("label") or value["cause"]
            name = label if label.startswith(value["cause"]) else f"{value['cause']}: {label}"
            return f"{name} (gain {_inputs_text(value['gain'], 'gain')}, z {_fmt(value.get('z'), 3)})"
        return ", ".join(f"{k} {_inputs_text(v, k)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_inputs_text(v) for v in value) + "]"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{_fmt(100 * value, 3)} %" if key in SHARES and math.isfinite(value) else _fmt(value, 3)
    return str(value)


def trace_lines(d) -> list[str]:
    """The rules that decided the verdict, in order (``Diagnosis.trace``): rule id, outcome, inputs."""
    return [f"{i}. `{t['rule']}` -> **{t['outcome']}**" + (f" ({_inputs_text(t['inputs'])})" if t["inputs"] else "")
            for i, t in enumerate(d.trace, start=1)]


def markdown(d, figures: dict[str, str], note: str = "") -> str:
    """diagnosis.md; ``figures``: the file of each figure drawn, by its key in ``FIGURES``."""
    lines = [
        f"# Diagnosis: {d.model} on {d.dataset.name}", "", *([note, ""] if note else []),
        f"`hysbench diagnose` (seed {d.seed}): the base model identified with varpro on the identification "
        "records' scored windows, simulated over every record whole; candidate causes fitted on the identification "
        "records' whole length and chosen by leave-one-record-out prediction against the base model refitted the "
        "same way; the named extension identified with the identifiers and scored on validation records that took "
        "part in no fit and no choice.", ""]
    if k := d.settings.get("segments"):
        lines += [f"Each identification record was cut into {k} consecutive records of whole periods, each from an "
                  f"input minimum (`--segments {k}`): the held-out folds are neighbouring stretches of one drive, so "
                  "the evidence says what holds over that drive, not what holds at other drives.", ""]
    if d.settings.get("thorough"):
        lines += ["Every cause was tried afresh on top of the named one (`--thorough`), also on these long records.",
                  ""]
    lines += ["## Verdict", ""]
    lines += [f"* {line}" for line in verdict_lines(d, strong=lambda t: f"**{t}**", code=lambda t: f"`{t}`")]
    lines += ["", "## Why: the rules that decided, in order", "",
              "Each rule that decided or changed the verdict (by its id; the rules are stated at the end of this "
              "report), with what it decided and on what.", "", *trace_lines(d)]
    lines += ["", "## Evidence: candidate causes (held-out)", "",
              f"Rows: {d.screen.n} samples of the identification records (whole length, at most "
              f"{d.settings['max_rows']} per record). The causes' bounds scale with the shortest drive period, "
              f"{d.settings['drive_time_s']:.3g} s; creep must be slower than {d.settings['creep_min_s']:.3g} s. "
              f"P{d.policy.summary()[1:]}; every field is in the JSON (`policy`); the rule with its values is at the "
              "end of this report.", *not_held_out_lines(d), "",
              "| cause | candidate | stage | k | held-out gain | z | folds improved | refit per fold | at bound "
              "| estimates |", "|---|---|---|---|---|---|---|---|---|---|"]
    for c in sorted(d.candidates + [v for v in d.relaxation_variants if v not in d.candidates],
                    key=lambda c: -c.heldout_gain):
        mark = " **(named)**" if c is d.chosen else (f" (not named: {c.limit})" if c.limit else "")
        h = c.heldout
        bound = [*(h.get("at_bound") or []), *(f"{n} (open-ended)" for n in h.get("open_ended") or [])]
        lines.append(f"| {c.cause}{mark} | {c.label} | {c.stage} | {c.k} | {100 * c.heldout_gain:.3f} % | "
                     f"{_fmt(h.get('z'), 3)} | {h.get('folds_improved')}/{h.get('n_folds')} | "
                     f"{'yes' if h.get('refit_per_fold') else 'no'} | {', '.join(bound) or '-'} | {_estimates(c)} |")
    if d.secondary_tried:
        lines += ["", "Secondary causes tried on top of the named one (held-out against the named one alone):", "",
                  "| cause | held-out gain | z | also? |", "|---|---|---|---|",
                  *(f"| {t.cause} | {100 * t.heldout_gain:.3f} % | {_fmt(t.heldout.get('z'), 3)} | "
                    f"{'yes' if any(t is a for a in d.also) else 'no'} |" for t in d.secondary_tried)]
    lib = d.library
    lines += ["", "## Evidence: library screen (pysindy)", "",
              f"{lib['method']}: the base-alone residual regressed on {lib['n_library']} candidate terms (each made "
              f"orthogonal to the base model's regressors). {lib['n_terms']} term(s) kept, explaining "
              f"{100 * lib['explained_total']:.2f} % of the residual sum of squares.", ""]
    if lib["terms"]:
        lines += ["| order | term | group | share explained |", "|---|---|---|---|",
                  *(f"| {t['order']} | `{t['name']}` | {t['group']} | {100 * t['explained']:.3f} % |"
                    for t in lib["terms"])]
        lines += ["", "Share by cause: " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in lib["groups"].items()), ""]
    lines += ["## Residuals of the base model", "", "| record | role | f (Hz) | noise sd | rms whole | rms window | "
              f"lag-1 autocorr. | Ljung-Box p ({LAGS} lags) |", "|---|---|---|---|---|---|---|---|",
              *(f"| {s.file} | {s.role} | {_fmt(s.frequency_hz)} | {_fmt(s.noise_sd, 3)} | {_fmt(s.rms, 3)} | "
                f"{_fmt(s.rms_window, 3)} | {s.lag1_autocorrelation:.3f} | {_fmt(s.ljung_box_p, 3)} |"
                for s in d.summaries)]
    lines += ["", "## e_m / e_rms per record (% of the measured peak-to-peak)", "",
              "Window: the record's scored window (the benchmark's metric); whole: every sample.", ""]
    three, two = ("e_m", "e_rms", "e_rms_whole"), ("e_rms", "e_rms_whole")
    cols = [(f"{name} {k.replace('_whole', ' whole')}", scores_by_file(recs), k)  # (header, scores by file, key)
            for name, recs, keys in (("before", d.before, three), ("base refit", d.base_whole, two),
                                     ("after", d.after, three)) if recs for k in keys]
    lines += ["| record | role | " + " | ".join(c for c, _, _ in cols) + " |", "|---|---|" + "---|" * len(cols)]
    lines += [f"| {rr.file} | {rr.record.role} | " + " | ".join(f"{by[rr.file][k]:.3f}" for _, by, k in cols) + " |"
              for rr in d.before]
    lines += ["", "## Figures", ""]
    for key, file in figures.items():
        lines += [f"### {FIGURES[key][1]}", "", f"![{key}]({file})", ""]
    lines += ["## The decision rule", "", d.decision_rule, ""]
    lines += ["## Run", "", "Wall time (s): " + ", ".join(f"{k} {v:.1f}" for k, v in d.timings.items()) + ".", ""]
    for title, fit in (("the base model's fit", d.base_fit), ("the extended fit", d.extended_fit)):
        if fit and fit.notes:
            lines += [f"Notes of {title}:", "", *(f"* {n}" for n in fit.notes), ""]
    return "\n".join(lines)


def write_report(diag, out: str | Path, json_path: str | Path | None = None, note: str = "") -> dict:
    """Write diagnosis.md and diagnosis_*.png in ``out``, the JSON to ``json_path`` (default: out/diagnosis.json)."""
    out = ensure_dir(out)
    figures = {}
    for key, (fn, _) in FIGURES.items():
        file = f"diagnosis_{key}.png"
        (out / file).unlink(missing_ok=True)  # a figure this diagnosis does not draw is not an earlier run's
        fn(diag, out / file)
        if (out / file).exists():
            figures[key] = file
    data = diag.to_json()
    json_path = Path(json_path) if json_path else out / "diagnosis.json"
    ensure_dir(json_path.parent)
    write_json(json_path, data)
    write_atomic(out / "diagnosis.md", markdown(diag, figures, note) + "\n")
    return data
