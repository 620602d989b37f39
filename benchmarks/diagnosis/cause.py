"""The interface of a cause the diagnosis can name (``Cause``, described here once for every cause) and the
registry of the causes (``CAUSES``); the causes themselves are the plug-ins of ``causes``, one module each."""

from __future__ import annotations

from typing import Mapping

import numpy as np

CAUSES: dict[str, "Cause"] = {}
OUTPUT_UNIT = object()  # a reported parameter in the output's unit (``Cause.units``)


def register(cls: type) -> type:
    """Register a ``Cause`` subclass under its ``name`` (an instance; the registry's order is the search's)."""
    CAUSES[cls.name] = cls()
    return cls


def get_cause(name: str) -> "Cause":
    try:
        return CAUSES[name]
    except KeyError:
        raise KeyError(f"unknown cause {name!r}; known: {', '.join(CAUSES)}") from None


def cause_of_parameter(name: str) -> "Cause | None":
    """The cause whose extension adds this nonlinear parameter (None: the base's)."""
    return next((c for c in CAUSES.values() if c.owns(name)), None)


def open_ended_parameter(name: str) -> bool:
    return name in getattr(cause_of_parameter(name), "open_ended", ())


def refined(name: str) -> bool:
    """Whether a gradient refinement moves this nonlinear parameter (a base's always)."""
    return name not in getattr(cause_of_parameter(name), "not_refined", ())


def log_scale(name: str) -> bool:
    """Whether a cause's parameter is searched and summarised on a log scale."""
    return any(name.startswith(p) for c in CAUSES.values() for p in c.log_scale)


class Cause:
    """One cause of the vocabulary. Class attributes describe it; methods do what differs for it.

    The defaults are those of a separable extension (its columns added to, or transforming, the base's), fitted
    and scored by the generic paths of ``screen`` and ``selection``. Below, ``screen`` is a ``Screen``, ``c`` a
    ``Candidate`` of this cause, ``folds`` the leave-one-record-out ``Folds``."""

    name: str = ""
    parameters: tuple = ()  # its nonlinear parameters in the extended model
    log_scale: tuple = ()  # prefixes of its parameters searched on a log scale
    open_ended: tuple = ()  # parameters whose upper search bound is a limit within its meaning (not "at bound")
    only_upper_bound: tuple = ()  # parameters whose lower bound is no effect at all: only the upper counts
    not_refined: tuple = ()  # parameters a gradient refinement holds (searched otherwise)
    relative_to_range: tuple = ()  # parameters whose fold spread is also taken against the output's range
    identifying: tuple | None = None  # the parameters that identify it alone (None: every one)
    bounded = True  # its parameters are checked at their search bounds
    separable = True  # composes with other separable causes in one extended model (``Screen.composite``)
    carries_others = True  # a cause composes on top of it (else only a disturbance still adds)
    disturbance = False  # not driven by the input: a line on top, its phase per record (``lines``)
    transforms = False  # changes the base's columns, not only adds columns
    late_input = False  # the base runs on a late input
    reshapes = False  # under one periodic drive it only reshapes the response's harmonics
    shown_at_rest = False  # the input held at rest separates it from another cause (``experiment.suggest``)
    variants = False  # fitted in variants of increasing order, each competing (``relaxation_variants``)
    slow_twin: str | None = None  # the cause its slowest part may be, slower than every drive period
    time_scale: str | None = None  # its parameter that is a time scale (a slow twin's, standing in)
    units: dict = {}  # its reported parameters (``estimates``) and their units (``OUTPUT_UNIT``: the output's)
    reported_as: dict = {}  # its parameters and their names among the reported ones (the default ``estimates``)

    def owns(self, parameter: str) -> bool:
        return parameter in self.parameters

    def fit(self, screen, library: dict, max_order: int) -> list:
        """Its candidates fitted on the screen (stage 1: the base's nonlinear parameters held)."""
        raise NotImplementedError

    def row_columns(self, nonlinear: Mapping[str, float], dt: float, rows: np.ndarray) -> dict:
        """Linear columns it computes on the screen's rows alone (by name), not from the extended model."""
        return {}

    def library_terms(self, screen, y_hat_rows: np.ndarray):
        """Its terms in the library screen: (names, ``columns(record, y_hat, t)`` -> one array over the record per
        name, each term's time constant or None), or None; ``y_hat_rows``: the null's prediction on the rows."""
        return None

    def joint(self, screen, c, max_nfev: int):
        """Stage 2: ``c`` refined with the base's nonlinear parameters free too (``c`` if nothing gains)."""
        return screen.joint(c, max_nfev)

    def estimates(self, params: Mapping[str, float], model) -> dict:
        """Its parameters in the report's vocabulary (units in the key)."""
        return {key: float(params[name]) for name, key in self.reported_as.items()}

    def from_fit(self, estimates: dict, params: Mapping[str, float]) -> dict:
        """A candidate's estimates updated from its extension identified on whole records (``params``)."""
        return {**estimates, **Cause.estimates(self, params, None)}

    def bounds(self, screen, parameter: str, lo: float, hi: float) -> tuple[float, float]:
        """A parameter's search bounds on these records, from the model's bounds at the drive's time scale."""
        return lo, hi

    def limit(self, screen, estimates: Mapping) -> str:
        """Why estimates fall outside its meaning ("" within): a fit pinned there is not named."""
        return ""

    def on_top(self, screen, kept, own, search: bool):
        """It composed with a kept separable part (``own``: its fit on the base alone); None if it cannot."""
        return screen.composite(kept, own, search=search)

    def starts_on_top(self, primary, starts: list[dict]) -> list[dict]:
        """More starts of its parameters searched on top of ``primary`` (``Screen.composite``)."""
        return []

    def grid_axis(self, screen, model, parameter: str, k: int) -> np.ndarray | None:
        """``k`` starts of a parameter inside its search bounds (None: nothing to search)."""
        lo, hi = screen.bounds_of(model, parameter)
        return (np.geomspace if log_scale(parameter) else np.linspace)(lo, hi, k + 2)[1:-1] if hi > lo else None

    def heldout_errors(self, screen, folds, c, refit: bool, train_residuals: list | None):
        """(out-of-fold residuals, fold estimates), its parameters refitted per fold with ``refit``, each fold's
        residual on its training rows appended to ``train_residuals``; None: the generic linear path."""
        return None

    def fold_checks(self, screen, fold_estimates: list[dict]) -> dict:
        """Entries its held-out score adds from its fold estimates (refitted per fold)."""
        return {}

    def refit_alone(self, screen, model, start: dict, training_rss):
        """Its parameter refitted alone on a fold's training rows, or None for a gradient refinement."""
        return None

    def slowest_time_s(self, estimates: Mapping) -> float | None:
        """Its slowest time scale, where its slow part may be another cause (``slow_twin``)."""
        return None

    def one_fewer(self, screen, c, pinned: list):
        """The variant of one order fewer without its parameters at a bound (``variants`` only)."""
        return None

    def merged(self, chosen, variants, held):
        """A variant that gives way to one of lower order (``variants`` only): ``chosen`` otherwise."""
        return chosen

    def on_validation(self, before: list, c, policy) -> tuple[list, dict]:
        """A disturbance's phase fitted per record on top of ``before`` (what is kept, refitted on whole records):
        the residuals after it and its check on the validation records (the others are identified there)."""
        raise NotImplementedError(f"{self.name} is identified on the validation records, not fitted on top")

    def spectrum_marker(self, parameters: Mapping) -> float | None:
        """A frequency the report's spectrum marks for it (None: nothing)."""
        return None
