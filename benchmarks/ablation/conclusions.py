"""The verdicts in plain sentences (computed from the numbers)."""

from __future__ import annotations

from .criteria import _family, _smallest_adequate, compare

def conclusions(result: dict) -> list[str]:
    """Plain statements, computed from the numbers, of which parts earn their keep."""
    rows = result["variants"]
    ref = next(r for r in rows if r["reference"])
    if not ref.get("cv_folds"):
        return []
    out = []

    def fmt(r):
        return f"{r['cv_e_rms']:.3f} %"

    for factor, label, plural in (("q_term", "The q V'' term", False),
                                  ("envelopes", "The dynamic envelopes (gamma, lambda)", True)):
        fam = _family(rows, factor)
        other = next((r for r in fam if r[factor] != ref[factor]), None)
        if other is None:
            continue
        with_it, without = (ref, other) if ref[factor] else (other, ref)
        c = compare(with_it, without)
        extra = with_it["n_params"] - without["n_params"]
        detail = (f"cross-validated e_rms {fmt(with_it)} with, {fmt(without)} without "
                  f"(mean paired difference {c['mean']:+.3f} ± {c['se']:.3f} points; worse without at "
                  f"{c['n_worse']} of {c['n']} left-out frequencies)")
        if with_it["validation_e_rms"] is not None:
            detail += (f"; on the validation records {with_it['validation_e_rms']:.3f} % with, "
                       f"{without['validation_e_rms']:.3f} % without")
        verb = ("earn their" if plural else "earns its") + " keep"
        if c["verdict"] == "worse":
            out.append(f"{label} {verb} ({extra} parameter{'s' if extra != 1 else ''}): {detail}.")
        elif c["verdict"] == "better":
            out.append(f"{label} {'cost' if plural else 'costs'} accuracy on frequencies left out of the fit: "
                       f"{detail}.")
        else:
            out.append(f"{label} {'make' if plural else 'makes'} no difference that counts on left-out "
                       f"frequencies: {detail}.")
    for factor, label in (("order", "polynomial order"), ("n_operators", "number of play operators")):
        fam = _family(rows, factor)
        if len(fam) < 2:
            continue
        best, enough = _smallest_adequate(fam, factor)
        val = ref[factor]
        cmp_ref = compare(enough, ref) if enough is not ref else None
        name = factor_name(factor)
        if enough is best:
            levels = ", ".join(str(r[factor]) for r in sorted(fam, key=lambda r: r[factor]))
            s = (f"The {label}: {name} = {enough[factor]} is enough: it has the lowest cross-validated e_rms "
                 f"({fmt(enough)}) of {name} = {levels}")
        else:
            c = compare(best, enough)
            s = (f"The {label}: {name} = {enough[factor]} is enough: its cross-validated e_rms {fmt(enough)} is within "
                 f"the margin ({c['margin']:.3f} points; mean paired difference {c['mean']:+.3f}) of the best, "
                 f"{name} = {best[factor]} with {fmt(best)}"
                 + (", and smaller values are worse by more" if any(r[factor] < enough[factor] for r in fam) else ""))
        if enough[factor] == val:
            s += f"; the reference's {val} is exactly that."
        elif enough[factor] < val:
            verdict = {"worse": "and fits left-out frequencies worse", "better": "and fits them better",
                       "tie": "at no measurable gain"}[cmp_ref["verdict"]] if cmp_ref else ""
            s += (f"; the reference's {val} adds {ref['n_params'] - enough['n_params']} parameters "
                  f"{verdict} ({fmt(ref)}).")
        else:
            s += f"; the reference's {val} is too small ({fmt(ref)})."
        out.append(s)
    grid = _family(rows, "grid")
    if grid:
        best = min(grid, key=lambda r: r["cv_e_rms"])
        out.append(f"Over the grid order x q x envelopes (N = {ref['n_operators']}), the lowest cross-validated e_rms "
                   f"is {best['name']} ({fmt(best)}, {best['n_params']} parameters); the reference {ref['name']} has "
                   f"{fmt(ref)} ({ref['n_params']} parameters).")
    bound_hits = [r for r in rows if r.get("at_bounds")]
    if bound_hits:
        names = sorted({n for r in bound_hits for n in r["at_bounds"]})
        first = next((r for r in bound_hits if r["reference"]), bound_hits[0])
        among = " (the reference among them)" if any(r is ref for r in bound_hits) else ""
        out.append(f"In {len(bound_hits)} of {len(rows)} variants{among} the fitted {' and/or '.join(names)} {'sit' if len(names) > 1 else 'sits'} at a bound of "
                   f"the default search box (e.g. {first['name']}: "
                   + ", ".join(f"{n} in [{lo:.3g}, {hi:.3g}]" for n, (lo, hi) in first["at_bounds"].items())
                   + "): those variants' errors are for envelopes within these bounds and might be lower with "
                     "wider ones.")
    by_bic = min(rows, key=lambda r: r["bic"])
    by_bice = min(rows, key=lambda r: r["bic_effective"])
    best_cv = min((r for r in rows if r.get("cv_folds")), key=lambda r: r["cv_e_rms"])
    out.append(f"BIC on the identification records prefers {by_bic['name']} ({by_bic['n_params']} parameters); "
               f"with the sample count cut to the {ref['n_effective']:.0f} effectively independent residuals "
               f"(of {ref['n_scored']}) it prefers {by_bice['name']} ({by_bice['n_params']} parameters); "
               f"cross-validation prefers {best_cv['name']} ({best_cv['n_params']} parameters).")
    return out


def factor_name(factor: str) -> str:
    return {"order": "order", "n_operators": "N", "q_term": "q", "envelopes": "envelopes"}[factor]
