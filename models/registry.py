"""Model registry: ``get_model(name, **hyperparameters)``, ``list_models()``."""

from __future__ import annotations

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
    try:
        return factory(**hyperparameters)
    except TypeError as exc:
        raise ModelError(f"bad hyperparameters for model {name!r}: {exc}") from None
