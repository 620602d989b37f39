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
about at or below what held-out evidence can show on these records. Benchmark-only: it needs the
generator's truth (``planted.planted_case``'s ``signals``).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .selection import Folds, evidence, out_of_fold, score

NO_NAMED_REFERENCE = ("interference", "saturation")  # named causes whose held-out design is not one matrix


def planted_column(screen, signal: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """The effect's waveform on the screen's rows (None if a record has none)."""
    cols = []
    for p in screen.parts:
        s = signal.get(p.record.file)
        if s is None:
            return None
        cols.append(np.asarray(s)[p.rows])
    return np.concatenate(cols)


def effect_evidence(diag, truth: Mapping) -> dict:
    """Per planted effect: its held-out score on top of the base model (``"base"``) and on top of the named
    cause's extension when another cause is named (``"named"``), each {gain, z, folds_improved, n_folds,
    evidence}."""
    screen = diag.screen
    folds = Folds.of(screen)
    references = {"base": screen.design(screen.base, screen.base_nl)}
    chosen = diag.chosen
    if chosen is not None and chosen.cause not in truth["kinds"] and chosen.cause not in NO_NAMED_REFERENCE:
        references["named"] = screen.design(chosen.model, {n: chosen.params[n] for n in chosen.model.nonlinear_names})
    errors = {ref: out_of_fold(screen, folds, lambda m, A=A: A) for ref, A in references.items()}
    out = {}
    for kind, signal in truth["signals"].items():
        col = planted_column(screen, signal)
        if col is None or not np.any(col):
            continue
        out[kind] = {}
        for ref, A in references.items():
            with_effect = np.column_stack([A, col])
            h = score(folds, errors[ref], out_of_fold(screen, folds, lambda m: with_effect))
            out[kind][ref] = {"gain": h["gain"], "z": h["z"], "folds_improved": h["folds_improved"],
                              "n_folds": h["n_folds"], "evidence": evidence(h)}
    return out


def shows_evidence(per_effect: Mapping) -> bool:
    """Any planted effect gives held-out evidence on top of the base or of the named cause."""
    return any(s["evidence"] for refs in per_effect.values() for s in refs.values())
