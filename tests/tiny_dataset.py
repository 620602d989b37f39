"""A tiny dataset written to a folder: three short periodic records (two to identify, one to validate),
output peak in [1, 2) (its power-of-two scale is 1). For tests of input handling and scale, not accuracy."""

from __future__ import annotations

from pathlib import Path

import numpy as np

FREQUENCIES = {"f1Hz.npz": (1.0, "identification"), "f2Hz.npz": (2.0, "identification"),
               "f1.5Hz.npz": (1.5, "validation")}
SAMPLES_PER_PERIOD = 40


def tiny_records(output_factor: float = 1.0, noise_seed: int = 0) -> dict[str, tuple]:
    """{file: (t, u, y)}: two periods of a sine drive and a lagging, slightly curved response."""
    rng = np.random.default_rng(noise_seed)
    out = {}
    for file, (f, _) in FREQUENCIES.items():
        dt = 1.0 / (f * SAMPLES_PER_PERIOD)
        t = np.arange(2 * SAMPLES_PER_PERIOD) * dt
        u = 1.5 + np.sin(2 * np.pi * f * t)
        y = 0.45 * u + 0.05 * u**2 + 0.12 * np.sin(2 * np.pi * f * t - 0.6 - 0.1 * f) + 0.004 * rng.standard_normal(t.size)
        out[file] = (t, u, y * output_factor)
    return out


def write_tiny_dataset(folder: Path, output_factor: float = 1.0, records: dict | None = None,
                       roles: dict | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    lines = ['name = "tiny"', 'time_column = "t"', 'input_column = "u"', 'output_column = "y"']
    for file, (t, u, y) in (records or tiny_records(output_factor)).items():
        f, role = FREQUENCIES.get(file, (None, "identification"))
        role = (roles or {}).get(file, role)
        np.savez(folder / file, t=t, u=u, y=y)
        lines += ["", "[[records]]", f'file = "{file}"', f'role = "{role}"'] + ([f"frequency_hz = {f}"] if f else [])
    (folder / "dataset.toml").write_text("\n".join(lines) + "\n")
    return folder
