"""posterior.md and its figures: parameter table, convergence, correlations and
what they say about identifiability, corner plot, posterior predictive bands."""

from __future__ import annotations

import logging
import math
from collections import Counter
from pathlib import Path

import numpy as np

from hysbench.benchmarks.plots import axis_label, pyplot, save_figure

from hysbench.identification.posterior import PosteriorRun, build_segments

STRONG_CORRELATION = 0.9
PRIOR_DOMINATED = 0.5  # posterior sd / prior sd above this: the data barely move the prior
N_CORNER = 6


# --- identifiability ---------------------------------------------------------------
def identifiability(run: PosteriorRun, table: dict) -> dict:
    """Which parameters the data determine: prior contraction, constant regressor
    columns over the fitted windows, strongly correlated pairs."""
    post = run.post
    prior_sd = {p["name"]: p["sd"] for p in post.priors.describe() if p["prior"] == "normal"}
    contraction = {n: table[n]["sd"] / s for n, s in prior_sd.items()}
    nl = np.array([[table[n]["mean"] for n in post.nonlinear_names]]).reshape(1, -1)
    segs = build_segments(post.model, [r for r in _records(run)], post.input_range, nl)
    constant = {}
    for j, name in enumerate(post.model_linear_names):
        values, spans = [], []
        for s in segs:
            col = post.model.windowed_regressors_batch(s.u, s.dt, nl, s.window, post.input_range)[0][:, j]
            values.append(float(col[0]))
            spans.append(float(np.ptp(col)))
        scale = max(1.0, max(abs(v) for v in values))
        if max(spans) <= 1e-9 * scale:
            constant[name] = {"values": dict(zip([s.file for s in segs], values))}
    names, corr = run.correlation()
    pairs = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if abs(corr[i, j]) >= STRONG_CORRELATION:
                pairs.append({"a": names[i], "b": names[j], "r": float(corr[i, j])})
    pairs.sort(key=lambda p: -abs(p["r"]))
    out = {
        "posterior_sd_over_prior_sd": contraction,
        "prior_dominated": sorted((n for n, c in contraction.items() if c > PRIOR_DOMINATED),
                                  key=lambda n: post.linear_names.index(n)),
        "constant_columns": constant,
        "strong_correlations": pairs,
    }
    thresholds = getattr(post.model, "thresholds", None)
    if callable(thresholds):
        lo, hi = post.input_range
        r = thresholds(np.array([lo, hi]), post.input_range)
        out["play_thresholds"] = [float(v) for v in r]
        out["input_span"] = float(hi - lo)
    return out


def _records(run: PosteriorRun):
    return run.post.problem.records


# --- figures -----------------------------------------------------------------------
def corner_names(names: list[str], corr: np.ndarray, k: int = N_CORNER) -> list[int]:
    """Indices of the k parameters most correlated with another one, strongest pairs first."""
    a = np.abs(corr - np.eye(len(names)))
    order = np.dstack(np.unravel_index(np.argsort(-a, axis=None), a.shape))[0]
    chosen: list[int] = []
    for i, j in order:
        if i >= j:
            continue
        for v in (int(i), int(j)):
            if v not in chosen and len(chosen) < k:
                chosen.append(v)
        if len(chosen) >= k:
            break
    return chosen


def corner_figure(run: PosteriorRun, path: Path) -> list[str]:
    names, corr = run.correlation()
    idx = corner_names(names, corr)
    S = run.samples()
    cols = [run.names.index(names[i]) for i in idx]
    pyplot()
    root = logging.getLogger()
    level = root.level
    root.setLevel(logging.ERROR)  # corner logs a warning for sparse tails of a contour
    import corner  # imported here: the command line loads this module for every command

    try:
        fig = corner.corner(S[:, cols], labels=[names[i] for i in idx], quantiles=[0.05, 0.5, 0.95],
                            show_titles=True, title_fmt=".3g", title_kwargs={"fontsize": 8},
                            label_kwargs={"fontsize": 9})
    finally:
        root.setLevel(level)
    fig.suptitle("most correlated parameters (5, 50, 95 % quantiles)", y=1.02)
    save_figure(fig, path)
    return [names[i] for i in idx]


def trace_figure(run: PosteriorRun, path: Path) -> None:
    plt = pyplot()
    post = run.post
    d = post.ndim
    fig, axes = plt.subplots(d + 1, 1, figsize=(8, 1.6 * (d + 1)), sharex=True)
    for k in range(d):
        axes[k].plot(run.chain[:, :, k], lw=0.4, alpha=0.5)
        axes[k].set_ylabel(post.coord_names[k], fontsize=8)
        axes[k].axvline(run.conv.burn, color="k", ls="--", lw=0.8)
    axes[d].plot(run.log_prob - np.max(run.log_prob), lw=0.4, alpha=0.5)
    axes[d].set_ylabel("log post.\n(- max)", fontsize=8)
    axes[d].set_ylim(-5 * post.ndim, 1)
    axes[d].axvline(run.conv.burn, color="k", ls="--", lw=0.8)
    axes[d].set_xlabel("step (dashed: end of burn-in)")
    axes[0].set_title(f"sampler traces: each walker's position per step ({run.chain.shape[1]} walkers)", fontsize=9)
    save_figure(fig, path)


def correlation_figure(run: PosteriorRun, path: Path) -> None:
    plt = pyplot()
    names, corr = run.correlation()
    fig, ax = plt.subplots(figsize=(0.34 * len(names) + 2, 0.34 * len(names) + 1.5))
    im = ax.imshow(corr, cmap="RdBu_r", vmin=-1, vmax=1)
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=7)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    fig.colorbar(im, ax=ax, shrink=0.7, label="posterior correlation")
    ax.set_xlabel("parameter")
    ax.set_ylabel("parameter")
    ax.set_title("posterior correlation of every pair of parameters", fontsize=10)
    save_figure(fig, path)


def predictive_figure(pred: list[dict], path: Path, unit: str = "", level: float = 0.9) -> None:
    plt = pyplot()
    n = len(pred)
    fig, axes = plt.subplots(n, 2, figsize=(11, 2.9 * n + 0.6), squeeze=False, layout="constrained")
    shared = Counter(p["frequency_hz"] for p in pred)
    for row, p in zip(axes, pred):
        t, y, med = p["_t"], p["_y"], p["_median"]
        (olo, ohi), (mlo, mhi) = p["_obs"], p["_model"]
        f = p["file"] if not p["frequency_hz"] else (
            f"{p['frequency_hz']:g} Hz, {p['file']}" if shared[p["frequency_hz"]] > 1 else f"{p['frequency_hz']:g} Hz")
        row[0].fill_between(t, olo, ohi, color="C0", alpha=0.3, lw=0, label=f"{level:.0%} predictive band")
        row[0].plot(t, med, color="C0", lw=0.8, label="median prediction")
        row[0].plot(t, y, color="k", lw=0.5, label="measured")
        row[0].set_title(f"{f}: {p['fraction_inside_observation_band']:.1%} of samples inside the band", fontsize=9)
        row[0].set_ylabel(axis_label("output", unit), fontsize=8)
        row[1].fill_between(t, olo - med, ohi - med, color="C0", alpha=0.3, lw=0,
                            label="predictive band about the median (with noise)")
        row[1].fill_between(t, mlo - med, mhi - med, color="C3", alpha=0.5, lw=0,
                            label="model's band only (without noise)")
        row[1].plot(t, y - med, color="k", lw=0.5, label="measured - median")
        row[1].set_title(f"{f}: residual about the median prediction", fontsize=9)
        row[1].set_ylabel(axis_label("output - median", unit), fontsize=8)
        for ax in row:  # the records differ in length: no shared time axis
            ax.set_xlabel("time in the scored window (s)", fontsize=8)
    (h0, l0), (h1, l1) = (ax.get_legend_handles_labels() for ax in axes[0])
    fig.legend(h0 + h1, l0 + l1, loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    save_figure(fig, path)


# --- markdown ------------------------------------------------------------------------
def _g(x, digits: int = 4) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.{digits}g}"


def render_markdown(summary: dict, ident: dict, files: dict, command: str, dataset_note: str = "") -> str:
    s = summary
    sm = s["sampler"]
    L = []
    if not s["converged"]:
        L += ["> **NOT CONVERGED.** " + " ".join(f"{p[0].upper()}{p[1:]}." for p in s["convergence_problems"])
              + " Treat every number below as provisional.", ""]
    if not s["ess_target_met"]:
        L += [f"> **ESS target not met**: the smallest effective sample size is {_g(s['min_ess'])} "
              f"(target {s['ess_target']:g}).", ""]
    L += [f"# Posterior of {s['model']} on {s['dataset']}", ""]
    if dataset_note:
        L += [dataset_note, ""]
    L += [
        f"Command: `{command}`", "",
        f"- noise model: **{s['noise_model']['name']}** — {s['noise_model']['description']}",
        f"- linear parameters: {s['linear_parameters']}; emcee walks over "
        f"{', '.join(sm['sampled_coordinates'])}",
        f"- data: {s['data']['rows']} fitted samples (scored windows of "
        + ", ".join(f"{r['file']}" + (" [simulated on a verified periodic proxy of "
                                      f"{r['simulated_samples']} of its {r['samples']} samples]"
                                      if r["shortened"] else "") for r in s["data"]["records"])
        + f"), every sample weighted alike; input range {s['data']['input_range'][0]:g}–"
          f"{s['data']['input_range'][1]:g}",
        f"- sampler: emcee, {sm['walkers']} walkers, {sm['moves']} moves, {sm['steps']} steps, burn-in "
        f"{sm['burn_in']} ({sm['kept_steps']} kept), seed {sm['seed']}"
        + (f", resumed from step {sm['resumed_from_step']}" if sm["resumed_from_step"] else ""),
        f"- convergence: largest autocorrelation time {_g(sm['tau_max'], 3)} steps, chain after burn-in "
        f"{_g(sm['chain_length_in_tau'], 3)} tau long (needs >= {sm['tau_factor_required']}); acceptance "
        f"{sm['acceptance_fraction']['mean']:.2f} (walkers {sm['acceptance_fraction']['min']:.2f}–"
        f"{sm['acceptance_fraction']['max']:.2f}); smallest ESS {_g(s['min_ess'])}; "
        f"**converged: {'yes' if s['converged'] else 'NO'}**",
        modes_line(s),
        bound_line(s),
        f"- wall time {s['wall_seconds']:.1f} s (sampling {s['sampling_seconds']:.1f} s"
        + (f"; over the runs that built the chain, this one {s['this_run_seconds']:.1f} s"
           if sm["resumed_from_step"] else "")
        + f"; {sm['log_posterior_evaluations']} log-posterior evaluations this run)",
        "",
        "## Priors", "",
        "| parameter | prior |", "|---|---|",
    ]
    for p in s["priors"]:
        if p["prior"] == "uniform":
            d = f"uniform on [{_g(p['low'])}, {_g(p['high'])}]"
        elif p["prior"] == "log-uniform":
            d = f"log-uniform on [{_g(p['low'])}, {_g(p['high'])}]"
        elif p["prior"] == "normal":
            d = f"normal, mean {_g(p['mean'])}, sd {_g(p['sd'])}"
        else:
            d = f"fixed at {_g(p['value'])}"
        note = f" ({p['note']})" if p.get("note") and p["name"] in ("sigma", "phi") else ""
        L.append(f"| {p['name']} | {d}{note} |")
    L += ["", "Linear parameters: integrated out of the likelihood analytically, then drawn from their "
          "Gaussian conditional for every kept state.", "",
          "## Parameters", "",
          "| parameter | mean | sd | 5 % | median | 95 % | ESS | tau | sd / prior sd |", "|---|---|---|---|---|---|---|---|---|"]
    contraction = ident["posterior_sd_over_prior_sd"]
    for n, v in s["parameters"].items():
        c = contraction.get(n)
        L.append(f"| {n} | {_g(v['mean'])} | {_g(v['sd'], 3)} | {_g(v['q05'])} | {_g(v['q50'])} | {_g(v['q95'])} | "
                 f"{_g(v['ess'], 4) if v['ess'] is None else round(v['ess'])} | {_g(v['tau'], 3)} | "
                 f"{_g(c, 2) if c is not None else ''} |")
    L += ["", "## Identifiability", ""]
    L += identifiability_text(s, ident)
    names, M = s["correlation"]["names"], s["correlation"]["matrix"]
    if files:
        L += ["", f"![correlation matrix]({files['correlation']})", "",
              f"Most correlated parameters (corner plot, {files['corner_names']}):", "",
              f"![corner plot]({files['corner']})"]
    L += ["", "<details><summary>Correlation matrix (posterior)</summary>", "",
          "| | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for n, row in zip(names, M):
        L.append(f"| **{n}** | " + " | ".join(f"{v:.2f}" for v in row) + " |")
    L += ["", "</details>", ""]
    L += predictive_text(s, files)
    if files:
        L += [f"Chains: ![traces]({files['trace']})", ""]
    return "\n".join(L).rstrip() + "\n"


def bound_line(s: dict) -> str:
    """One bullet: nonlinear parameters whose posterior the prior's bounds cut off."""
    at = s.get("at_prior_bound") or {}
    if not at:
        return "- prior bounds: no nonlinear parameter has 5 % or more of its kept states at a bound"
    return ("- **at a prior bound** (the prior cuts the posterior off; that end of the interval is the bound's, "
            "not the data's): " + "; ".join(f"{n}: {b['share']:.0%} of the kept states within 1 % of the range "
                                            f"from the {b['bound']} bound {_g(b['value'])}" for n, b in at.items()))


def modes_line(s: dict) -> str:
    """One bullet: the separated posterior modes the walkers started in and the share of kept states in each."""
    modes = s.get("modes") or []
    if len(modes) < 2:
        return "- modes: one (the mode search from the six best start candidates found no other separated mode)"
    names = [n for n in modes[0]["mode"] if n not in ("log_sigma", "phi")]
    parts = [", ".join(f"{n} {_g(m['mode'][n], 3)}" for n in names)
             + f" (log posterior {m['log_posterior'] - modes[0]['log_posterior']:+.1f}, {m['walkers']} walkers at the "
               f"start, **{m['share_of_kept_states']:.0%} of the kept states**)" for m in modes]
    return (f"- **modes: {len(modes)} separated** (a valley between each pair); the walkers started in every one and "
            f"mode jumps carried them between: " + "; ".join(parts)
            + "; medians and intervals span every mode, and each mode's predictive draws are scaled by its own scale")


def _pct(x) -> str:
    return "-" if x is None else f"{x:.1%}"


def predictive_text(s: dict, files: dict) -> list[str]:
    """The predictive section: what the bands are, how they were calibrated, coverage per record."""
    L = ["## Posterior predictive bands and their coverage", ""]
    d, cal = s.get("discrepancy", {}), s.get("predictive_calibration") or {}
    if d.get("kind") == "relaxation":
        L.append("Model discrepancy: the model's output plus sum_k c_k (L_k u - u), first-order relaxations of the "
                 "input at tau = " + ", ".join(f"{t:.3g}" for t in d["relaxation_times_s"])
                 + " s, integrated out with the linear parameters (coefficients "
                 + ", ".join(d["coefficients"]) + " in the table above).")
    else:
        L.append("Model discrepancy: none (the model's output alone).")
    L += [""] + calibration_text(cal)
    per_mode = s.get("predictive_calibration_per_mode") or []
    if len(per_mode) > 1:
        L += ["The posterior has separated modes (see the top). Each mode is calibrated as above at its own median "
              "state, and each predictive draw's deviation is taken from its own mode's per-sample median and "
              "multiplied by its mode's scale; the table's scale is the main mode's. Per mode:", ""]
        for k, c in enumerate(per_mode):
            if c is None:
                L.append(f"- mode {k + 1}: holds no kept state, not calibrated")
            else:
                L.append(f"- mode {k + 1}: " + (f"one scale {c['constant_scale']:.3g}" if c["kind"] == "constant" else
                                                _pooled_summary(c)))
        L.append("")
    pv = s.get("predictive", {})
    if not pv.get("validation"):
        return L + ["The dataset has no validation records: no predictive bands.", ""]
    L += ["Coverage = share of the measured samples inside the band; width = mean band width "
          "(output units). A calibrated predictive covers about 50 % and 90 %; the target for held-out "
          "(validation) records is 80–97 % for the 90 % band. \"scale 1\": the same draws without the "
          "held-out scale. With separated modes the scale column lists each mode's. \"scale x for 80 / 90 / 97 %\": "
          "the factor on the used scale at which this record's 90 % band would cover 80 / 90 / 97 % of its samples "
          "(1: the scale was what this record needed). The 90 % holds on average over records, not record by record: "
          "a record's misfit is one smooth curve, so its coverage scatters widely about 90 % (docs/posterior.md, \"One "
          "record's coverage\").", "",
          "| record | f (Hz) | role | scale | 50 % coverage | 90 % coverage | 90 % width | 50 % width "
          "| 90 % coverage, scale 1 | 90 % width, scale 1 | scale x for 80 / 90 / 97 % | model-only 90 % coverage "
          "| rms error of median | draws (non-finite) |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for role in ("validation", "identification"):
        for p in pv.get(role, []):
            f = f"{p['frequency_hz']:g}" if p["frequency_hz"] else "-"
            c, u = p.get("coverage"), p.get("unscaled")
            if c is None:
                L.append(f"| {p['file']} | {f} | {role} | | no finite draw | | | | | | | | | 0 ({p['nonfinite_draws']}) |")
                continue
            scale = "/".join(f"{v:.3g}" for v in p.get("predictive_scale_per_mode") or [p.get("predictive_scale", 1.0)])
            L.append(f"| {p['file']} | {f} | {role} | {scale} | {_pct(c['50'])} | "
                     f"**{_pct(c['90'])}** | {_g(c['width_90'], 3)} | "
                     f"{_g(c['width_50'], 3)} | {_pct(u['90'])} | {_g(u['width_90'], 3)} | "
                     f"{_multipliers(p.get('multiplier_for_coverage'))} | {_pct(p['fraction_inside_model_band'])} | {_g(p['rms_error_of_median'], 3)} | "
                     f"{p['draws']} ({p['nonfinite_draws']}) |")
    outside = [p["file"] for p in pv.get("validation", []) if p.get("inside_fitted_range") is False]
    if outside:
        L += ["", f"**Outside the fitted frequency range: {', '.join(outside)}.** These bands are extrapolated and "
              "not calibrated: on development data fitted on 0.05-0.4 Hz and scored at 0.02, 0.8 and 1 Hz, such "
              "bands covered 72 % (planted relaxation) and 63 % (virtual DEA) of the samples on average, some "
              "none (docs/posterior.md, \"Outside the fitted frequency range\")."]
    nf = s.get("nonfinite_model_outputs", {})
    L += ["", f"Non-finite model outputs: {nf.get('log_posterior_evaluations', 0)} of "
          f"{nf.get('of_evaluations', 0)} log-posterior evaluations (rejected and counted); "
          f"{nf.get('singular_linear_precision', 0)} with a singular linear precision.", ""]
    if files:
        L += [f"![posterior predictive bands on the validation records]({files['predictive']})", ""]
    return L


def _multipliers(need: dict | None) -> str:
    if not need:
        return "-"
    return " / ".join(">100" if need[k] is None else f"{need[k]:.3g}" for k in ("80", "90", "97"))


def _own_scales(cal: dict) -> str:
    """Each fitted record's own in-sample scale, as "c at f Hz, ..."."""
    return ", ".join(f"{p['scale']:.3g} at {p['frequency_hz']:g} Hz" for p in cal["in_sample"] if p["frequency_hz"])


def _pooled_summary(c: dict) -> str:
    pooled, beyond = c["pooled_in_sample_scale"], c.get("beyond_range_scale")
    beyond = "-" if beyond is None else f"{beyond:.3g}"
    return f"pooled in-sample scale {pooled:.3g} (records' own: {_own_scales(c)}); beyond the fitted range {beyond}"


def calibration_text(cal: dict) -> list[str]:
    """How the predictive scale was set: the pooled in-sample scale, the end records held out, every fold."""
    if cal.get("kind") == "constant" or not cal:
        c = cal.get("constant_scale", 1.0) if cal else 1.0
        L = [f"Predictive scale: each draw (model output plus its noise path) has its deviation from the "
             f"per-sample median multiplied by {c:.3g} for every record ({cal.get('note', 'not calibrated')}).", ""]
    else:
        out = cal.get("outside_range_scale")
        held = ("the scale that covers the end records (lowest and highest frequency), each held out and the "
                "linear parameters refitted without it, at 90 % on average")
        if out is None:
            beyond = "the pooled scale (no end record could be refitted)"
        elif out > cal["pooled_in_sample_scale"]:
            beyond = f"{out:.3g}, {held}"
        else:
            beyond = f"the pooled scale ({held} is smaller: {out:.3g})"
        L = ["Predictive scale: each draw (model output plus its noise path) has its deviation from the "
             f"per-sample median multiplied by c = {cal['pooled_in_sample_scale']:.3g} for a record inside the fitted "
             "frequencies' range: the one scale that covers the fitted records' own residuals at 90 % on average, "
             f"every record weighted alike (each record's own: {_own_scales(cal)}). Beyond that range: {beyond}. The interior "
             "records held out are reported, not used.", ""]
    folds = cal.get("folds") or []
    if folds:
        key = [k for k in folds[0] if k.endswith("_scaled")][0]
        L += ["| held out | f (Hz) | used | rms error (refit without it) | 90 % coverage, scale 1 | scale | "
              "90 % coverage with it |", "|---|---|---|---|---|---|---|"]
        for f in folds:
            fr = f"{f['frequency_hz']:g}" if f["frequency_hz"] else "-"
            used = "yes (end record)" if f["used"] and not f["interior"] else ("yes" if f["used"] else "no (interior)")
            L.append(f"| {f['held_out']} | {fr} | {used} | {_g(f['rms_error'], 3)} | "
                     f"{_pct(f[key.replace('_scaled', '_unscaled')])} | {f['scale']:.3g} | {_pct(f[key])} |")
        L.append("")
    return L


def identifiability_text(s: dict, ident: dict) -> list[str]:
    L = []
    const = ident["constant_columns"]
    if const:
        for n, c in const.items():
            vals = sorted(set(round(v, 6) for v in c["values"].values()))
            L.append(f"- **{n}**: its regressor is constant over every fitted window "
                     f"({', '.join(f'{v:g}' for v in vals)}), so it acts as an output offset.")
        thr = ident.get("play_thresholds")
        if thr is not None:
            span = ident["input_span"]
            wide = [i + 1 for i, r in enumerate(thr) if r >= span]
            if wide:
                L.append(f"  Play thresholds r_i = (i-1)/N ||u||_inf: {', '.join(f'r{i} = {thr[i - 1]:.4g}' for i in wide)} "
                         f"exceed the input span {span:.4g}: after the input's first maximum such an operator never "
                         "moves again (it would need the input to fall by more than r_i), so its output is the "
                         "constant max(h_l) - r_i over every later sample.")
    dom = ident["prior_dominated"]
    if dom:
        L.append(f"- **Not determined by the data** (posterior sd > {PRIOR_DOMINATED:g} x prior sd): "
                 + ", ".join(f"{n} ({ident['posterior_sd_over_prior_sd'][n]:.2f})" for n in dom)
                 + ". Their posteriors are essentially the prior; any single value quoted for them (for MRPIM, "
                 "Table 2's large opposite-signed a12, a13) is one point on a ridge the data cannot resolve.")
    else:
        L.append("- Every linear parameter is determined by the data (posterior sd <= "
                 f"{PRIOR_DOMINATED:g} x prior sd).")
    pairs = ident["strong_correlations"]
    if pairs:
        L.append(f"- Strongly correlated pairs (|r| >= {STRONG_CORRELATION}): "
                 + ", ".join(f"{p['a']}–{p['b']} ({p['r']:+.3f})" for p in pairs[:12])
                 + (f" and {len(pairs) - 12} more" if len(pairs) > 12 else "") + ".")
    return L
