"""How much held-out evidence a planted effect gives by itself: the accuracy benchmark's ceiling.

The planted effect's own waveform (what the generator added to each record,
known exactly, with one free gain) is added as a regressor to the base model,
and to the named cause's extension when that is another cause, and scored by
the diagnosis's own held-out test (``selection``: leave one identification
record out, linear parameters re-solved on the others, block signed-rank z,
folds improved; ``selection.evidence``). An extension predicts the planted
effect at best about as well as its exact waveform (better only where refitting
the base's nonlinear parameters with it also removes some of the base's own
misfit; here they stay at the base's fit), so an effect that fails this test is
about at or below what held-out evidence can show on these records. A second
reading (``extension_at_truth``) uses the vocabulary's own extension at the
planted parameters instead. A third reference (``"kept"``) is everything the
diagnosis kept (the named cause with its secondary causes composed on top),
when that is more than the named cause and holds no planted cause: a plant's
own causes (the virtual DEA's relaxation and lag) are then counted as the
diagnosis counts them, which the first two readings ignore. It errs the other
way: what was kept was fitted with the effect present and may have absorbed
part of it. Benchmark-only: it needs the generator's truth
(``planted.planted_case``'s ``signals`` and ``effects``).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from hysbench.benchmarks.diagnosis.policy import Policy
from hysbench.benchmarks.diagnosis.selection import Folds, evidence, out_of_fold, score

NO_NAMED_REFERENCE = ("interference", "saturation")  # named causes whose held-out design is not one matrix
AT_TRUTH_NFEV = 8  # the base's nonlinear parameters refitted around an extension at the planted parameters


def planted_column(screen, signal: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The effect's waveform on the screen's rows (None if a record has none)."""
    cols = []
    for p in screen.parts:
        s = signal.get(p.record.file)
        if s is None:
            return None
        cols.append(np.asarray(s)[p.rows])
    return np.concatenate(cols)


def _summary(h: dict) -> dict:
    return {"gain": h["gain"], "z": h["z"], "folds_improved": h["folds_improved"], "n_folds": h["n_folds"],
            "evidence": evidence(h, Policy())}


def effect_evidence(diag, truth: Mapping) -> dict:
    """Per planted effect: its held-out score on top of the base model (``"base"``) and on top of the named
    cause's extension when another cause is named (``"named"``), each {gain, z, folds_improved, n_folds,
    evidence}; for a relaxation, delay or mode also the vocabulary's own extension at the planted parameters
    against each of them (``"extension_at_truth_on_base"``, ``"extension_at_truth_on_named"``)."""
    screen = diag.screen
    folds = Folds.of(screen)
    references = {"base": screen.design(screen.base, screen.base_nl)}
    chosen = diag.chosen
    if chosen is not None and chosen.cause not in truth["kinds"] and chosen.cause not in NO_NAMED_REFERENCE:
        references["named"] = screen.design(chosen.model, {n: chosen.params[n] for n in chosen.model.nonlinear_names})
    kept = kept_composite(diag, truth["kinds"])
    if kept is not None:
        references["kept"] = screen.design(kept.model, {n: kept.params[n] for n in kept.model.nonlinear_names})
    errors = {ref: out_of_fold(screen, folds, lambda m, A=A: A) for ref, A in references.items()}
    out = {}
    for kind, signal in truth["signals"].items():
        col = planted_column(screen, signal)
        if col is None or not np.any(col):
            continue
        out[kind] = {}
        for ref, A in references.items():
            with_effect = np.column_stack([A, col])
            out[kind][ref] = _summary(score(folds, errors[ref], out_of_fold(screen, folds, lambda m: with_effect)))
        for ref in references:
            on = {"named": chosen, "kept": kept}.get(ref)
            A_true = extension_at_truth(screen, kind, truth["effects"][kind], on)
            if A_true is not None:
                out[kind][f"extension_at_truth_on_{ref}"] = _summary(
                    score(folds, errors[ref], out_of_fold(screen, folds, lambda m: A_true)))
    return out


def keeps_more(causes: Sequence[str], kinds) -> bool:
    """Whether what the diagnosis kept (the named cause, then those under "also") is more than the named cause,
    composes into one design (no interference or clip) and holds none of the planted ``kinds``."""
    return len(causes) >= 2 and not set(causes) & {*NO_NAMED_REFERENCE, *kinds}


def kept_composite(diag, kinds) -> object | None:
    """Everything the diagnosis kept as one separable candidate (the last of the named cause and its secondary
    causes, each composed on top of the ones before) if it ``keeps_more``, its components included; else None."""
    chain = [c for c in (diag.chosen, *diag.also) if c is not None]
    parts = [c.cause for c in chain] + list(getattr(chain[-1].model, "components", ()) if chain else ())
    if len(chain) < 2 or not keeps_more(parts, kinds):
        return None
    return chain[-1]


def extension_at_truth(screen, kind: str, effect: Mapping, on=None) -> np.ndarray | None:
    """The design of the vocabulary's own extension for ``kind`` with the planted parameters (a relaxation's
    one time constant, a delay, a mode), on top of the candidate ``on`` (the named cause, its parameters
    kept) or of the base alone; the base's nonlinear parameters refitted with the rest held (as a candidate's
    joint stage does). None for causes whose planted form has no such parameters (creep's logarithmic law,
    an interference's per-record phase, a clip), or when ``on`` already has that component."""
    planted = {"relaxation": {"tau1": effect.get("tau_s")}, "delay": {"delay": effect.get("delay_s")},
               "resonance": {"natural_frequency": effect.get("natural_frequency_hz"),
                             "damping_ratio": effect.get("damping_ratio")}}.get(kind)
    if planted is None:
        return None
    parts = tuple(getattr(on.model, "components", ())) if on is not None else ()
    if kind in parts:
        return None
    hyper = dict(on.hyperparameters) if on is not None else {}
    if kind == "relaxation":
        hyper.update(n_relaxation=1, relaxation_powers=[1])
    model = screen.extension((*parts, kind), **hyper)
    z = {**screen.base_nl, **({n: on.params[n] for n in on.model.nonlinear_names} if on is not None else {}),
         **{k: float(v) for k, v in planted.items()}}
    if screen.base_nl_names:
        z = screen.refine(model, z, [(n, False) for n in screen.base_nl_names], max_nfev=AT_TRUTH_NFEV)
    return screen.design(model, z)


def shows_evidence(per_effect: Mapping, references: tuple[str, ...] = ("base", "named")) -> bool:
    """Any planted effect gives held-out evidence on one of ``references`` (default: its exact waveform on
    top of the base or of the named cause)."""
    return any(s["evidence"] for refs in per_effect.values() for ref, s in refs.items() if ref in references)


def _reaches(refs: Mapping, on: tuple[str, ...]) -> bool:
    """One effect's evidence on any of the references ``on``: a relaxation's, delay's or mode's by its extension
    at the planted parameters, another effect's by its waveform."""
    at_truth = {ref.removeprefix("extension_at_truth_on_"): s for ref, s in refs.items()
                if ref.startswith("extension_at_truth")}
    return any(s["evidence"] for ref, s in (at_truth or refs).items() if ref in on)


def extension_could_show(per_effect: Mapping) -> bool:
    """The reading with the vocabulary's own extensions: a planted relaxation, delay or mode counts only if
    its extension at the planted parameters gives held-out evidence on the base or the named cause; the
    other effects as ``shows_evidence``."""
    return any(_reaches(refs, ("base", "named")) for refs in per_effect.values())


def shows_on_kept(per_effect: Mapping) -> bool:
    """``shows_evidence``, and where everything kept is a reference of its own, on top of it as well (the exact
    waveform, or a relaxation's, delay's or mode's extension at the planted parameters)."""
    if not shows_evidence(per_effect):
        return False
    on_kept = [s for refs in per_effect.values() for ref, s in refs.items() if ref.endswith("kept")]
    return not on_kept or any(s["evidence"] for s in on_kept)


def extension_on_kept(per_effect: Mapping) -> bool:
    """The strictest reading: an effect that ``extension_could_show`` counts and, where everything kept is a
    reference of its own, that shows on top of it by the same rule (its extension at the planted parameters
    for a relaxation, delay or mode; else its waveform)."""
    return any(_reaches(refs, ("base", "named")) and (not any(ref.endswith("kept") for ref in refs)
                                                       or _reaches(refs, ("kept",)))
               for refs in per_effect.values())
