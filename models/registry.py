"""Model registry: ``get_model(name, **hyperparameters)``, ``list_models()``."""

from __future__ import annotations

from typing import Callable

from .base import HysteresisModel
from .errors import ModelError

_REGISTRY: dict[str, Callable[..., HysteresisModel]] = {}


def register(name: str, factory: Callable[..., HysteresisModel] | None = None):
    """Register a model class or factory under ``name`` (usable as a decorator)."""

    def add(f):
        if name in _REGISTRY and _REGISTRY[name] is not f:
            raise ModelError(f"a model is already registered as {name!r}")
        _REGISTRY[name] = f
        return f

    return add(factory) if factory is not None else add


def list_models() -> list[str]:
    return sorted(_REGISTRY)


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
