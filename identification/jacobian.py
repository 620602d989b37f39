"""The forward-difference Jacobian driver every least-squares search uses (one home).

``CachedResidual`` remembers the residual of the last point asked for (scipy's
least_squares asks for the same point again when it wants the Jacobian there);
``forward_difference`` perturbs each free coordinate by its step, taken
backwards where a forward step would leave the upper bound, and evaluates all
perturbed points as one batch.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


class CachedResidual:
    """residual(z) with the last point's value kept (keyed by the bytes of z)."""

    def __init__(self, compute: Callable[[np.ndarray], np.ndarray]):
        self.compute = compute
        self._key: bytes | None = None
        self._value: np.ndarray | None = None

    def __call__(self, z: np.ndarray) -> np.ndarray:
        key = np.asarray(z, dtype=float).tobytes()
        if key != self._key:
            self._value = self.compute(z)
            self._key = key
        return self._value

    def clear(self) -> None:
        self._key = self._value = None


def forward_difference(residual_batch: Callable[[np.ndarray], np.ndarray], z: np.ndarray, r0: np.ndarray,
                       step: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """J (n_residuals, n_coordinates) of ``residual_batch`` at z by forward differences.

    ``residual_batch`` maps points (k, n) to residuals (k, m); ``r0`` is the residual at z; a step
    that would pass ``upper`` is taken backwards.
    """
    h = np.where(z + step <= upper, step, -step)
    Z = np.repeat(np.asarray(z, dtype=float)[None], h.size, axis=0)
    Z[np.arange(h.size), np.arange(h.size)] += h
    R = residual_batch(Z)
    return (R - r0[None]).T / h[None]
