"""The paper's seven-frequency protocol and scoring of a model on a dataset.

Input (eq. 1): V(t) = sin(2 pi f t - pi/2) + 1.5 kV, sampled every 1 ms, at
0.02, 0.05, 0.1, 0.2, 0.4, 0.8 and 1 Hz. Identification on 0.02, 0.1, 0.4 and
1 Hz with Table 1's weights k_m = 4, 1, 4, 1; validation on 0.05, 0.2 and
0.8 Hz. One stable period is scored per frequency (the paper's n_m: 50,000
samples at 0.02 Hz ... 1,000 at 1 Hz).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.models.base import HysteresisModel

from .metrics import e_m, e_rms, fitness

FREQUENCIES_HZ = (0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.0)
IDENTIFICATION_WEIGHTS = {0.02: 4.0, 0.1: 1.0, 0.4: 4.0, 1.0: 1.0}  # Table 1, k_m
VALIDATION_FREQUENCIES_HZ = (0.05, 0.2, 0.8)
SAMPLE_TIME_S = 1e-3
OFFSET_KV = 1.5
AMPLITUDE_KV = 1.0


def paper_voltage(t, frequency_hz: float) -> np.ndarray:
    """Eq. 1: V(t) = sin(2 pi f t - pi/2) + 1.5 (kV)."""
    return AMPLITUDE_KV * np.sin(2 * np.pi * frequency_hz * np.asarray(t, float) - 0.5 * np.pi) + OFFSET_KV


def role_of(frequency_hz: float) -> str:
    return "identification" if frequency_hz in IDENTIFICATION_WEIGHTS else "validation"


def weight_of(frequency_hz: float) -> float:
    return IDENTIFICATION_WEIGHTS.get(frequency_hz, 1.0)


def period_samples(frequency_hz: float, dt: float = SAMPLE_TIME_S) -> int:
    return int(round(1.0 / (frequency_hz * dt)))


def protocol_time(frequency_hz: float, n_periods: float = 2, dt: float = SAMPLE_TIME_S) -> np.ndarray:
    return np.arange(int(round(n_periods * period_samples(frequency_hz, dt)))) * dt


def simulated_dataset(
    model: HysteresisModel,
    params: Mapping[str, float],
    *,
    n_periods: float = 2,
    dt: float = SAMPLE_TIME_S,
    noise_sd: float = 0.0,
    seed: int | None = 0,
    frequencies: Sequence[float] = FREQUENCIES_HZ,
    name: str = "simulated",
) -> Dataset:
    """The protocol's seven records with outputs simulated from a model (plus white noise)."""
    rng = np.random.default_rng(seed)
    records = []
    for f in frequencies:
        t = protocol_time(f, n_periods, dt)
        u = paper_voltage(t, f)
        y = model.simulate(u, dt, params)
        if noise_sd > 0:
            y = y + rng.normal(0.0, noise_sd, y.size)
        records.append(Record(file=f"f{f:g}Hz.npz", t=t, u=u, y=y, role=role_of(f), frequency_hz=f,
                              weight=weight_of(f)))
    return Dataset(name=name, records=records, description=f"{model.name} simulated on the paper's protocol",
                   input_unit="kV", output_unit="mm")


# --- scoring ------------------------------------------------------------------
@dataclass(frozen=True)
class RecordScore:
    """The errors of a model on one record's scored window (eq. 10).

    Attributes
    ----------
    file : str
        The record's file name.
    frequency_hz : float or None
        The record's drive frequency, Hz (None: not a periodic drive).
    role : str
        "identification" (fitted) or "validation" (not fitted).
    e_m : float
        The largest absolute error, in percent of the measured peak-to-peak of the scored window.
    e_rms : float
        The root-mean-square error, in percent of the measured peak-to-peak of the scored window.
    """

    file: str
    frequency_hz: float | None
    role: str
    e_m: float
    e_rms: float

    def as_dict(self) -> dict:
        return {"file": self.file, "frequency_hz": self.frequency_hz, "role": self.role,
                "e_m": self.e_m, "e_rms": self.e_rms}


def input_range(records: Sequence[Record]) -> tuple[float, float]:
    """(min, max) of the input over whole records: the operator structure of a fitted model."""
    return (float(min(np.min(r.u) for r in records)), float(max(np.max(r.u) for r in records)))


def predict(model: HysteresisModel, params, record: Record, in_range=None) -> np.ndarray:
    """Simulate a record from its first sample."""
    return model.simulate(record.u, record.dt, params, input_range=in_range)


def score_records(model: HysteresisModel, params, records: Sequence[Record], in_range=None) -> list[RecordScore]:
    scores = []
    for r in records:
        y = predict(model, params, r, in_range)[r.scored]
        ya = r.y[r.scored]
        scores.append(RecordScore(r.file, r.frequency_hz, r.role, e_m(y, ya), e_rms(y, ya)))
    return scores


def dataset_fitness(model: HysteresisModel, params, records: Sequence[Record], in_range=None) -> float:
    """Eq. 9 over the given (identification) records' scored windows."""
    preds = [predict(model, params, r, in_range)[r.scored] for r in records]
    return fitness(preds, [r.y[r.scored] for r in records], [r.weight for r in records])
