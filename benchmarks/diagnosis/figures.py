"""The figures of a diagnosis report (``FIGURES``: key -> (drawing function, caption)), each a PNG file; large
records are thinned for plotting, keeping each bin's extremes (``extremes_kept``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hysbench.benchmarks.plots import (axis_label, figure_legend, legend_outside, plain_log_labels, pyplot, save_figure,
                                      series_style, ticks_at)

from .residuals import LAGS, autocorrelation, coherent_spectrum, periodogram, phase_of

MAX_PLOT_POINTS = 4_000  # per record and curve: a figure is about 1,000 pixels wide


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


def _label(rec, diag) -> str:
    """The record's frequency and role; its file too when another record has the same frequency."""
    shared = rec.frequency_hz and sum(rr.record.frequency_hz == rec.frequency_hz for rr in diag.before) > 1
    return f"{rec.label}{f', {rec.file}' if shared else ''} ({'id' if rec.role == 'identification' else 'val'})"


def figure_residual_time(diag, path: Path) -> None:
    recs = diag.before
    fig, axes = pyplot().subplots(len(recs), 1, figsize=(9, 1.6 * len(recs) + 0.6), squeeze=False,
                                  layout="constrained")
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
        ax.set_ylabel(_label(r, diag), fontsize=8)
        ax.tick_params(labelsize=7)
    figure_legend(fig, axes[0, 0])
    fig.suptitle(f"residual (measured - model, {diag.dataset.output_unit or 'output units'}) over whole "
                 "records; shaded: scored window", fontsize=9)
    fig.supxlabel("time (s)")  # every panel's: the records differ in length
    save_figure(fig, path)


def _per_record(diag, recs: list, path: Path, draw, xlabel: str, title: str) -> None:
    """One small panel per record, four to a row, each drawn by ``draw(ax, record_residual)``."""
    cols = min(4, len(recs))
    rows = int(math.ceil(len(recs) / cols))
    fig, axes = pyplot().subplots(rows, cols, figsize=(3.0 * cols, 2.4 * rows + 0.6), squeeze=False,
                                  layout="constrained")
    for ax, rr in zip(axes.flat, recs):
        draw(ax, rr)
        ax.set_title(_label(rr.record, diag), fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(recs):]:
        ax.axis("off")
    figure_legend(fig, axes[0, 0])
    fig.suptitle(f"{title}: residual of the base model {diag.model} (measured - model)", fontsize=9)
    fig.supxlabel(xlabel, fontsize=8)
    fig.supylabel(axis_label("residual", diag.dataset.output_unit), fontsize=8)
    save_figure(fig, path)


def figure_residual_input(diag, path: Path) -> None:
    def draw(ax, rr):
        r = rr.record
        k = _stride(r.t.size)
        ax.plot(r.u[::k], rr.residual[::k], ".", ms=1, color="0.6", label="whole record")
        w = slice(r.start, r.stop, _stride(r.stop - r.start))  # the scored window, thinned
        ax.plot(r.u[w], rr.residual[w], lw=0.7, color="C0", label="window")
    _per_record(diag, diag.before, path, draw, axis_label("input", diag.dataset.input_unit or "input units"),
                "against the input")


def figure_residual_phase(diag, path: Path) -> None:
    def draw(ax, rr):
        r = rr.record
        ph = phase_of(r)
        k = _stride(r.t.size)
        ax.plot(ph[::k], rr.residual[::k], ".", ms=1, color="0.7", label="all periods")
        w = slice(r.start, r.stop, _stride(r.stop - r.start))  # the scored window, thinned
        order = np.argsort(ph[w])
        ax.plot(ph[w][order], rr.residual[w][order], lw=0.8, color="C0", label="scored period")
    recs = [rr for rr in diag.before if rr.record.frequency_hz]
    if recs:
        _per_record(diag, recs, path, draw, "phase within the drive period (periods; 0: input minimum)",
                    "against the phase within the drive period")


def figure_spectrum(diag, path: Path) -> None:
    fig, axes = pyplot().subplots(1, 2, figsize=(11, 4), layout="constrained")
    ax = axes[0]
    for i, rr in enumerate(diag.before):
        f, a = periodogram(rr.residual, rr.record.dt)
        f, a = f[f > 0], a[f > 0]
        keep = extremes_kept(np.log(f), a, low=False)
        ax.loglog(f[keep], np.maximum(a[keep], 1e-12), lw=0.5, color=f"C{i % 10}", label=_label(rr.record, diag))
    ax.axhline(diag.noise_sd * 2.0 / math.sqrt(max(rr.record.t.size for rr in diag.before)), color="k", ls=":", lw=0.8,
               label="white noise of the\nestimated sd")
    unit = diag.dataset.output_unit
    ax.set(xlabel="frequency (Hz)", ylabel=axis_label("residual amplitude", unit))
    ax.set_title(f"residual spectrum per record (base model {diag.model})", fontsize=9)
    legend_outside(ax, fontsize=6)
    ax = axes[1]
    ids = [rr for rr in diag.before if rr.record.role == "identification"]
    duration = max(rr.record.t.size * rr.record.dt for rr in ids)
    dt = max(rr.record.dt for rr in ids)  # below every record's Nyquist frequency
    f, a = coherent_spectrum(ids, 1.0 / duration, 0.45 / dt, pad=2)
    keep = extremes_kept(np.log(f), a, low=False)
    ax.loglog(f[keep], np.maximum(a[keep], 1e-12), lw=0.5, color="C0")
    marker = diag.chosen.kind.spectrum_marker(diag.parameters) if diag.chosen is not None else None
    if marker is not None:
        ax.axvline(marker, color="C3", lw=0.8, ls="--", label=f"named {diag.cause}")
        ax.legend(fontsize=7)
    ax.set(xlabel="frequency (Hz)", ylabel=axis_label("pooled coherent amplitude", unit))
    ax.set_title("identification records pooled in their own time\n(a disturbance with a common phase adds up)",
                 fontsize=9)
    save_figure(fig, path)


def figure_error_vs_frequency(diag, path: Path) -> None:
    if not any(rr.record.frequency_hz for rr in diag.before):  # no nominal drive frequency: nothing to plot
        return
    fig, axes = pyplot().subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    series = ((f"{diag.model} (before)", diag.before, "0.3", "o"),
              (f"{diag.model} refit on whole records", diag.base_whole, "C0", "s"),
              (f"{diag.extended_model} (after)", diag.after, "C3", "^"))  # one without records draws nothing
    for ax, key, title in ((axes[0], "e_rms", "scored window"), (axes[1], "e_rms_whole", "whole record")):
        for name, recs, color, marker in series:
            pts = sorted((rr.record.frequency_hz, rr.scores()[key], rr.record.role) for rr in recs
                         if rr.record.frequency_hz)
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=color, lw=0.8, marker=marker, ms=5,
                    label=name)
            for fr, v, role in pts:
                ax.plot(fr, v, marker, color=color, mfc=color if role == "identification" else "white", ms=5)
        ax.set(xscale="log", yscale="log", xlabel="drive frequency (Hz)", ylabel="e_rms (% of measured peak-to-peak)")
        ticks_at(ax, [rr.record.frequency_hz for rr in diag.before if rr.record.frequency_hz])
        plain_log_labels(ax)
        ax.set_title(f"error against frequency, {title}\n(filled: identification, open: validation)", fontsize=9)
    figure_legend(fig, axes[0])
    save_figure(fig, path)


def figure_whiteness(diag, path: Path) -> None:
    fig, ax = pyplot().subplots(figsize=(7, 3.8), layout="constrained")
    lags = np.arange(1, LAGS + 1)
    for i, (rr, s) in enumerate(zip(diag.before, diag.summaries)):
        ax.plot(lags, autocorrelation(rr.residual, LAGS), ms=3, lw=0.7, **series_style(i),
                label=f"{_label(rr.record, diag)}: Ljung-Box p = {s.ljung_box_p:.2g}")
    n = min(rr.record.t.size for rr in diag.before)
    ax.axhspan(-1.96 / math.sqrt(n), 1.96 / math.sqrt(n), color="0.85", lw=0, label="95 % band of white noise")
    ax.axhline(0, color="k", lw=0.4)
    ax.set(xlabel="lag (samples)", ylabel="autocorrelation of the residual")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # lags are whole samples
    ax.set_title(f"whiteness of the base model's residual ({diag.model}, whole records)", fontsize=9)
    legend_outside(ax, fontsize=6)
    save_figure(fig, path)


def figure_candidates(diag, path: Path) -> None:
    cands = sorted(diag.candidates, key=lambda c: -c.heldout_gain)
    fig, axes = pyplot().subplots(1, 2, figsize=(10, 3.4), layout="constrained")
    names = [c.cause for c in cands]
    colors = ["C3" if diag.chosen is not None and c is diag.chosen else "0.5" for c in cands]
    axes[0].barh(names, [100 * max(c.heldout_gain, -1.0) for c in cands], color=colors)
    axes[0].axvline(100 * diag.policy.min_explained, color="k", ls=":", lw=0.8)
    axes[0].set_xlabel("held-out gain over the base model (%, leave one record out; floored at -100)")
    axes[0].invert_yaxis()
    axes[1].barh(names, [max(min(c.heldout.get("z", 0.0), 40.0), -10.0) for c in cands], color=colors)
    axes[1].axvline(diag.policy.z_pass, color="k", ls=":", lw=0.8)
    axes[1].set_xlabel("z (signed-rank test over blocks; clipped to -10..40)")
    axes[1].invert_yaxis()
    for ax in axes:
        ax.set_ylabel("candidate cause")
    fig.suptitle(f"candidate causes (red: named); dotted: the decision rule's least held-out gain "
                 f"({100 * diag.policy.min_explained:g} %) and least block-test z ({diag.policy.z_pass:g})", fontsize=9)
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
