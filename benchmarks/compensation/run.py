"""The tracking benchmark: every compensator on every reference, on the plant.

Controllers per reference (names are the JSON keys):

* ``linear``          the static linear gain's inverse, open loop (no model)
* ``<model>``         the model's inverse, open loop
* ``pi``              the PI loop alone (reference tracking by feedback only)
* ``pi+linear``       the PI loop with the linear inverse as feedforward
* ``pi+<model>``      the PI loop with the model's inverse as feedforward

Scores on the reference's scored samples, against the sensor's reading (what the
experimenter sees: the noise, sd 0.01 mm, is in every score): e_rms and e_m in percent
of the reference's peak-to-peak there (``hysbench.data.metrics``); ``clipped`` counts the
scored samples at which the command was clipped at the input limits or the inverse did
not reach the reference (``input_clipped`` and ``inverse_clipped`` give the two apart).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from hysbench.data.dataset import Dataset, load_dataset
from hysbench.data.metrics import e_m, e_rms
from hysbench.identification.api import build_identifier
from hysbench.identification.errors import IdentificationError
from hysbench.models import get_model
from hysbench.models.errors import HysbenchError

from ..matrix.cells import MATRIX_BUDGET

from .controllers import (PI, PI_BANDWIDTH_HZ, InverseNotRunnable, LinearGain, ModelInverse,
                          check_inverse_option)
from .plant import DEAPlant
from .references import Reference, references

DEFAULT_MODELS = ("classical-pi", "mrpim", "rate-dependent-pi", "mrpim+relaxation", "mrpim+creep", "mrpim+interference",
                  "viscoelastic", "elliptical", "dual-polynomial", "preisach", "bouc-wen")

# Identifier options per model under ``--method auto`` (varpro for these): bouc-wen gets the
# matrix's varpro budget (benchmarks/matrix/cells.MATRIX_BUDGET: one local search from the best
# of 8 candidates). On the default dataset it reaches the same optimum as varpro's own default
# budget (validation e_rms 6.998223 % both, parameters equal to 3 digits) in 24 s instead of 90 s.
AUTO_IDENTIFY_OPTIONS = {"bouc-wen": MATRIX_BUDGET["varpro"]}


def identify_options_for(name: str, method: str, options: Mapping | None = None) -> dict:
    """The identifier options a model gets: the user's ``options`` over ``AUTO_IDENTIFY_OPTIONS``
    (those only under ``--method auto``)."""
    return {**(AUTO_IDENTIFY_OPTIONS.get(name, {}) if method == "auto" else {}), **(options or {})}


def check_identify_options(names, method: str, options: Mapping | None) -> None:
    """Refuse, in one line naming the model, a method or option any of ``names`` cannot be identified
    with (the identifier built and checked against the model as ``identify`` does), before any fit.
    The common options (fit_on, bounds, start) are checked when each model's identification starts."""
    if options is not None and not isinstance(options, Mapping):
        raise HysbenchError(f"identify_options must map option names to values, got {type(options).__name__}")
    for name in names:
        model = get_model(name)
        try:
            for stage in build_identifier(method, model, identify_options_for(name, method, options)).stages():
                stage.check(model)
        except IdentificationError as err:
            raise IdentificationError(f"{name}: {err}") from None


@dataclass
class Tracking:
    """One controller on one reference: the run and its scores.

    Attributes
    ----------
    reference : Reference
        The reference tracked (its name, desired output in mm, scored samples).
    u : numpy.ndarray
        The command sent to the plant, kV, one value per sample.
    y : numpy.ndarray
        The sensor's reading of the plant's output, mm, one value per sample.
    clipped_input : numpy.ndarray
        Bool per sample: the command was clipped at the input limits.
    clipped_inverse : numpy.ndarray
        Bool per sample: the inverse did not reach the reference.
    scores : dict
        Filled by ``score()``, on the reference's scored samples: ``e_rms`` and ``e_m`` in percent of the
        reference's peak-to-peak there (None when ``y`` is not finite), ``clipped`` (samples clipped
        either way), ``input_clipped``, ``inverse_clipped``, ``scored_samples`` and ``finite``.
    """

    reference: Reference
    u: np.ndarray
    y: np.ndarray
    clipped_input: np.ndarray
    clipped_inverse: np.ndarray
    scores: dict = field(default_factory=dict)

    def score(self) -> dict:
        s = self.reference.scored
        r, y = self.reference.y[s], self.y[s]
        finite = bool(np.all(np.isfinite(y)))
        ci, cv = self.clipped_input[s], self.clipped_inverse[s]
        self.scores = {"e_rms": e_rms(y, r) if finite else None, "e_m": e_m(y, r) if finite else None,
                       "clipped": int(np.count_nonzero(ci | cv)), "input_clipped": int(np.count_nonzero(ci)),
                       "inverse_clipped": int(np.count_nonzero(cv)), "scored_samples": int(r.size),
                       "finite": finite}
        return self.scores


def check_models(names) -> tuple[list[str], dict[str, str]]:
    """(invertible names, {name: why not} for the others); unknown names raise ModelError."""
    ok, not_invertible = [], {}
    for name in names:
        reason = get_model(name).inverse_unavailable
        if reason:
            not_invertible[name] = reason
        else:
            ok.append(name)
    return ok, not_invertible


def compensate(dataset: Dataset | str, models=DEFAULT_MODELS, method: str = "auto", seed: int = 0,
               bandwidth_hz: float = PI_BANDWIDTH_HZ, plant: DEAPlant | None = None,
               reference_names=None, log=print, identify_options: Mapping | None = None,
               inverse: str = "auto") -> tuple[dict, dict]:
    """(result JSON, runs {reference: {controller: Tracking}}) for the dataset's plant.

    ``identify_options``: identifier options for every model (``identify``'s keyword arguments,
    e.g. ``{"stable_inverse": True}``), over ``AUTO_IDENTIFY_OPTIONS``. ``inverse``: the P-I
    family's causal inverse, "auto", "exact" or "reference-driven" (``ModelInverse.identify``);
    a model whose fit cannot run the one asked for is reported in ``not_invertible``. Both are
    checked before any identification."""
    t_start = time.perf_counter()
    check_inverse_option(inverse)
    ds = load_dataset(dataset) if not isinstance(dataset, Dataset) else dataset
    plant = plant or DEAPlant()
    dt = ds.records[0].dt
    if abs(dt - plant.dt) > 1e-12:
        raise HysbenchError(f"dataset {ds.name!r} is sampled every {dt:g} s; the plant runs at {plant.dt:g} s")
    if (ds.input_unit, ds.output_unit) != ("kV", "mm"):
        raise HysbenchError(f"dataset {ds.name!r} is in {ds.input_unit or '?'} -> {ds.output_unit or '?'}; the plant "
                            "(the virtual DEA) takes kV and gives mm: compensate needs a dataset recorded on it")
    refs = references(ds, dt)  # refuses a dataset without the protocol's sines, before any identification
    if reference_names is not None:
        if not any(reference_names):
            raise HysbenchError(f"--references names no reference; known: {', '.join(r.name for r in refs)}")
        unknown = sorted(set(n for n in reference_names if n) - {r.name for r in refs})
        if unknown:
            raise HysbenchError(f"unknown reference(s) {', '.join(unknown)}; known: {', '.join(r.name for r in refs)}")
        refs = [r for r in refs if r.name in reference_names]
    invertible, not_invertible = check_models(models)
    if not invertible:
        raise HysbenchError("no model to compare: " + "; ".join(f"{n} cannot be inverted ({why})"
                                                                 for n, why in not_invertible.items()))
    check_identify_options(invertible, method, identify_options)
    for name, why in not_invertible.items():
        log(f"{name}: cannot be inverted: {why}")
    linear = LinearGain.fit(ds)
    pi = PI.design(linear.gain, bandwidth_hz)
    inverses = {}
    for name in invertible:
        options = identify_options_for(name, method, identify_options)
        try:
            inverses[name] = ModelInverse.identify(name, ds, method=method, seed=seed, u_limits=plant.u_limits,
                                                   inverse=inverse, **options)
        except InverseNotRunnable as err:  # the fit cannot run the inverse asked for: say so, keep the others
            not_invertible[name] = str(err)
            log(f"{name}: cannot be inverted: {err}")
            continue
        log(f"{name}: identified ({inverses[name].fit.method}, {inverses[name].identify_seconds:.1f} s), "
            f"{inverses[name].inverse} inverse")
    if not inverses:
        raise HysbenchError("no model to compare: " + "; ".join(f"{n} cannot be inverted ({why})"
                                                                 for n, why in not_invertible.items()))
    runs: dict[str, dict[str, Tracking]] = {}
    invert_seconds = 0.0
    for ref in refs:
        feedforwards = {"linear": linear.invert(ref.y)}
        for name, inv in inverses.items():
            t0 = time.perf_counter()
            feedforwards[name] = inv.invert(ref.y, dt, plant.u_limits)
            invert_seconds += time.perf_counter() - t0
        zero = np.zeros(ref.y.size)
        plans = [(name, ff, 0.0, 0.0) for name, ff in feedforwards.items()]
        plans.append(("pi", None, pi.kp, pi.ki))
        plans += [(f"pi+{name}", ff, pi.kp, pi.ki) for name, ff in feedforwards.items()]
        runs[ref.name] = {}
        for controller, ff, kp, ki in plans:
            run = plant.run(ref.y, zero if ff is None else ff.u, kp, ki)  # PI alone: no feedforward
            tracking = Tracking(ref, run.u, run.y, run.clipped, zero.astype(bool) if ff is None else ff.clipped)
            tracking.score()
            runs[ref.name][controller] = tracking
        log(f"{ref.name}: " + ", ".join(f"{c} {t.scores['e_rms']:.3g}" if t.scores["e_rms"] is not None else
                                       f"{c} non-finite" for c, t in runs[ref.name].items()))
    result = {
        "format": "hysbench-compensation/1",
        "dataset": ds.name,
        "dataset_hash": ds.content_hash(),
        "plant": {"physics": "hysbench.models.dea_physics TRUTH", "sensor": plant.sensor.as_dict(),
                  "u_limits_kV": list(plant.u_limits), "noise_seed": plant.seed, "dt_s": plant.dt},
        "linear": {"gain": linear.gain, "offset": linear.offset},
        "pi": {"kp": pi.kp, "ki": pi.ki, "bandwidth_hz": pi.bandwidth_hz, "zero_s": pi.zero_s},
        "models": {name: {"method": inv.fit.method, "identify_options": inv.identify_options,
                          "inverse": inv.inverse, "identify_s": inv.identify_seconds,
                          "validation_e_rms_mean": inv.fit.mean("validation"), "max_rate": inv.max_rate,
                          "params": inv.fit.params,
                          "input_range": list(inv.fit.input_range), "notes": list(inv.fit.notes)}
                   for name, inv in inverses.items()},
        "not_invertible": not_invertible,
        "inverse_option": inverse,
        "seed": seed,
        "references": {ref: {c: t.scores for c, t in by.items()} for ref, by in runs.items()},
        "invert_seconds": invert_seconds,
        "seconds": time.perf_counter() - t_start,
    }
    return result, runs
