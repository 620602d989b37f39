"""Planted cases for the diagnosis tests, each generated and diagnosed once per test process.

``diagnosed(kinds, base, drive, seed, ...)`` returns ``(diagnosis, truth)`` for a planted case
(``hysbench.benchmarks.diagnosis_accuracy.planted.planted_case``) diagnosed with the base model MRPIM and the
default policy; every test that reads the same case reads the same diagnosis (do not modify it).
``planted(...)`` returns a fresh copy of the case's dataset, for a test that changes its records.
"""

from __future__ import annotations

import copy
import json
from functools import lru_cache

from hysbench.benchmarks.diagnosis import diagnose
from hysbench.benchmarks.diagnosis_accuracy.planted import planted_case


def _key(effects: dict | None) -> str | None:
    return json.dumps(effects, sort_keys=True) if effects else None


@lru_cache(maxsize=None)
def _planted(kinds: tuple, base: str, drive: str, seed: int, effects: str | None):
    return planted_case(kinds, base, drive, seed, effects=json.loads(effects) if effects else None)


def planted(kinds, base: str, drive: str, seed: int, effects: dict | None = None):
    """(dataset, truth) of a planted case: a copy the caller may change."""
    return copy.deepcopy(_planted(tuple(kinds), base, drive, seed, _key(effects)))


@lru_cache(maxsize=None)
def _diagnosed(kinds: tuple, base: str, drive: str, seed: int, effects: str | None, extend: bool,
               experiments: bool):
    ds, truth = _planted(kinds, base, drive, seed, effects)
    return diagnose(copy.deepcopy(ds), seed=0, experiments=experiments, extend=extend), truth


def diagnosed(kinds, base: str, drive: str, seed: int, effects: dict | None = None, extend: bool = True,
              experiments: bool = False):
    """(diagnosis, truth) of a planted case, diagnosed once per process for these arguments."""
    return _diagnosed(tuple(kinds), base, drive, seed, _key(effects), extend, experiments)
