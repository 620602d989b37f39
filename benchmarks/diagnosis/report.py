"""diagnosis.md, its PNG figures and the JSON of a ``Diagnosis``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hysbench.benchmarks.plots import pyplot, save_figure
from hysbench.data.files import ensure_dir, write_atomic, write_json

from .residuals import LAGS, autocorrelation, coherent_spectrum, periodogram, phase_of
from .secondary import not_identified

MAX_PLOT_POINTS = 4_000  # per record and curve: a figure is about 1,000 pixels wide


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


def _stride(n: int) -> int:
    return max(1, int(math.ceil(n / MAX_PLOT_POINTS)))


def extremes_kept(key: np.ndarray, y: np.ndarray, bins: int = MAX_PLOT_POINTS // 2, low: bool = True) -> np.ndarray:
    """Sorted indices of each bin's largest (and, if ``low``, smallest) ``y``, the bins equal in the
    ascending ``key``: a long curve thinned for plotting without losing its peaks."""
    if y.size <= 2 * bins:
        return np.arange(y.size)
    bounds = np.unique(np.searchsorted(key, np.linspace(key[0], key[-1], bins + 1)[1:-1]))
    kept = []
    for lo, hi in zip(np.concatenate(([0], bounds)), np.concatenate((bounds, [y.size]))):
        if hi > lo:
            kept.append(lo + np.argmax(y[lo:hi]))
            if low:
                kept.append(lo + np.argmin(y[lo:hi]))
    return np.unique(np.array(kept))


def _label(rec) -> str:
    return f"{rec.label} ({'id' if rec.role == 'identification' else 'val'})"


# --- figures --------------------------------------------------------------------
def figure_residual_time(diag, path: Path) -> None:
    plt = pyplot()
    recs = diag.before
    fig, axes = plt.subplots(len(recs), 1, figsize=(9, 1.6 * len(recs) + 0.6), squeeze=False, layout="constrained")
    after = {rr.file: rr for rr in diag.after}
    for ax, rr in zip(axes[:, 0], recs):
        r = rr.record
        k = extremes_kept(r.t, rr.residual)
        ax.plot(r.t[k], rr.residual[k], lw=0.6, color="0.35", label=f"{diag.model} (before)")
        if rr.file in after:
            k = extremes_kept(r.t, after[rr.file].residual)
            ax.plot(r.t[k], after[rr.file].residual[k], lw=0.6, color="C3", label=f"{diag.extended_model} (after)")
        ax.axvspan(r.t[r.start], r.t[r.stop - 1], color="C0", alpha=0.12, lw=0)
        ax.axhline(0, color="k", lw=0.4)
        ax.set_ylabel(_label(r), fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[0, 0].set_title(f"residual (measured - model, {diag.dataset.output_unit or 'output units'}) over whole "
                         "records; shaded: scored window", fontsize=9)
    axes[-1, 0].set_xlabel("time (s)")
    save_figure(fig, path)


def _panels(plt, n: int):
    """A figure with one small panel per record, four to a row."""
    cols = min(4, n)
    rows = int(math.ceil(n / cols))
    return plt.subplots(rows, cols, figsize=(3.0 * cols, 2.4 * rows), squeeze=False, layout="constrained")


def figure_residual_input(diag, path: Path) -> None:
    plt = pyplot()
    recs = diag.before
    n = len(recs)
    fig, axes = _panels(plt, n)
    for ax, rr in zip(axes.flat, recs):
        r = rr.record
        k = _stride(r.t.size)
        ax.plot(r.u[::k], rr.residual[::k], ".", ms=1, color="0.6", label="whole record")
        w = slice(r.start, r.stop, _stride(r.stop - r.start))  # the scored window, thinned
        ax.plot(r.u[w], rr.residual[w], lw=0.7, color="C0", label="window")
        ax.set_title(_label(r), fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=6)
    fig.supxlabel(f"input ({diag.dataset.input_unit or 'input units'})", fontsize=8)
    fig.supylabel("residual (base model)", fontsize=8)
    save_figure(fig, path)


def figure_residual_phase(diag, path: Path) -> None:
    plt = pyplot()
    recs = [rr for rr in diag.before if rr.record.frequency_hz]
    if not recs:
        return
    n = len(recs)
    fig, axes = _panels(plt, n)
    for ax, rr in zip(axes.flat, recs):
        r = rr.record
        ph = phase_of(r)
        k = _stride(r.t.size)
        ax.plot(ph[::k], rr.residual[::k], ".", ms=1, color="0.7", label="all periods")
        w = slice(r.start, r.stop, _stride(r.stop - r.start))  # the scored window, thinned
        order = np.argsort(ph[w])
        ax.plot(ph[w][order], rr.residual[w][order], lw=0.8, color="C0", label="scored period")
        ax.set_title(_label(r), fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=6)
    fig.supxlabel("phase within the drive period (0: input minimum)", fontsize=8)
    fig.supylabel("residual (base model)", fontsize=8)
    save_figure(fig, path)


def figure_spectrum(diag, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    ax = axes[0]
    for i, rr in enumerate(diag.before):
        f, a = periodogram(rr.residual, rr.record.dt)
        f, a = f[f > 0], a[f > 0]
        keep = extremes_kept(np.log(f), a, low=False)
        ax.loglog(f[keep], np.maximum(a[keep], 1e-12), lw=0.5, color=f"C{i % 10}", label=_label(rr.record))
    ax.axhline(diag.noise_sd * 2.0 / math.sqrt(max(rr.record.t.size for rr in diag.before)), color="k", ls=":", lw=0.8)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("residual amplitude")
    ax.set_title("residual spectrum per record (base model)", fontsize=9)
    ax.legend(fontsize=6)
    ax = axes[1]
    ids = [rr for rr in diag.before if rr.record.role == "identification"]
    duration = max(rr.record.t.size * rr.record.dt for rr in ids)
    dt = max(rr.record.dt for rr in ids)  # below every record's Nyquist frequency
    f, a = coherent_spectrum(ids, 1.0 / duration, 0.45 / dt, pad=2)
    keep = extremes_kept(np.log(f), a, low=False)
    ax.loglog(f[keep], np.maximum(a[keep], 1e-12), lw=0.5, color="C0")
    if diag.cause == "interference":
        ax.axvline(diag.parameters["frequency_hz"], color="C3", lw=0.8, ls="--", label="named interference")
        ax.legend(fontsize=7)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("pooled coherent amplitude")
    ax.set_title("identification records pooled in their own time\n(a disturbance with a common phase adds up)",
                 fontsize=9)
    save_figure(fig, path)


def figure_error_vs_frequency(diag, path: Path) -> None:
    if not any(rr.record.frequency_hz for rr in diag.before):  # no nominal drive frequency: nothing to plot
        return
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    series = [("before", diag.before, "0.3", "o")]
    if diag.base_whole:
        series.append(("base refit, whole records", diag.base_whole, "C0", "s"))
    if diag.after:
        series.append(("after", diag.after, "C3", "^"))
    for ax, key, title in ((axes[0], "e_rms", "scored window"), (axes[1], "e_rms_whole", "whole record")):
        for name, recs, color, marker in series:
            pts = sorted((rr.record.frequency_hz, rr.scores()[key], rr.record.role) for rr in recs
                         if rr.record.frequency_hz)
            if not pts:
                continue
            f = [p[0] for p in pts]
            ax.plot(f, [p[1] for p in pts], "-", color=color, lw=0.8, label=name)
            for fr, v, role in pts:
                ax.plot(fr, v, marker, color=color, mfc=color if role == "identification" else "white", ms=5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("drive frequency (Hz)")
        ax.set_ylabel("e_rms (% of measured peak-to-peak)")
        ax.set_title(f"error against frequency, {title}\n(filled: identification, open: validation)", fontsize=9)
    axes[0].legend(fontsize=7)
    save_figure(fig, path)


def figure_whiteness(diag, path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 3.8), layout="constrained")
    lags = np.arange(1, LAGS + 1)
    for i, (rr, s) in enumerate(zip(diag.before, diag.summaries)):
        rho = autocorrelation(rr.residual, LAGS)
        ax.plot(lags, rho, "o-", ms=2, lw=0.7, color=f"C{i % 10}",
                label=f"{_label(rr.record)}: Ljung-Box p = {s.ljung_box_p:.2g}")
    n = min(rr.record.t.size for rr in diag.before)
    ax.axhspan(-1.96 / math.sqrt(n), 1.96 / math.sqrt(n), color="0.85", lw=0, label="95 % band of white noise")
    ax.axhline(0, color="k", lw=0.4)
    ax.set_xlabel("lag (samples)")
    ax.set_ylabel("autocorrelation of the residual")
    ax.set_title("whiteness of the base model's residual (whole records)", fontsize=9)
    ax.legend(fontsize=6)
    save_figure(fig, path)


def figure_candidates(diag, path: Path) -> None:
    plt = pyplot()
    cands = sorted(diag.candidates, key=lambda c: -c.heldout_gain)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), layout="constrained")
    names = [c.cause for c in cands]
    colors = ["C3" if diag.chosen is not None and c is diag.chosen else "0.5" for c in cands]
    axes[0].barh(names, [100 * max(c.heldout_gain, -1.0) for c in cands], color=colors)
    axes[0].axvline(100 * diag.policy.min_explained, color="k", ls=":", lw=0.8)
    axes[0].set_xlabel("held-out gain over the base model (%, leave one record out; floored at -100)")
    axes[0].invert_yaxis()
    axes[1].barh(names, [max(min(c.heldout.get("z", 0.0), 40.0), -10.0) for c in cands], color=colors)
    axes[1].axvline(diag.policy.z_pass, color="k", ls=":", lw=0.8)
    axes[1].set_xlabel("z (signed-rank test over blocks)")
    axes[1].invert_yaxis()
    fig.suptitle("candidate causes (red: named)", fontsize=9)
    save_figure(fig, path)


FIGURES = {
    "residual_time": (figure_residual_time, "Residual against time, whole records (shaded: the scored window)"),
    "residual_input": (figure_residual_input, "Residual against the input"),
    "residual_phase": (figure_residual_phase, "Residual against the phase within the drive period, per frequency"),
    "residual_spectrum": (figure_spectrum, "Residual spectrum"),
    "error_vs_frequency": (figure_error_vs_frequency, "How the error grows with frequency"),
    "whiteness": (figure_whiteness, "Whiteness of the residual"),
    "candidates": (figure_candidates, "Candidate causes"),
}


# --- markdown ---------------------------------------------------------------------
def base_bound_caution(fit) -> str:
    """What a base fit pinned at its search bounds (``Fit.diagnostics["at_bounds"]``) means for the
    verdict ("" if none is)."""
    pinned = fit.diagnostics.get("at_bounds") or []
    if not pinned:
        return ""
    values = ", ".join(f"{n} = {fit.params[n]:.4g}" for n in pinned)
    return (f"the base model's fit has parameters at their search bounds ({values}): part of the misfit the "
            "diagnosis explains may be that bound's, not the actuator's")


def not_held_out_lines(d) -> list[str]:
    """The records the held-out test predicts only in part (``screen.held_out_windows``), with why."""
    skipped = d.settings.get("not_held_out") or []
    if not skipped:
        return []

    def until(s) -> str:
        t = s.get("held_out_until_s")
        share = s.get("predicted_share")
        of = f", {100 * share:.0f} % of it" if share is not None else ""
        return "not predicted" if t is None else f"predicted up to t = {t:.4g} s{of}"

    names = ", ".join(f"{s['record']} ({until(s)}; beyond by {100 * s['beyond_others_range']:.0f} % of the input "
                      "span)" for s in skipped)
    return ["", f"Held out in part: {names}. A record that goes beyond the other identification records' input "
                f"range by more than {100 * d.policy.beyond_range:.0f} % of the span is predicted only up to where it first "
                "does (a fit on the others would extrapolate beyond); it takes part whole in every other fold's fit, "
                "and the held-out scores cover the rows predicted."]


REPORTED_AS = {"creep_time": "time_scale_s"}  # an open-ended parameter's name among the reported parameters


def _bound_cell(heldout: dict) -> str:
    """The candidate table's bound column: parameters at a bound, and open-ended ones (``selection.open_ended``)."""
    names = [*(heldout.get("at_bound") or []), *(f"{n} (open-ended)" for n in heldout.get("open_ended") or [])]
    return ", ".join(names) or "-"


def _also_on_validation(check: dict | None) -> str:
    """What a cause kept under "also" did on the validation records, on top of what was kept before it."""
    if not check:
        return ""
    if not check["checked"]:
        return f" (validation: {check['note']})"
    return (f" (validation, on top of what was kept before it: {100 * check['explained_whole']:.1f} % removed, "
            f"z = {check['z_whole']:.2f}; " + ("borne out)" if check["borne_out"] else "NOT borne out)"))


def verdict_lines(d, strong=lambda text: text, code=lambda text: text) -> list[str]:
    """The verdict as plain lines (the report bullets them, the CLI prints them): the cause, its
    parameters and uncertainty, ambiguity and suggested experiments, the validation gain."""
    unit = d.dataset.output_unit or "output units"
    lines = [f"cause: {strong(d.cause)} ({d.verdict.reason})"]
    units = {"tau_s": "s", "delay_s": "s", "natural_frequency_hz": "Hz", "damping_ratio": "", "time_scale_s": "s",
             "frequency_hz": "Hz", "size": unit, "amplitude": unit, "level": unit, "side": ""}
    if d.chosen is not None:  # the named parameters (per-record phases and diagnostics are in the JSON)
        open_ = set(d.chosen.heldout.get("open_ended") or [])  # its folds at the bound agree trivially
        unidentified = {REPORTED_AS.get(n, n) for n in open_}
        lines.append("parameters: " + ", ".join(f"{k} = {_fmt(v)}" + (f" {units[k]}" if units[k] else "")
                                                + (" (not identified)" if k in unidentified else "")
                                                for k, v in d.parameters.items() if k in units))
        if d.uncertainty:
            lines.append("uncertainty (jackknife over the held-out folds): " + ", ".join(
                f"{k}: not identified" if k in open_ else
                f"{k} ±{100 * v['relative_se']:.2g} %" if "relative_se" in v else f"{k} ±{_fmt(v['se'], 2)}"
                for k, v in d.uncertainty.items()))
        how = (f"identified with {d.extended_fit.method} on the identification records' whole length"
               if d.extended_fit else "phase fitted per record")
        lines.append(f"extended model: {code(d.extended_model)} ({how})")
    if d.verdict.partial is not None:
        p = d.verdict.partial
        lines.append(f"best partial candidate: {p.label} (held-out gain {100 * p.heldout_gain:.2f} %, "
                     f"{_fmt(p.heldout.get('share_of_misfit'))} of the misfit beyond noise)")
    u = d.unexplained_check
    if u and u["checked"]:
        lines.append(f"the best partial candidate on the validation records (records {', '.join(u['records'])}, "
                     f"fitted on the identification records' whole length): {100 * u['explained_whole']:.2f} % of "
                     f"their residual removed, z = {u['z_whole']:.2f} "
                     + ("(borne out: the verdict stays unexplained)" if u["borne_out"] else
                        f"(not borne out, needs {d.policy.z_confirm:.3g}: the verdict is none)"))
    elif u:
        lines.append(f"the best partial candidate not checked on validation records: {u['note']}")
    for c in d.verdict.ambiguous_with:
        lines.append(strong(f"ambiguous with {c.cause}") + f": {c.label} predicts the held-out records as well "
                     f"(gain {100 * c.heldout_gain:.2f} %; {_estimates(c)})")
    for e in d.experiments:
        pair = " vs ".join(e["causes"]) + (f", on top of {e['on_top_of']}" if e.get("on_top_of") else "")
        if e.get("frequency_hz"):
            lines.append(f"suggested experiment ({pair}): drive with a {e['drive']} at "
                         f"{_fmt(e['frequency_hz'], 3)} Hz, where the two fits differ most ({_fmt(e['separation'], 3)} "
                         f"{unit} rms, noise sd {_fmt(e['noise_sd'], 3)})")
        else:
            lines.append(f"suggested experiment ({pair}): {e['drive'] or 'none'}"
                         + (f" ({_fmt(e['separation'], 3)} {unit} rms)" if e.get("separation") else "")
                         + (f": {e['note']}" if e.get("note") else ""))
    for n in d.verdict.not_identified:
        lines.append(f"not identified: {n}")
    also = []
    checks = d.also_check or [None] * len(d.also)  # one per cause under also once checked
    for c, check in zip(d.also, checks):
        text, why = c.cause, not_identified(c)
        fits = d.as_good_as(c)
        if fits:
            text += f" (or, as good on these records: {'; '.join(f'{a.cause}: {_estimates(a)}' for a in fits)})"
        also.append(text + (f" (not identified: {why})" if why else "") + _also_on_validation(check))
    lines.append(f"also: {', '.join(also) if also else 'none'}")
    lines.append(f"measurement noise sd (from first differences): {_fmt(d.noise_sd)} {unit}; residual "
                 f"period-to-period F = {_fmt(d.structure.get('F'), 3)}")
    g = d.gain()
    if g:
        v = g["validation"]
        lines.append(f"validation gain (records {', '.join(v['records'])}, against the base model refitted on the "
                     "same whole records): " + strong(f"{100 * v['explained_whole']:.2f} %") + " of its residual sum "
                     f"of squares removed over whole records (z = {v['z_whole']:.2f} against the records' own noise, "
                     f"correlated noise counted; confirmed from {d.policy.z_confirm:.3g}), "
                     f"{100 * v['explained_window']:.2f} % on the scored "
                     f"windows; mean e_rms on the windows {v['mean_e_rms_before']:.3g} % -> {v['mean_e_rms_after']:.3g} %.")
        vw = g["validation_vs_base_fitted_on_windows"]
        lines.append(f"against the base model fitted on the windows (the benchmark's): {100 * vw['explained_whole']:.2f} % "
                     f"whole, {100 * vw['explained_window']:.2f} % on the windows.")
    if d.warning:
        lines.append(strong("warning:") + f" {d.warning}.")
    for caution in (base_bound_caution(d.base_fit), d.one_drive_caution):
        if caution:
            lines.append(strong("caution:") + f" {caution}")
    return lines


def _inputs_text(value) -> str:
    """A trace entry's inputs in one line: numbers to 3 significant digits, a candidate's score by its cause."""
    if isinstance(value, dict):
        if "cause" in value and "gain" in value:
            return f"{value['cause']} (gain {_fmt(value['gain'], 3)}, z {_fmt(value.get('z'), 3)})"
        return ", ".join(f"{k} {_inputs_text(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_inputs_text(v) for v in value) + "]"
    if isinstance(value, float):
        return _fmt(value, 3)
    return str(value)


def trace_lines(d) -> list[str]:
    """The rules that decided the verdict, in order (``Diagnosis.trace``): rule id, outcome, inputs."""
    return [f"{i}. `{t['rule']}` -> **{t['outcome']}**" + (f" ({_inputs_text(t['inputs'])})" if t["inputs"] else "")
            for i, t in enumerate(d.trace, start=1)]


def markdown(diag, figures: dict[str, str], note: str = "") -> str:
    d = diag
    lines = [f"# Diagnosis: {d.model} on {d.dataset.name}", ""]
    if note:
        lines += [note, ""]
    lines += [
        f"`hysbench diagnose` (seed {d.seed}): the base model identified with varpro on the identification "
        "records' scored windows, simulated over every record whole; candidate causes fitted on the identification "
        "records' whole length and chosen by leave-one-record-out prediction against the base model refitted the "
        "same way; the named extension identified with the identifiers and scored on validation records that took "
        "part in no fit and no choice.", ""]
    if d.settings.get("segments"):
        k = d.settings["segments"]
        lines += [f"Each identification record was cut into {k} consecutive records of whole periods, each from an input "
                  f"minimum (`--segments {k}`): "
                  "the held-out folds are neighbouring stretches of one drive, so the evidence says what holds over "
                  "that drive, not what holds at other drives.", ""]
    if d.settings.get("thorough"):
        lines += ["Every cause was tried afresh on top of the named one (`--thorough`), also on these long records.", ""]
    lines += ["## Verdict", ""]
    lines += [f"* {line}" for line in verdict_lines(d, strong=lambda text: f"**{text}**", code=lambda text: f"`{text}`")]
    lines += ["", "## Why: the rules that decided, in order", "",
              "Each rule of docs/diagnosis.md (\"The decision rule\") that decided or changed the verdict, with what "
              "it decided and on what.", "", *trace_lines(d)]
    lines += ["", "## Evidence: candidate causes (held-out)", "",
              f"Rows: {d.screen.n} samples of the identification records (whole length, at most "
              f"{d.settings['max_rows']} per record). The causes' bounds scale with the shortest drive period, "
              f"{d.settings['drive_time_s']:.3g} s; creep must be slower than {d.settings['creep_min_s']:.3g} s. "
              f"Rule: {d.decision_rule}.", "", f"P{d.policy.summary()[1:]}; every field is in the JSON "
              "(`policy`).", *not_held_out_lines(d), "",
              "| cause | candidate | stage | k | held-out gain | z | folds improved | refit per fold | at bound | estimates |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for c in sorted(d.candidates + [v for v in d.relaxation_variants if v not in d.candidates],
                    key=lambda c: -c.heldout_gain):
        mark = " **(named)**" if c is d.chosen else (f" (not named: {c.limit})" if c.limit else "")
        h = c.heldout
        lines.append(f"| {c.cause}{mark} | {c.label} | {c.stage} | {c.k} | {100 * c.heldout_gain:.3f} % | "
                     f"{_fmt(h.get('z'), 3)} | {h.get('folds_improved')}/{h.get('n_folds')} | "
                     f"{'yes' if h.get('refit_per_fold') else 'no'} | {_bound_cell(h)} | "
                     + ", ".join(f"{k} = {_fmt(v)}" for k, v in c.estimates.items()) + " |")
    if d.secondary_tried:
        lines += ["", "Secondary causes tried on top of the named one (held-out against the named one alone):", "",
                  "| cause | held-out gain | z | also? |", "|---|---|---|---|"]
        for t in d.secondary_tried:
            lines.append(f"| {t.cause} | {100 * t.heldout_gain:.3f} % | {_fmt(t.heldout.get('z'), 3)} | "
                         f"{'yes' if any(t is a for a in d.also) else 'no'} |")
    lib = d.library
    lines += ["", "## Evidence: library screen (pysindy)", "",
              f"{lib['method']}: the base-alone residual regressed on {lib['n_library']} candidate terms (each made "
              f"orthogonal to the base model's regressors). {lib['n_terms']} term(s) kept, explaining "
              f"{100 * lib['explained_total']:.2f} % of the residual sum of squares.", ""]
    if lib["terms"]:
        lines += ["| order | term | group | share explained |", "|---|---|---|---|"]
        for t in lib["terms"]:
            lines.append(f"| {t['order']} | `{t['name']}` | {t['group']} | {100 * t['explained']:.3f} % |")
        lines += ["", "Share by cause: " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in lib["groups"].items()), ""]
    lines += ["## Residuals of the base model", "",
              f"| record | role | f (Hz) | noise sd | rms whole | rms window | lag-1 autocorr. | Ljung-Box p ({LAGS} lags) |",
              "|---|---|---|---|---|---|---|---|"]
    for s in d.summaries:
        lines.append(f"| {s.file} | {s.role} | {_fmt(s.frequency_hz)} | {_fmt(s.noise_sd, 3)} | {_fmt(s.rms, 3)} | "
                     f"{_fmt(s.rms_window, 3)} | {s.lag1_autocorrelation:.3f} | {_fmt(s.ljung_box_p, 3)} |")
    lines += ["", "## e_m / e_rms per record (% of the measured peak-to-peak)", "",
              "Window: the record's scored window (the benchmark's metric); whole: every sample.", ""]
    header = "| record | role | before e_m | before e_rms | before e_rms whole |"
    sep = "|---|---|---|---|---|"
    if d.base_whole:
        header += " base refit e_rms | base refit e_rms whole |"
        sep += "---|---|"
    if d.after:
        header += " after e_m | after e_rms | after e_rms whole |"
        sep += "---|---|---|"
    lines += [header, sep]
    bw = {rr.file: rr.scores() for rr in d.base_whole}
    af = {rr.file: rr.scores() for rr in d.after}
    for rr in d.before:
        s = rr.scores()
        row = f"| {rr.file} | {rr.record.role} | {s['e_m']:.3f} | {s['e_rms']:.3f} | {s['e_rms_whole']:.3f} |"
        if d.base_whole:
            row += f" {bw[rr.file]['e_rms']:.3f} | {bw[rr.file]['e_rms_whole']:.3f} |"
        if d.after:
            row += f" {af[rr.file]['e_m']:.3f} | {af[rr.file]['e_rms']:.3f} | {af[rr.file]['e_rms_whole']:.3f} |"
        lines.append(row)
    lines += ["", "## Figures", ""]
    for key, file in figures.items():
        lines += [f"### {FIGURES[key][1]}", "", f"![{key}]({file})", ""]
    t = d.timings
    lines += ["## Run", "", "Wall time (s): " + ", ".join(f"{k} {v:.1f}" for k, v in t.items()) + ".", ""]
    if d.base_fit.notes:
        lines += ["Notes of the base model's fit:", ""] + [f"* {n}" for n in d.base_fit.notes] + [""]
    if d.extended_fit and d.extended_fit.notes:
        lines += ["Notes of the extended fit:", ""] + [f"* {n}" for n in d.extended_fit.notes] + [""]
    return "\n".join(lines)


def write_report(diag, out: str | Path, json_path: str | Path | None = None, note: str = "",
                 prefix: str = "diagnosis") -> dict:
    """Write ``prefix``.md, ``prefix``_*.png and the JSON (``json_path`` or ``prefix``.json in ``out``)."""
    out = ensure_dir(out)
    figures = {}
    for key, (fn, _) in FIGURES.items():
        file = f"{prefix}_{key}.png"
        (out / file).unlink(missing_ok=True)  # a figure this diagnosis does not draw is not an earlier run's
        fn(diag, out / file)
        if (out / file).exists():
            figures[key] = file
    data = diag.to_json()
    json_path = Path(json_path) if json_path else out / f"{prefix}.json"
    ensure_dir(json_path.parent)
    write_json(json_path, data)
    write_atomic(out / f"{prefix}.md", markdown(diag, figures, note) + "\n")
    return data
