"""What the validation records -- untouched until the verdict is reached -- say about it.

* The named cause (``fit_extension``): its extension identified on the identification records' whole length
  against the base model refitted the same way (``refit_base_whole``); borne out (``borne_out``) if it lowers
  the validation records' residual by more than their noise explains; an interference, by the same amplitude.
* An ``unexplained`` verdict resting on a candidate's held-out evidence alone (``check_unexplained``): that
  candidate, by the same test; if not, the verdict is ``none``.
* The causes kept under "also" (``check_also``): each on top of what was kept before it, by the same test;
  reported, the verdict unchanged.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from hysbench.identification import Fit

from .candidates import Candidate
from .extensions import gain, identify_whole, registered_extension, residuals_of_fit
from .interference import amplitude_at, phase_fitted
from .residuals import RecordResidual
from .policy import Policy
from .selection import Verdict, step


def borne_out(v: dict, cause: str, interference_check: dict, policy: Policy) -> bool:
    """Whether an extension's validation gain ``v`` (``extensions.gain``) bears it out: it lowers the validation
    records' residual over whole records and on the windows, by more than their noise explains (z >= the
    policy's ``z_confirm``); an interference, by the same amplitude there (``interference_on_validation``)."""
    ok = bool(v["explained_whole"] > 0 and v["explained_window"] > 0)
    if cause == "interference":
        return ok and bool(interference_check.get("same_amplitude"))
    return ok and bool(v["z_whole"] >= policy.z_confirm)


def interference_on_validation(before: list[RecordResidual], c: Candidate,
                               policy: Policy) -> tuple[list[RecordResidual], dict]:
    """A sinusoid at ``c``'s frequency and amplitude on top of ``before`` (the base, or what is kept, refitted on
    whole records), its phase fitted per record: the residuals after it, and the validation records' own
    amplitude there against ``c``'s (the same within the policy's ``interference_amplitude_tolerance``)."""
    f = c.estimates["frequency_hz"]
    amplitude = c.estimates["amplitude"]
    after, amps = [], []
    for rr in before:
        t = rr.record.t - rr.record.t[0]
        sine = phase_fitted(rr.residual, t, f, amplitude)
        after.append(RecordResidual(rr.record, rr.prediction + sine))
        if rr.record.role == "validation":
            amps.append(amplitude_at(rr.residual, t, f))
    a_val = float(np.sqrt(np.mean(np.square(amps)))) if amps else float("nan")
    return after, {"frequency_hz": f, "identification_amplitude": amplitude, "validation_amplitude": a_val,
                   "same_amplitude": bool(abs(a_val / amplitude - 1.0) <= policy.interference_amplitude_tolerance)}


def fit_extension(diag, c: Candidate, say: Callable[[str], None]) -> tuple[Fit | None, list, dict]:
    """``c``'s extension identified on the identification records' whole length, every parameter free (an
    interference: its phase fitted per record on the base refitted there): the fit, the residuals of every
    record and the interference check."""
    if c.cause == "interference":
        after, check = interference_on_validation(diag.base_whole, c, diag.screen.policy)
        return None, after, check
    base = diag.screen.base
    ext = registered_extension(base.name, c.cause, c.hyperparameters, base.get_hyperparameters())
    say(f"identifying {ext.name} on the identification records' whole length")
    fit = identified_whole(diag, ext, c.params)
    return fit, residuals_of_fit(fit, diag.dataset), {}


def identified_whole(diag, model, start) -> Fit:
    """``model`` identified on the identification records' whole length (on the screen's rows) from ``start``,
    the parameters it adds to the base within the screen's search bounds."""
    screen = diag.screen
    bounds = {n: list(screen.bounds_of(model, n)) for n in model.nonlinear_names if n not in screen.base.param_names}
    return identify_whole(model, diag.dataset, start, diag.seed, [r.file for r in diag.dataset.identification],
                          bounds, {p.record.file: p.rows for p in screen.parts})


def refit_base_whole(diag, say: Callable[[str], None]) -> None:
    """The baseline an extension is measured against: the base model refitted on the identification records'
    whole length (on the screen's rows), from its fit on their windows."""
    say(f"refitting {diag.screen.base.name} on the identification records' whole length (the baseline)")
    diag.base_whole_fit = identified_whole(diag, diag.screen.base, diag.base_fit.params)
    diag.base_whole = residuals_of_fit(diag.base_whole_fit, diag.dataset)


def check_unexplained(diag, say: Callable[[str], None]) -> None:
    """An ``unexplained`` verdict resting on its best partial candidate alone: that candidate's extension must
    predict the validation records as a named cause must (``borne_out``); if it does not, the held-out evidence
    that made the residual look structured is not borne out on data that took no part, and the verdict is
    ``none`` (the candidate kept as the best partial one)."""
    v, p = diag.verdict, diag.verdict.partial
    if not diag.dataset.validation:
        diag.unexplained_check = {"cause": p.cause, "label": p.label, "checked": False,
                                  "note": "no validation record"}
        return
    say(f"checking on the validation records what {p.label} predicted of the unexplained residual")
    _, after, check = fit_extension(diag, p, say)
    g = gain(diag.base_whole, after, "validation")
    borne = borne_out(g, p.cause, check, diag.screen.policy)
    diag.unexplained_check = {"cause": p.cause, "label": p.label, "checked": True, "borne_out": borne,
                              **{k: g[k] for k in ("records", "explained_whole", "explained_window", "z_whole")},
                              **({"interference_check": check} if check else {})}
    diag.trace.append(step("unexplained-check", "unexplained" if borne else "none", partial=p.cause,
                           **{k: g[k] for k in ("explained_whole", "explained_window", "z_whole")}))
    if borne:
        return
    diag.verdict = Verdict("none", None, reason=(
        f"{v.reason}; but fitted on the identification records {p.label} does not predict the validation records "
        f"beyond their noise ({100 * g['explained_whole']:.1f} % of their residual removed, z = {g['z_whole']:.2f}, "
        f"needs {diag.screen.policy.z_confirm:.3g}): the structure it pointed to is not borne out on data that took "
        "no part, so "
        f"nothing is named"), not_identified=v.not_identified, partial=p)


def _with_lines(residuals: list[RecordResidual], lines: list[Candidate], policy: Policy) -> list[RecordResidual]:
    """Every kept interference on top: each a sinusoid at its frequency and amplitude, phase fitted per record."""
    for c in lines:
        residuals = interference_on_validation(residuals, c, policy)[0]
    return residuals


def check_also(diag, say: Callable[[str], None]) -> None:
    """Each cause kept under "also", on the validation records: what is kept with it against what was kept before
    it (the named extension first), every model identified on the identification records' whole length from the
    screen's fit; borne out as a named cause is (``borne_out``). An interference is a sinusoid on top of all that
    is kept, its phase fitted per record and its amplitude checked. A clip of what is kept, and what follows it,
    are not checked (its level was fitted on the screen's rows of the kept part only). Reported; the verdict
    is unchanged."""
    if not diag.also or not diag.after:
        return
    if not diag.dataset.validation:
        diag.also_check = [{"cause": c.cause, "label": c.label, "checked": False, "note": "no validation record"}
                           for c in diag.also]
        return
    lines = [diag.chosen] if diag.cause == "interference" else []  # a named line is on top of the base
    before, out, clipped = diag.after, [], False
    for c in diag.also:
        entry = {"cause": c.cause, "label": c.label}
        clipped = clipped or c.clips is not None
        if clipped:
            out.append({**entry, "checked": False, "note": "a clip of what is kept, or on top of one: not checked"})
            continue
        say(f"checking {c.label} on the validation records")
        check = {}
        if c.cause == "interference":
            after, check = interference_on_validation(before, c, diag.screen.policy)
            lines.append(c)
        else:
            part = residuals_of_fit(identified_whole(diag, c.model, c.params), diag.dataset)
            after = _with_lines(part, lines, diag.screen.policy)
        g = gain(before, after, "validation")
        out.append({**entry, "checked": True, "borne_out": borne_out(g, c.cause, check, diag.screen.policy),
                    **{k: g[k] for k in ("explained_whole", "explained_window", "z_whole")},
                    **({"interference_check": check} if check else {})})
        before = after
    diag.also_check = out
