"""What the validation records, untouched until the verdict, say of the named extension (rule ``validation``),
an ``unexplained`` verdict's partial candidate (``unexplained-check``) and each cause under "also" (``check_also``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

from hysbench.identification import Fit

from .candidates import Candidate
from .extensions import gain, identify_whole, registered_extension, residuals_of_fit
from .causes import CAUSES
from .policy import Policy
from .rule import NONE, UNEXPLAINED, Rule, Verdict, step


def borne_out(v: dict, cause: str, interference_check: dict, policy: Policy) -> bool:
    """Whether an extension's validation gain ``v`` (``extensions.gain``) bears it out."""
    ok = bool(v["explained_whole"] > 0 and v["explained_window"] > 0)
    if cause in CAUSES and CAUSES[cause].disturbance:
        return ok and bool(interference_check.get("same_amplitude"))
    return ok and bool(v["z_whole"] >= policy.z_confirm)


def validation_record(c: Candidate, g: dict, check: dict, policy: Policy) -> dict:
    """What a candidate's extension did on the validation records, as reported."""
    return {"cause": c.cause, "label": c.label, "checked": True, "borne_out": borne_out(g, c.cause, check, policy),
            **{k: g[k] for k in ("explained_whole", "explained_window", "z_whole")},
            **({"interference_check": check} if check else {})}


def fit_extension(diag, c: Candidate, say: Callable[[str], None]) -> tuple[Fit | None, list, dict]:
    """``c``'s extension identified on the identification records' whole length (a disturbance: fitted on top):
    the fit, the residuals of every record and the interference check."""
    if c.kind.disturbance:
        after, check = c.kind.on_validation(diag.base_whole, c, diag.screen.policy)
        return None, after, check
    base = diag.screen.base
    ext = registered_extension(base.name, c.cause, c.hyperparameters, base.get_hyperparameters())
    say(f"identifying {ext.name} on the identification records' whole length")
    fit = identified_whole(diag, ext, c.params)
    return fit, residuals_of_fit(fit, diag.dataset), {}


def identified_whole(diag, model, start) -> Fit:
    """``model`` identified on the identification records' whole length (the screen's rows) from ``start``, the
    parameters it adds to the base within the screen's search bounds."""
    screen = diag.screen
    bounds = {n: list(screen.bounds_of(model, n)) for n in model.nonlinear_names if n not in screen.base.param_names}
    return identify_whole(model, diag.dataset, start, diag.seed, [r.file for r in diag.dataset.identification],
                          bounds, {p.record.file: p.rows for p in screen.parts})


def refit_base_whole(diag, say: Callable[[str], None]) -> None:
    """The baseline of an extension: the base refitted on the identification records' whole length; once."""
    if diag.base_whole_fit is not None:
        return
    say(f"refitting {diag.screen.base.name} on the identification records' whole length (the baseline)")
    diag.base_whole_fit = identified_whole(diag, diag.screen.base, diag.base_fit.params)
    diag.base_whole = residuals_of_fit(diag.base_whole_fit, diag.dataset)


def gather_unexplained(ctx, v: Verdict) -> dict | None:
    """The validation check of an ``unexplained`` verdict's partial candidate, the residual not structured."""
    diag, p = ctx.diag, v.partial
    if not ctx.extend or v.cause != UNEXPLAINED or p is None or diag.structure["structured"]:
        return None
    refit_base_whole(diag, ctx.say)
    ctx.say(f"checking on the validation records what {p.label} predicted of the unexplained residual")
    _, after, check = fit_extension(diag, p, ctx.say)
    g = gain(diag.base_whole, after, "validation")
    diag.unexplained_check = {**validation_record(p, g, check, ctx.policy), "records": g["records"]}
    return diag.unexplained_check


def decide_unexplained(check: dict, v: Verdict, policy: Policy) -> tuple[Verdict, dict]:
    p = v.partial
    borne = borne_out(check, p.cause, check.get("interference_check", {}), policy)
    entry = step("unexplained-check", UNEXPLAINED if borne else NONE, partial=p.cause,
                 **{k: check[k] for k in ("explained_whole", "explained_window", "z_whole")})
    if borne:
        return v, entry
    return replace(v, cause=NONE, chosen=None, ambiguous_with=(), remainder=None, reason=(
        f"{v.reason}; but fitted on the identification records {p.label} does not predict the validation records "
        f"beyond their noise ({100 * check['explained_whole']:.1f} % of their residual removed, z = "
        f"{check['z_whole']:.2f}, needs {policy.z_confirm:.3g}): the structure it pointed to is not borne out on "
        "data that took no part, so nothing is named")), entry


UNEXPLAINED_CHECK = Rule("unexplained-check", (
    "An `unexplained` verdict that rests on a candidate's held-out evidence alone (the residual not "
    "structured) must have that candidate's extension confirmed as a named cause is (`validation`); otherwise "
    "the verdict is `none`."), decide_unexplained, gather_unexplained, timing="unexplained_check")


@dataclass(frozen=True)
class Validation:
    """The named extension's gain on the validation records (empty without one) and an interference's check."""

    gain: dict
    interference_check: dict


def gather_validation(ctx, v: Verdict) -> Validation | None:
    diag = ctx.diag
    if not ctx.extend or v.chosen is None:
        return None
    refit_base_whole(diag, ctx.say)
    diag.extended_fit, diag.after, diag.interference_check = fit_extension(diag, v.chosen, ctx.say)
    return Validation(diag.gain().get("validation") or {}, diag.interference_check)


def decide_validation(ev: Validation, v: Verdict, policy: Policy) -> tuple[Verdict, dict]:
    g = ev.gain
    confirmed = bool(g) and borne_out(g, v.cause, ev.interference_check, policy)
    return v, step("validation", "confirmed" if confirmed else "not confirmed", cause=v.cause,
                   **{k: g.get(k) for k in ("explained_whole", "explained_window", "z_whole")},
                   **({"same_amplitude": ev.interference_check.get("same_amplitude")}
                      if v.chosen.kind.disturbance else {}))


VALIDATION = Rule("validation", (
    "The named extension is identified on the identification records' whole length; it is *confirmed* if it "
    "lowers the validation records' residual (against the base refitted the same way) over whole records and "
    "on the scored windows, with z >= {z_confirm} (the normal quantile of 1 - {confirm_p}; z counts correlated "
    "noise). An interference is confirmed by its amplitude on the validation records, phase fitted per record, "
    "within {interference_amplitude_tolerance} of the identified one. Reported; the verdict is unchanged."),
    decide_validation, gather_validation, timing="extended_fit")


def check_also(diag, say: Callable[[str], None]) -> None:
    """Each cause under "also" on the validation records: what is kept with it against what was kept before it,
    borne out as a named cause is. A clip of what is kept, and what follows it, are not checked."""
    if not diag.also or not diag.after:
        return
    lines = [diag.chosen] if diag.chosen.kind.disturbance else []  # a named line is on top of the base
    before, out, clipped = diag.after, [], False
    for c in diag.also:
        clipped = clipped or c.clips is not None
        if clipped:
            out.append({"cause": c.cause, "label": c.label, "checked": False,
                        "note": "a clip of what is kept, or on top of one: not checked"})
            continue
        say(f"checking {c.label} on the validation records")
        check = {}
        if c.kind.disturbance:
            after, check = c.kind.on_validation(before, c, diag.screen.policy)
            lines.append(c)
        else:
            after = residuals_of_fit(identified_whole(diag, c.model, c.params), diag.dataset)
            for line in lines:  # every kept interference on top, its phase fitted per record
                after = line.kind.on_validation(after, line, diag.screen.policy)[0]
        out.append(validation_record(c, gain(before, after, "validation"), check, diag.screen.policy))
        before = after
    diag.also_check = out
