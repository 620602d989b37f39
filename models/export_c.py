"""C code for a fitted P-I-family model and its inverse (``hysbench export``).

``export_c(fitted, prefix, ...)`` returns the text of PREFIX.h and PREFIX.c: plain C99, no
allocation, only <math.h> and <limits.h>:

    typedef struct {...} PREFIX_state;
    void   PREFIX_init(PREFIX_state *s);                    /* the state before the first sample */
    double PREFIX_step(PREFIX_state *s, double u);          /* output at this sample */
    double PREFIX_inverse_step(PREFIX_state *s, double y_ref);  /* input for this desired output */

One state serves the forward model or the inverse (use one or the other on a state). The
per-sample update is ``kernels.pi_sample`` written out in C with the same operations in the
same order (so it agrees with Python to rounding; the tests require 1e-9 relative), and the
inverse is ``root_search``'s walk-and-refine search at one sample, as ``inverse.invert_sample``
runs it; ``PREFIX_state.clipped`` / ``n_clipped`` report the samples whose reference was out of
reach. ``inverse`` picks the inverse written (models/inverse.py): "exact" (the root search on
``sample``) or "reference-driven" (the same search on ``guided_sample``, ``inverse.guided_output``
in C, with the guide's follower of ``inverse.guide_step``); "auto" as ``invert``. The header names
it. Parameters, thresholds and the sample time are constants; the sample time is the model
file's: the generated code is valid only at that rate.

Exports: classical-pi, mrpim, rate-dependent-pi and the mrpim extensions with a step structure
(+relaxation, +creep, +interference). Others raise ``ExportError`` naming why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import HysbenchError
from .inverse import DEFAULT_GUIDE_TIME, InverseArguments, StepInvertible, check_guide_time, guide_rate
from .model_file import FittedModel
from .root_search import NEWTON_ITERATIONS


class ExportError(HysbenchError):
    """A model that cannot be exported as C (yet), or bad export options."""


def _num(x: float) -> str:
    """A double literal that reads back as exactly x (the shortest round-trip repr)."""
    x = float(x)
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "(-HUGE_VAL)"
    if math.isnan(x):
        raise ExportError("a constant of the model is NaN")
    r = repr(x)
    return r if ("e" in r or "." in r) else r + ".0"


def _array(name: str, values, ctype: str = "double") -> str:
    values = list(values)
    if not values:
        values = [0]  # C99 has no empty arrays; the loops over it run zero times
    body = ", ".join(_num(v) if ctype == "double" else str(int(v)) for v in values)
    return f"static const {ctype} {name}[{len(values)}] = {{{body}}};"


INVERSE_TEXT = {
    "exact": " (y(u(k); u(k-1), u(k-2)) = y_ref(k) solved each sample; gives back a reachable input exactly "
             "where its error recursion is stable)",
    "reference-driven": " (the rate and relaxation terms driven by the reference mapped to the input, "
                        "U_START + (y_ref(k) - y_ref(0)) * INV_GAIN, through a second-order follower (GUIDE_C per "
                        "sample) at most MAX_STEP per sample: no "
                        "recursion through the input's differences; approximate, see hysbench docs/deploying.md)",
}

# hysbench.models.inverse.guided_output in C (same operations, same order)
GUIDED_SAMPLE = """
/* The reference-driven model (hysbench.models.inverse.guided_output): the rates are the guide's
   (gd now, s->g1, s->g2 before), the filters (s->xf) follow the guide and add their lag to u^p;
   dy/du has no rate or lag term. */
static double guided_sample(PREFIX_state *s, double u, double gd, int commit, double *slope)
{
    const double k = s->k;
    double a = 0.0, d2 = 0.0, acc = 0.0, dy = 0.0, p = 0.0, dp = 0.0, y;
    int i, j;
    (void)k;
    if (!s->first) {
        a = fabs(gd - s->g1) * INV_DT;
        d2 = (gd - 2.0 * s->g1 + s->g2) * (INV_DT * INV_DT);
    }
    for (i = 0; i < N_PLAYS; i++) {
        const double lower = u - G_LO * a - R_LO[i];
        const double upper = u + G_HI * a + R_HI[i];
        double v = upper < s->w[i] ? upper : s->w[i];
        v = v > lower ? v : lower;
        if (commit) s->w[i] = v;
        acc += WEIGHTS[i] * v;
        if (slope && (v == lower || v == upper)) dy += WEIGHTS[i];
    }
    for (j = N_POLY - 1; j >= 0; j--) {
        const double t = p + POLY[j];
        dp = dp * u + t;
        p = t * u;
    }
    y = acc + p + Q * d2 + BASE_EXPR;
    dy += dp;
    for (j = 0; j < N_FILTERS; j++) {
        double x = 0.0;
        if (!s->first) {
            x = FA[j] * s->xf[j] + FB0[j] * ipow(s->g1, FPOW[j]) + FB1[j] * ipow(gd, FPOW[j]);
            y += FW[j] * (x - ipow(gd, FPOW[j]) + ipow(u, FPOW[j]));
            dy += FW[j] * FPOW[j] * ipow(u, FPOW[j] - 1);
        }
        if (commit) s->xf[j] = x;
    }
    if (slope) *slope = dy;
    return y;
}
"""

INVERSE_EXACT = """double PREFIX_inverse_step(PREFIX_state *s, double y_ref)
{
    double x;
    if (refused(s, y_ref)) return s->u1;
    x = search(s, y_ref, 0.0);
    advance(s, x);
    return x;
}
"""

# as hysbench.models.pi_stepper.PIInverseStepper.step / pi_guided_inverse_step
INVERSE_GUIDED = """double PREFIX_inverse_step(PREFIX_state *s, double y_ref)
{
    double mapped, gd, x, dg;
    if (refused(s, y_ref)) return s->u1;
    if (s->first) s->y_first = y_ref;
    mapped = U_START + (y_ref - s->y_first) * INV_GAIN;
    if (s->first) s->g1 = s->g2 = mapped;
    /* the guide follows the mapped reference (hysbench.models.inverse.guide_step), at most MAX_STEP per sample */
    if (GUIDE_C >= 1.0) dg = mapped - s->g1;
    else dg = (s->g1 - s->g2) * (1.0 - 2.0 * GUIDE_C) + GUIDE_C * GUIDE_C * (mapped - s->g1);
    dg = dg > -MAX_STEP ? dg : -MAX_STEP;
    gd = s->g1 + (dg < MAX_STEP ? dg : MAX_STEP);
    x = search(s, y_ref, gd);
    s->g2 = s->first ? gd : s->g1;
    s->g1 = gd;
    advance(s, x);
    return x;
}
"""


def check_exportable(fitted: FittedModel) -> None:
    model = fitted.model
    if not isinstance(model, StepInvertible):
        raise ExportError(f"model {model.name!r} cannot be exported as C (yet): only the P-I family "
                          "(classical-pi, mrpim, rate-dependent-pi, mrpim+relaxation/+creep/+interference) exports")
    reason = model.inverse_unavailable
    if reason:
        raise ExportError(f"model {model.name!r} cannot be exported as C (yet): {reason}")


def _base_code(fitted: FittedModel) -> tuple[str, float]:
    """(C expression of the offset at sample k, the constant offset)."""
    model, p = fitted.model, fitted.params
    if not getattr(model, "time_varying_base", False):
        s = model._structure(fitted.sample_time, p, fitted.input_range, 1)
        return "BASE", float(s.base[0])
    base_model = model.base_model
    s = base_model._structure(fitted.sample_time, {k: p[k] for k in model.base_names}, fitted.input_range, 1)
    expr = "BASE"
    if model.has("creep"):  # as ExtendedModel._creep_column: -expm1(-(k dt) / T_c)
        expr = f"({expr} + {_num(p['creep_size'])} * -expm1(-(0.0 + k * DT) / {_num(p['creep_time'])}))"
    if model.has("interference"):  # as ExtendedModel.interference_columns: phase = 2 pi f dt k
        w = 2.0 * math.pi * p["interference_frequency"] * fitted.sample_time
        expr = (f"({expr} + ({_num(p['interference_sin'])} * sin({_num(w)} * k) + "
                f"{_num(p['interference_cos'])} * cos({_num(w)} * k)))")
    return expr, float(s.base[0])


def export_c(fitted: FittedModel, prefix: str, model_file: str = "", model_sha256: str = "", version: str = "",
             input_limits=None, max_rate: float | None = None, u_start: float | None = None,
             reference_scale: float | None = None, n_grid: int = 32, inverse_note: str = "",
             inverse: str = "auto", guide_time: float = DEFAULT_GUIDE_TIME) -> tuple[str, str]:
    """(header, source) of the C export; the inverse options as ``PIInverseStepper``
    (``reference_scale`` default: ``fitted.reference_scale``, the data scale's |y| recorded in the
    model file, else 1, as ``fitted.inverse_stepper``;
    ``inverse``: "auto", "exact" or "reference-driven", ``inverse.INVERSES``; ``guide_time``: the
    reference-driven inverse's follower time constant, s);
    ``inverse_note``: the inverse's check (``check_inverse``), written into the header."""
    if not prefix.isidentifier() or not prefix.isascii():
        raise ExportError(f"prefix must be a C identifier (letters, digits, _), got {prefix!r}")
    check_exportable(fitted)
    model, dt = fitted.model, fitted.sample_time
    if reference_scale is None:
        reference_scale = fitted.reference_scale  # as fitted.inverse_stepper's default
    a = InverseArguments.check(model.name, [abs(float(reference_scale))], dt, fitted.input_range, input_limits,
                               n_grid, max_rate, u_start)
    s = model._structure(dt, fitted.params, fitted.input_range, 1)
    inverse, gain = model.resolve_inverse(inverse, s, fitted.input_range)
    guided = inverse != "exact"
    guide_c = guide_rate(dt, check_guide_time(model.name, guide_time))
    r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
    base_expr, base0 = _base_code(fitted)
    n, m, f = r_lo.size, poly.size, fa.size
    P = prefix
    guard = f"{P.upper()}_H"
    origin = (f"Generated by hysbench {version or '(unknown version)'} (hysbench export) from the model file\n"
              f" * {model_file or '(not from a file)'}\n * sha256 {model_sha256 or '-'}\n"
              f" * model {model.name}, sample time {dt!r} s, input range {list(fitted.input_range)!r}, "
              f"input unit {fitted.metadata.get('input_unit', '')!r}, output unit "
              f"{fitted.metadata.get('output_unit', '')!r}.")
    header = f"""/* {origin}
 *
 * Inverse: {inverse}{INVERSE_TEXT[inverse]}
 * Inverse check: {inverse_note or 'not run'}
 *
 * {P}_step(s, u): the model's output at this sample for input u (call once per sample, every
 * {dt!r} s, after {P}_init). {P}_inverse_step(s, y_ref): the input within [{a.lo!r}, {a.hi!r}]
 * that makes the {'reference-driven ' if guided else ''}model output y_ref at this sample; s->clipped says the reference was out of
 * reach (the nearest reachable output was taken), s->n_clipped counts those. Use one state
 * for either the forward model or the inverse; {P}_init(s) again resets it. The forward model
 * does not clip its input (outside the input range it extrapolates). A NaN or infinite input
 * (or reference) is refused: the state does not advance, s->refused is set and s->n_refused
 * counts it; {P}_step returns NaN, {P}_inverse_step the last input it returned ({P}_init: the
 * start input). (Compiled with -ffast-math, the compiler may drop that check.)
 */
#ifndef {guard}
#define {guard}

#define {P.upper()}_N_PLAYS {n}
#define {P.upper()}_N_FILTERS {max(f, 1)}
#define {P.upper()}_SAMPLE_TIME {_num(dt)}

typedef struct {{
    int first;        /* 1 before the first sample */
    double k;         /* samples since init (a double: exact to 2^53 samples, never overflows) */
    double u1, u2;    /* the input one and two samples ago */
    double y_first, g1, g2;  /* reference-driven inverse: the first reference, the guide one and two samples ago */
    double w[{P.upper()}_N_PLAYS];     /* play operators */
    double xf[{P.upper()}_N_FILTERS];  /* relaxation filters */
    int clipped;      /* inverse: the last reference was out of reach */
    long n_clipped;   /* inverse: references out of reach since init (stops at LONG_MAX) */
    int refused;      /* the last input or reference was NaN or infinite: the state did not advance */
    long n_refused;   /* inputs and references refused since init (stops at LONG_MAX) */
}} {P}_state;

void {P}_init({P}_state *s);
double {P}_step({P}_state *s, double u);
double {P}_inverse_step({P}_state *s, double y_ref);

#endif
"""
    source = f"""/* {origin} */
#include <limits.h>
#include <math.h>
#include "{P}.h"

#define N_PLAYS {n}
#define N_POLY {m}
#define N_FILTERS {f}
#define DT {_num(dt)}
#define INV_DT {_num(1.0 / dt)}
#define G_LO {_num(g_lo)}
#define G_HI {_num(g_hi)}
#define Q {_num(q)}
#define BASE {_num(base0)}
#define U_LO {_num(a.lo)}
#define U_HI {_num(a.hi)}
#define U_START {_num(a.u_start)}
#define MAX_STEP {_num(a.max_step)}
#define WALK_STEP {_num((a.hi - a.lo) / a.n_grid)}
#define TOL {_num(a.tol)}
#define NEWTON_ITERATIONS {NEWTON_ITERATIONS}
#define INV_GAIN {_num(1.0 / gain if guided else 0.0)}
#define GUIDE_C {_num(guide_c)}

{_array("R_LO", r_lo)}
{_array("R_HI", r_hi)}
{_array("WEIGHTS", weights)}
{_array("POLY", poly)}
{_array("FA", fa)}
{_array("FB0", fb0)}
{_array("FB1", fb1)}
{_array("FW", fw)}
{_array("FPOW", fpow, "int")}

static double ipow(double x, int p)
{{
    double r = 1.0;
    int i;
    for (i = 0; i < p; i++) r *= x;
    return r;
}}

/* One sample (hysbench.models.kernels.pi_sample): the output for input u from the state after
   the previous sample; the plays and filters move to this sample when commit is set; *slope
   receives dy/du when not NULL. */
static double sample({P}_state *s, double u, int commit, double *slope)
{{
    const double k = s->k;
    double a = 0.0, sg = 0.0, d2 = 0.0, acc = 0.0, dy = 0.0, p = 0.0, dp = 0.0, y;
    int i, j;
    (void)k;
    if (!s->first) {{
        const double du = u - s->u1;
        a = fabs(du) * INV_DT;
        sg = du > 0 ? 1.0 : (du < 0 ? -1.0 : 0.0);
        d2 = (u - 2.0 * s->u1 + s->u2) * (INV_DT * INV_DT);
    }}
    for (i = 0; i < N_PLAYS; i++) {{
        const double lower = u - G_LO * a - R_LO[i];
        const double upper = u + G_HI * a + R_HI[i];
        double v = upper < s->w[i] ? upper : s->w[i];
        v = v > lower ? v : lower;
        if (commit) s->w[i] = v;
        acc += WEIGHTS[i] * v;
        if (slope) {{
            if (v == lower) dy += WEIGHTS[i] * (1.0 - G_LO * sg * INV_DT);
            else if (v == upper) dy += WEIGHTS[i] * (1.0 + G_HI * sg * INV_DT);
        }}
    }}
    for (j = N_POLY - 1; j >= 0; j--) {{
        const double t = p + POLY[j];
        dp = dp * u + t;
        p = t * u;
    }}
    y = acc + p + Q * d2 + {base_expr};
    dy += dp;
    if (!s->first) dy += Q * INV_DT * INV_DT;
    for (j = 0; j < N_FILTERS; j++) {{
        double x = 0.0;
        if (!s->first) {{
            x = FA[j] * s->xf[j] + FB0[j] * ipow(s->u1, FPOW[j]) + FB1[j] * ipow(u, FPOW[j]);
            y += FW[j] * x;
            dy += FW[j] * FB1[j] * FPOW[j] * ipow(u, FPOW[j] - 1);
        }}
        if (commit) s->xf[j] = x;
    }}
    if (slope) *slope = dy;
    return y;
}}

{GUIDED_SAMPLE.replace("PREFIX", P).replace("BASE_EXPR", base_expr) if guided else ""}
static void advance({P}_state *s, double u)
{{
    s->u2 = s->first ? u : s->u1;
    s->u1 = u;
    s->first = 0;
    s->k += 1.0;
}}

/* A NaN or infinite sample is refused (the state does not advance), as the Python stepper refuses it. */
static int refused({P}_state *s, double x)
{{
    s->refused = !isfinite(x);
    if (s->refused && s->n_refused < LONG_MAX) s->n_refused++;
    return s->refused;
}}

void {P}_init({P}_state *s)
{{
    int i;
    s->first = 1;
    s->k = 0.0;
    s->u1 = s->u2 = U_START;
    s->y_first = 0.0;
    s->g1 = s->g2 = U_START;
    for (i = 0; i < {P.upper()}_N_PLAYS; i++) s->w[i] = 0.0;
    for (i = 0; i < {P.upper()}_N_FILTERS; i++) s->xf[i] = 0.0;
    s->clipped = 0;
    s->n_clipped = 0;
    s->refused = 0;
    s->n_refused = 0;
}}

double {P}_step({P}_state *s, double u)
{{
    double y;
    if (refused(s, u)) return NAN;
    y = sample(s, u, 1, 0);
    advance(s, u);
    return y;
}}

/* hysbench.models.root_search at one sample: walk out from the previous input, up and down
   alternately in steps of WALK_STEP, to the first sign change of g = y(u) - y_ref; refine it by
   safeguarded Newton steps (bisection when a step leaves the bracket or does not halve |g|);
   with no sign change take the visited input of smallest |g| and report the sample clipped.
   {'The output is the reference-driven model (guided_sample) at guide value gd.' if guided else ''} */
static double search({P}_state *s, double y_ref, double gd)
{{
    const double start = s->u1;
    const double lo = U_LO > start - MAX_STEP ? U_LO : start - MAX_STEP;
    const double hi = U_HI < start + MAX_STEP ? U_HI : start + MAX_STEP;
    double x = start, g, dy, best_u, best_g, up_x, up_g, dn_x, dn_g, px = 0.0, pg = 0.0;
    double xa, ga, xb, gb, g_prev, j = 1.0;
    int up_done, dn_done, side = 0, bracket = 0, clipped = 0, iter;
    (void)gd;
    g = {{EVAL}} - y_ref;
    best_u = x;
    best_g = fabs(g);
    if (fabs(g) <= TOL) goto done;
    up_x = dn_x = x;
    up_g = dn_g = g;
    up_done = x >= hi;
    dn_done = x <= lo;
    for (;;) {{  /* the walk */
        for (;;) {{
            if (up_done && dn_done) {{
                x = best_u;
                clipped = best_g > TOL;
                goto done;
            }}
            if (side >= 2) {{
                side = 0;
                j += 1.0;
            }}
            if ((side == 0 && up_done) || (side == 1 && dn_done)) {{
                side++;
                continue;
            }}
            break;
        }}
        if (side == 0) {{
            x = start + j * WALK_STEP;
            x = x < hi ? x : hi;
        }} else {{
            x = start - j * WALK_STEP;
            x = x > lo ? x : lo;
        }}
        g = {{EVAL}} - y_ref;
        if (fabs(g) < best_g) {{
            best_u = x;
            best_g = fabs(g);
        }}
        px = side == 0 ? up_x : dn_x;
        pg = side == 0 ? up_g : dn_g;
        if (fabs(g) <= TOL) goto done;
        if ((g > 0) != (pg > 0)) {{
            bracket = 1;
            break;
        }}
        if (side == 0) {{
            up_x = x;
            up_g = g;
            up_done = x >= hi;
        }} else {{
            dn_x = x;
            dn_g = g;
            dn_done = x <= lo;
        }}
        side++;
    }}
    if (bracket) {{  /* refine [xa, xb] from its better end */
        xa = px;
        ga = pg;
        xb = x;
        gb = g;
        g_prev = HUGE_VAL;
        x = fabs(pg) < fabs(g) ? px : x;
        for (iter = 0;;) {{
            double l, h, xn, x_next;
            g = {{EVAL}} - y_ref;
            if (fabs(g) <= TOL) break;
            if ((g > 0) == (ga > 0)) {{
                xa = x;
                ga = g;
            }} else {{
                xb = x;
                gb = g;
            }}
            l = xa < xb ? xa : xb;
            h = xa < xb ? xb : xa;
            if (h - l <= 1e-15 * (fabs(l) + fabs(h) + 1e-300)) {{
                x = fabs(ga) < fabs(gb) ? xa : xb;
                break;
            }}
            xn = dy != 0.0 ? x - g / dy : 0.5 * (l + h);
            x_next = (l < xn && xn < h && fabs(g) <= 0.5 * g_prev) ? xn : 0.5 * (l + h);
            g_prev = fabs(g);
            iter++;
            if (iter >= NEWTON_ITERATIONS) {{
                x = fabs(ga) < fabs(gb) ? xa : xb;
                break;
            }}
            x = x_next;
        }}
    }}
done:
    {'guided_sample(s, x, gd, 1, 0)' if guided else 'sample(s, x, 1, 0)'};
    s->clipped = clipped;
    if (clipped && s->n_clipped < LONG_MAX) s->n_clipped++;
    return x;
}}

{INVERSE_GUIDED.replace("PREFIX", P) if guided else INVERSE_EXACT.replace("PREFIX", P)}"""
    evaluation = "guided_sample(s, x, gd, 0, &dy)" if guided else "sample(s, x, 0, &dy)"
    return header, source.replace("{EVAL}", evaluation)


@dataclass(frozen=True)
class InverseCheck:
    """Whether an inverse gives back the input of a reachable trajectory (``check_inverse``).

    ``max_error``: the largest |u_inverse - u| over the samples the inverse did not clip, as a share
    of the input span; ``first_sample``: the first sample where it exceeded ``tolerance`` (-1: none);
    ``n_clipped``: samples clipped; ``stable``: max_error <= tolerance."""

    max_error: float
    first_sample: int
    n_clipped: int
    n_samples: int
    tolerance: float
    stable: bool
    max_root: float = float("nan")  # largest root modulus of the exact inverse's linearised error recursion (nan: not known)
    share_unstable: float = float("nan")  # share of the samples where that modulus exceeds 1
    inverse: str = "exact"  # the inverse checked ("exact" or "reference-driven", models/inverse.py)
    variation_ratio: float = float("nan")  # total variation of the inverse's input / the sine's (ringing raises it)

    def message(self, name: str) -> str:
        if self.inverse != "exact":
            roots = (f"; the exact inverse's error recursion has roots up to {self.max_root:.3g} per sample"
                     if self.max_root == self.max_root else "")
            head = (f"{name}: the reference-driven inverse (approximate by design: its rate and relaxation terms "
                    f"follow the reference) gives back a reachable trajectory's input to {self.max_error:.3g} of "
                    f"the input span ({self.n_samples} samples, {self.n_clipped} clipped); its input varies "
                    f"{self.variation_ratio:.3g} times as much as the sine's{roots}")
            return head + ("" if self.stable else f" (above {VARIATION_LIMIT:g}: it rings, so it is not safe as a "
                                                  "feedforward)")
        if self.stable:
            return (f"{name}: the inverse gives back a reachable trajectory's input to {self.max_error:.1e} of the "
                    f"input span ({self.n_samples} samples, {self.n_clipped} clipped)")
        return (f"{name}: the inverse does not give back a reachable trajectory's input: its error grows to "
                f"{self.max_error:.3g} of the input span (above {self.tolerance:g} from sample {self.first_sample} of "
                f"{self.n_samples}; {self.n_clipped} clipped): " + (
                    f"its linearised error recursion has roots of modulus up to {self.max_root:.3g} (above 1 on "
                    f"{100 * self.share_unstable:.0f} % of the samples), so it amplifies any error, rounding included "
                    "(classical-pi and mrpim identified with --method varpro --option stable_inverse=true have a "
                    "stable one)"
                    if self.max_root == self.max_root and self.max_root > 1.0 else
                    "the inverse recursion amplifies small errors or jumps to another root")
                + ", so it is not safe as a feedforward")


MAX_CHECK_SAMPLES = 2**22  # the longest sine check_inverse drives (a tiny max_rate asks for a slow one)
VARIATION_LIMIT = 2.0  # the reference-driven inverse's input may vary at most this many times as much as the sine's


def check_inverse(fitted: FittedModel, tolerance: float = 1e-6, periods: int = 2, **options) -> InverseCheck:
    """Drive the model with sines over its input range, invert the model's own output with the
    inverse's ``options`` (input_limits, max_rate, u_start, inverse, ...) and measure how far the
    inverse's input strays from the sine's where it did not clip. The sines sweep a decade of drive
    periods from the data scale's time (the shortest drive period the model was identified on) to ten
    times it (three log-spaced, ``periods`` periods each), no faster than ``max_rate`` allows. The
    exact inverse passes when it gives the input back to ``tolerance`` of the span (a stable one does,
    to rounding; an unstable recursion, e.g. through q u'' with rate-dependent envelopes, amplifies
    rounding errors until the input is lost). The reference-driven inverse is approximate by design
    (its error is reported); it passes when it does not ring: its input's total variation is at most
    ``VARIATION_LIMIT`` times the sine's. The worst sine counts."""
    lo, hi = fitted.input_range
    shortest = float((fitted.metadata.get("scale") or {}).get("time") or 1.0)
    if options.get("max_rate"):
        with np.errstate(over="ignore", divide="ignore"):
            shortest = max(shortest, float(np.pi * (hi - lo) / np.float64(options["max_rate"])))
    shortest = max(shortest, 2.0 * fitted.sample_time)  # two samples a period at least (an edited file's time)
    longest = periods * 10.0 * shortest / fitted.sample_time
    if not longest <= MAX_CHECK_SAMPLES:
        raise HysbenchError(f"{fitted.name}: checking the inverse would drive it with a sine of "
                            f"{longest:.3g} samples, above the limit of {MAX_CHECK_SAMPLES}: its period is set by "
                            "max_rate (input range / max_rate) and the sample time; give a larger max_rate")
    span = hi - lo if hi > lo else 1.0
    worst = None
    for period in shortest * np.logspace(0.0, 1.0, 3):
        t = np.arange(int(round(periods * period / fitted.sample_time))) * fitted.sample_time
        u = 0.5 * (lo + hi) - 0.5 * (hi - lo) * np.cos(2.0 * np.pi * t / period)
        inv = fitted.invert(fitted.simulate(u), **dict(options, u_start=options.get("u_start", float(u[0]))))
        err = np.where(inv.clipped, 0.0, np.abs(inv.u - u)) / span
        err = np.where(np.isfinite(err), err, np.inf)
        over = np.flatnonzero(err > tolerance)
        roots = (fitted.model.inverse_recursion_radius(u, fitted.sample_time, fitted.params, fitted.input_range)
                 if hasattr(fitted.model, "inverse_recursion_radius") else np.full(u.size, np.nan))
        variation = float(np.sum(np.abs(np.diff(inv.u))) / np.sum(np.abs(np.diff(u))))
        exact = inv.inverse == "exact"
        stable = float(np.max(err)) <= tolerance if exact else bool(variation <= VARIATION_LIMIT)
        check = InverseCheck(float(np.max(err)), int(over[0]) if over.size else -1, inv.n_clipped, u.size, tolerance,
                             stable, float(np.max(roots)), float(np.mean(roots > 1.0 + 1e-9)), inv.inverse,
                             variation if np.isfinite(variation) else float("inf"))
        key = (not check.stable, check.max_error)
        if worst is None or key > (not worst.stable, worst.max_error):
            worst = check
    return worst
