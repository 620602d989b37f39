"""results/compensation.md, its figures and compensation.json."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hysbench.benchmarks.plots import legend_outside, pyplot, save_figure, series_style
from hysbench.data.files import ensure_dir, write_atomic, write_json

SINES_PREFIX = "sine-"


def _fmt(v, digits=3):
    return "n/a" if v is None else f"{v:.{digits}g}"


def controllers_of(result: dict) -> list[str]:
    first = next(iter(result["references"].values()))
    return list(first)


def sine_mean(result: dict, controller: str, metric: str = "e_rms") -> float | None:
    vals = [by[controller][metric] for name, by in result["references"].items() if name.startswith(SINES_PREFIX)]
    return None if not vals or any(v is None for v in vals) else float(np.mean(vals))


def ranked_models(result: dict) -> list[str]:
    """Models by the mean e_rms of their open-loop inverse over the sines (finite ones only)."""
    scored = [(sine_mean(result, m), m) for m in result["models"]]
    return [m for v, m in sorted((v, m) for v, m in scored if v is not None)]


def best_model(result: dict) -> str | None:
    """The model whose open-loop inverse has the lowest mean e_rms over the sines."""
    ranked = ranked_models(result)
    return ranked[0] if ranked else None


def pi_alone(result: dict) -> float | None:
    return sine_mean(result, "pi")


NUMBERS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven"}


def summary(result: dict) -> str:
    """The findings, written from the numbers (the same sentences whatever they say)."""
    lin = sine_mean(result, "linear")
    best = best_model(result)
    out = []
    n_sines = sum(name.startswith(SINES_PREFIX) for name in result["references"])
    if not n_sines:
        return "No sine reference was run: the inverses are not ranked on the sines."
    if best is None or lin is None:
        return "No model's inverse gave finite tracking on every sine."
    b = sine_mean(result, best)
    ratio = lin / b
    sines = f"{NUMBERS.get(n_sines, n_sines)} sine{'s' if n_sines > 1 else ''}"
    out.append(f"On the {sines} the best open-loop inverse is {best}'s: mean e_rms {b:.3g} % against "
               f"{lin:.3g} % for the static linear gain, "
               + (f"{ratio:.2g}x lower" if ratio >= 1 else f"{1 / ratio:.2g}x higher")
               + f"; the goal (>= 5x) is {'reached' if ratio >= 5 else 'not reached'}.")
    others = [f"{m} {_fmt(sine_mean(result, m))} % ({lin / sine_mean(result, m):.2g}x)" for m in ranked_models(result)
              if m != best]
    if others:
        out.append("The other inverses, in order (mean e_rms on the sines, ratio to the linear gain): "
                   + ", ".join(others) + ".")
    bad = [m for m in result["models"] if (sine_mean(result, m) or np.inf) > lin]
    if bad:
        out.append(f"Worse than no model at all: {', '.join(bad)}.")
    alone = pi_alone(result)
    feedback = [(m, sine_mean(result, f"pi+{m}")) for m in result["models"]]
    lower = [m for m, v in feedback if v is not None and alone is not None and v < 0.99 * alone]
    out.append(f"As feedforward, the inverse lowers the PI loop's mean e_rms on the sines (by more than 1 %) for: "
               f"{', '.join(lower) if lower else 'no model'}.")
    pi = sine_mean(result, "pi")
    pib = sine_mean(result, f"pi+{best}")
    if pi is not None and pib is not None:
        out.append(f"With feedback (PI at {result['pi']['bandwidth_hz']:g} Hz) the sines' mean e_rms is {pi:.3g} % "
                   f"alone and {pib:.3g} % with {best}'s inverse as feedforward "
                   f"({'lower' if pib < pi else 'not lower'}); with the linear gain as feedforward "
                   f"{_fmt(sine_mean(result, 'pi+linear'))} %.")
    per_ref = []
    for ref, by in result["references"].items():
        if ref.startswith(SINES_PREFIX):
            continue
        cells = {c: by[c]["e_rms"] for c in by if by[c]["e_rms"] is not None}
        if cells:
            c = min(cells, key=cells.get)
            per_ref.append(f"{ref}: best {c} ({cells[c]:.3g} %), linear {_fmt(cells.get('linear'))} %, "
                           f"{best} {_fmt(cells.get(best))} %")
    if per_ref:
        out.append("Other references: " + "; ".join(per_ref) + ".")
    return " ".join(out)


PLOT_SECONDS = 20.0  # a longer reference is shown by its last 20 s: 1,000 pixels do not resolve more


def figure(runs: dict, reference: str, controllers: list[str], path: Path, plt) -> Path:
    by = runs[reference]
    ref = next(iter(by.values())).reference
    s = ref.scored
    dt = 1e-3  # the plant's sample time
    s = slice(max(s.start, s.stop - int(round(PLOT_SECONDS / dt))), s.stop)
    t = np.arange(ref.y.size)[s] * dt
    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True)
    axes[0].plot(t, ref.y[s], "k", lw=2.0, label="reference")
    for i, c in enumerate(controllers):
        # the line styles keep in sight a controller that tracks as well as another drawn over it
        style = series_style(i, marker=False)
        axes[0].plot(t, by[c].y[s], lw=0.9, label=c, **style)
        axes[1].plot(t, by[c].y[s] - ref.y[s], lw=0.9, label=c, **style)
        axes[2].plot(t, by[c].u[s], lw=0.9, label=c, **style)
    axes[0].set_ylabel("output (mm)")
    axes[1].set_ylabel("tracking error (mm)")
    axes[2].set_ylabel("input to the plant (kV)")
    shown = "scored samples" if s.start == ref.scored.start else f"last {PLOT_SECONDS:g} s of the scored samples"
    axes[2].set_xlabel(f"time (s), {shown}")
    axes[0].set_title(f"{reference}: reference and achieved output (sensor reading)\n"
                      "a model's name: its inverse, open loop; pi: PI feedback; pi+name: PI with the inverse as "
                      "feedforward; linear: the linear gain's inverse", fontsize=9)
    legend_outside(axes[0], fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    return save_figure(fig, path)


def write_report(result: dict, runs: dict, out: str | Path, json_path: str | Path | None = None,
                 command: str = "") -> dict:
    out = ensure_dir(Path(out))
    json_path = Path(json_path) if json_path else out / "compensation.json"
    if str(json_path) != "-":  # the JSON's folder exists before any file is written
        ensure_dir(json_path.parent)
    plt = pyplot()
    best = best_model(result)
    top = ranked_models(result)[:2]
    top += [m for m in ("mrpim",) if m in result["models"] and m not in top]  # the seed paper's model, always
    shown = ["linear"] + top + ["pi"] + ([f"pi+{best}"] if best else [])
    figures = []
    for ref in ("sine-0.1Hz", "sine-1Hz", "random"):
        if ref in runs:
            path = out / f"compensation_{ref.replace('.', 'p')}.png"
            figure(runs, ref, shown, path, plt)
            figures.append((ref, path.name))
    result["best_model"] = best
    controllers = controllers_of(result)
    lines = ["# Inverse compensation: tracking on the virtual DEA", ""]
    if command:
        lines += [f"Generated by `{command}` in {result['seconds']:.0f} s (inverting every reference: "
                  f"{result['invert_seconds']:.1f} s).", ""]
    pi = result["pi"]
    lines += [
        f"Plant: the virtual DEA's physics (`dea_physics`, TRUTH) read by its laser sensor (noise sd "
        f"{result['plant']['sensor']['noise_sd_mm']:g} mm, 16-bit ADC), input clipped to "
        f"{result['plant']['u_limits_kV'][0]:g}-{result['plant']['u_limits_kV'][1]:g} kV, from rest. "
        f"Models identified on the dataset `{result['dataset']}` (`{result['dataset_hash'][:12]}`). "
        f"Linear gain: y = {result['linear']['gain']:.4g} u + {result['linear']['offset']:.4g}. "
        f"PI: bandwidth {pi['bandwidth_hz']:g} Hz (kp = {pi['kp']:.4g} kV/mm, ki = {pi['ki']:.4g} kV/(mm s), "
        f"zero at {1e3 * pi['zero_s']:g} ms), one sample of computation delay.", "",
        "Scores on the scored samples of each reference (after the creep transition), against the sensor "
        "reading: e_rms / e_m in % of the reference's peak-to-peak; `clipped` = scored samples where the "
        "command hit 0.5 or 2.5 kV or the inverse did not reach the reference.", "",
    ]
    lines += ["| model | identifier | inverse | validation e_rms mean (%) | inverse rate limit (kV/s) |",
              "|---|---|---|---:|---:|"]
    for name, m in result["models"].items():
        options = ", ".join(f"{k}={v}" for k, v in m.get("identify_options", {}).items())
        lines.append(f"| {name} | {m['method']}{f' ({options})' if options else ''} | {m['inverse']} | {_fmt(m['validation_e_rms_mean'])} | "
                     f"{'none' if m.get('max_rate') is None else _fmt(m['max_rate'])} |")
    if result["not_invertible"]:
        lines += ["", "Not inverted:", ""]
        lines += [f"* `{name}`: {why}" for name, why in result["not_invertible"].items()]
    lines += ["", "## Tracking e_rms (%) [clipped scored samples]", "",
              "| reference | " + " | ".join(controllers) + " |", "|---|" + "---:|" * len(controllers)]
    for ref, by in result["references"].items():
        lines.append(f"| {ref} | " + " | ".join(f"{_fmt(by[c]['e_rms'])} [{by[c]['clipped']}]" for c in controllers)
                     + " |")
    lines.append("| **sines, mean** | " + " | ".join(f"**{_fmt(sine_mean(result, c))}**" for c in controllers) + " |")
    lines += ["", "## Tracking e_m (%)", "", "| reference | " + " | ".join(controllers) + " |",
              "|---|" + "---:|" * len(controllers)]
    for ref, by in result["references"].items():
        lines.append(f"| {ref} | " + " | ".join(_fmt(by[c]["e_m"]) for c in controllers) + " |")
    lines += ["", "## Figures", ""]
    lines += [f"![{ref}]({name})" for ref, name in figures]
    lines += ["", "## What it shows", "", summary(result), ""]
    text = "\n".join(lines) + "\n"
    write_atomic(out / "compensation.md", text.encode())
    write_json(json_path, result)
    return result
