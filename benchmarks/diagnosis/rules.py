"""The decision rule: the ordered rules (``selection.SELECTION``, then ``AFTER_SELECTION``) and its text.

docs/diagnosis.md's section "The decision rule" is ``rule_text(Policy())`` (tests/test_causes.py keeps them equal).
"""

from __future__ import annotations

from .backward import DROP_REDUNDANT_PRIMARY
from .policy import Policy
from .rule import Rule, render
from .secondary import ALSO, COMPLETE_PARTIAL, COMPLETE_PROMISING
from .selection import SELECTION
from .slow_part import SLOW_PART_TWIN
from .validation import UNEXPLAINED_CHECK, VALIDATION

AFTER_SELECTION = (COMPLETE_PARTIAL, COMPLETE_PROMISING, UNEXPLAINED_CHECK, ALSO, DROP_REDUNDANT_PRIMARY,
                   SLOW_PART_TWIN, VALIDATION)

NOTATION = (
    "Notation: for a candidate c and a reference r (the base model unless said otherwise), the held-out gain is "
    "G = 1 - sum e_c^2 / sum e_r^2 over the out-of-fold residuals of every identification record; z is the "
    "one-sided Wilcoxon signed-rank test (as a normal quantile) of ln(SSE_r / SSE_c) over {n_blocks} contiguous "
    "blocks of each left-out record; \"folds improved\" counts the records whose squared error c lowers. \"c "
    "predicts as well as b\" means b is not better than c by z >= {z_same} on the same blocks. The share of "
    "misfit of c is the part of the base's held-out squared error beyond white noise (n times the noise "
    "variance) that c removes. A policy field is shown as `name` = value; a rule's id is the "
    "one its trace entries carry.")

HELD_OUT = (
    "Every identification record is left out once. A record whose input goes beyond the other records' range "
    "by more than {beyond_range} of the input span is scored only up to the sample where it first does (it "
    "takes part whole in every other fold's fit); if fewer than two records stay within the others' range, "
    "every record is scored whole.")

ADMISSION = (
    "A held-out score is *evidence* if G >= {min_explained}, more than half of the records are improved, and "
    "z >= {z_pass} or (G >= {strong_gain} and every record is improved).",
    "An interference whose frequency and amplitude, fitted on each fold's other records, agree across the folds "
    "(frequencies within the coarsest fold's spectral resolution, amplitudes within {line_amplitude}) is "
    "evidence with any G > 0 if it improves every record with z >= {z_pass}.",
    "A candidate *keeps its cause's meaning* unless: a resonance's damping ratio is at or above "
    "{damping_limit_share} x {max_damping}; two of a relaxation's time constants are closer than a factor "
    "{duplicate_tau_ratio}; an interference completes fewer than {interference_min_cycles} cycles in the "
    "shortest record, or sits at a drive harmonic with phases in the records within {locked_phase} rad of each "
    "other and does not turn from period to period by more than {locked_turn} rad and {locked_turn_z} standard "
    "errors (a misfit locked to the drive); a clip cuts fewer than {min_clipped_samples} samples of the "
    "prediction, or the output there follows the unclipped model with a slope of {max_clipped_slope} or more "
    "either way; a delay is shorter than one sample; creep's time scale is at most {creep_limit_margin} x its "
    "least value ({creep_periods} longest drive periods, at least the shortest record).",
    "A candidate *passes* if its score is evidence, it keeps its meaning, and none of its own nonlinear "
    "parameters is within {at_bound} of a search bound (creep's upper bound excepted: a drift longer than the "
    "records, reported as not identified).",
    "A candidate is *identified* if the fold estimates of its identifying parameters agree within {partial_se} "
    "(jackknife spread: relative, a clipping level relative to the output's range; a mode is identified by its "
    "natural frequency alone, its damping reported).")

ALSO_CHECK = (
    "Each cause under `also` is checked as the named extension is (`validation`) on top of what was kept before "
    "it (a clip, and what follows it, is not checked). Reported; the verdict does not change.")


SECTIONS = (  # (title, where in the code, definitions and rules), in the order they are applied
    ("Held-out targets", "`heldout`", (HELD_OUT,)),
    ("Evidence and admission", "`heldout`; what keeps each cause's meaning: its class in `causes`", ADMISSION),
    ("Naming one cause", "`selection.decide`", SELECTION),
    ("After the verdict", "`secondary`, `backward`, `slow_part`, `validation`; applied in this order",
     (*AFTER_SELECTION, ALSO_CHECK)),
)


def rule_text(policy: Policy) -> str:
    """The decision rule as numbered markdown, each rule with its trace id and the policy's values."""
    out, n = [render(NOTATION, policy), ""], 0
    for title, where, items in SECTIONS:
        out += [f"**{title}** ({where})", ""]
        for item in items:
            n += 1
            head, body = (f"`{item.id}`: ", item.statement) if isinstance(item, Rule) else ("", item)
            out.append(f"{n}. {head}{render(body, policy)}")
        out.append("")
    return "\n".join(out).rstrip("\n")
