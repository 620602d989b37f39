"""Model registry: ``get_model(name, **hyperparameters)``, ``list_models()``."""

from __future__ import annotations

import difflib
import inspect
from typing import Callable

from .base import HysteresisModel
from .errors import ModelError

_REGISTRY: dict[str, Callable[..., HysteresisModel]] = {}
_NOT_IN_MATRIX: set[str] = set()


def register(name: str, factory: Callable[..., HysteresisModel] | None = None, *, in_matrix: bool = True):
    """Register a model class or factory under ``name`` (usable as a decorator).

    ``in_matrix=False`` keeps a model out of the default benchmark matrix
    (``hysbench run`` without ``--models``); it can still be named there.
    """

    def add(f):
        if name in _REGISTRY and _REGISTRY[name] is not f:
            raise ModelError(f"a model is already registered as {name!r}")
        _REGISTRY[name] = f
        (_NOT_IN_MATRIX.discard if in_matrix else _NOT_IN_MATRIX.add)(name)
        return f

    return add(factory) if factory is not None else add


def is_registered(name: str) -> bool:
    return name in _REGISTRY


def list_models(matrix_only: bool = False) -> list[str]:
    """Registered names; ``matrix_only``: those the default benchmark matrix runs."""
    return sorted(n for n in _REGISTRY if not (matrix_only and n in _NOT_IN_MATRIX))


def get_model(name: str, **hyperparameters) -> HysteresisModel:
    """A new model instance by registry name."""
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise ModelError(f"unknown model {name!r}; known models: {', '.join(list_models())}") from None
    accepted = hyperparameter_names(name)
    unknown = [k for k in hyperparameters if accepted is not None and k not in accepted]
    if unknown:
        close = difflib.get_close_matches(unknown[0], accepted, n=1, cutoff=0.75)  # a typo, not any likeness
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ModelError(f"unknown hyperparameter {unknown[0]!r} for model {name!r}{hint}; it takes: "
                         f"{', '.join(accepted) or 'none'}")
    try:
        return factory(**hyperparameters)
    except TypeError as exc:
        raise ModelError(f"bad hyperparameters for model {name!r}: {exc}") from None


def hyperparameter_names(name: str) -> list[str] | None:
    """The hyperparameters model ``name`` takes (its constructor's arguments); None if its factory takes any.

    A factory function that forwards ``**hyperparameters`` names what it takes in its
    ``hyperparameter_names`` attribute.
    """
    factory = _REGISTRY[name]
    declared = getattr(factory, "hyperparameter_names", None)
    if declared is not None:
        return list(declared)
    target = factory.__init__ if isinstance(factory, type) else factory
    try:
        parameters = list(inspect.signature(target).parameters.values())
    except (TypeError, ValueError):  # a callable whose signature Python cannot read
        return None
    if isinstance(factory, type):
        parameters = parameters[1:]  # self
    if any(p.kind is p.VAR_KEYWORD for p in parameters):
        return None
    return [p.name for p in parameters if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
