"""The virtual DEA's displacement sensor: a laser triangulation sensor read by a 16-bit ADC.

Modelled on the paper's set-up (section 2.2): a Micro-Epsilon ILD2300-100
(0-100 mm on an analogue output of 0-10 V) read every 1 ms by a dSPACE DS1103
16-bit ADC, whose input range is +-10 V. So

    distance  d   = d_rest + x                       (mm; x = platform displacement)
    voltage   v   = d / 10 mm/V + n,  n ~ N(0, sigma_v) white, sigma_v = noise_sd_mm / 10
    v is clipped to the sensor's 0-10 V output
    code      c   = round(v / LSB_V),  LSB_V = 20 V / 2**16 = 0.305 mV  (= 3.05 um)
    output    y   = (c - c_rest) * LSB_mm

The output is the displacement from rest: the experimenter's zero is the code
of the platform at rest (0 V), ``c_rest = round(d_rest / LSB_mm)``. Every
output is an exact multiple of LSB_mm = 200/65536 mm = 25/8192 mm.
The noise is seeded (``numpy.random.Generator``), so a record is reproducible.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numba import njit

from hysbench.models.errors import HysbenchError


@njit(cache=True)
def read_sample(x_mm, noise_volts, rest_mm, mm_per_volt, full_scale_v, lsb_v, rest_code, lsb_mm):
    """One reading (mm from rest) of the true displacement x_mm with the noise noise_volts (V)."""
    volts = (rest_mm + x_mm) / mm_per_volt + noise_volts
    volts = min(max(volts, 0.0), full_scale_v)
    return (np.rint(volts / lsb_v) - rest_code) * lsb_mm


@njit(cache=True)
def read_samples(x_mm, noise_volts, rest_mm, mm_per_volt, full_scale_v, lsb_v, rest_code, lsb_mm):
    out = np.empty(x_mm.shape[0])
    for k in range(x_mm.shape[0]):
        out[k] = read_sample(x_mm[k], noise_volts[k], rest_mm, mm_per_volt, full_scale_v, lsb_v, rest_code, lsb_mm)
    return out


@dataclass(frozen=True)
class LaserSensor:
    """Laser sensor + ADC; the defaults are the virtual DEA's."""

    range_mm: float = 100.0  # measuring range, mapped to 0..volts_full_scale
    volts_full_scale: float = 10.0  # analogue output at the end of the range
    adc_bits: int = 16
    adc_span_v: float = 20.0  # the ADC reads -10..+10 V
    noise_sd_mm: float = 0.01  # white noise, in mm (1 mV at the ADC input)
    rest_distance_mm: float = 25.0  # distance of the platform at rest, inside the range (code 8192 exactly)

    def __post_init__(self):
        if not (0 <= self.rest_distance_mm <= self.range_mm):
            raise HysbenchError(f"sensor: rest distance {self.rest_distance_mm} mm is outside 0..{self.range_mm} mm")
        if self.noise_sd_mm < 0:
            raise HysbenchError(f"sensor: noise_sd_mm must not be negative, got {self.noise_sd_mm}")

    @property
    def mm_per_volt(self) -> float:
        return self.range_mm / self.volts_full_scale

    @property
    def lsb_volts(self) -> float:
        return self.adc_span_v / 2**self.adc_bits

    @property
    def lsb_mm(self) -> float:
        return self.lsb_volts * self.mm_per_volt

    @property
    def rest_code(self) -> int:
        return int(round(self.rest_distance_mm / self.lsb_mm))

    def measure(self, displacement_mm: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Sensor output (mm from rest) for a true displacement history."""
        x = np.ascontiguousarray(displacement_mm, dtype=float)
        return read_samples(x, self.noise_volts(x.size, rng), *self.constants())

    def noise_volts(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """The white noise of n readings, in volts at the ADC input (zeros without noise)."""
        if self.noise_sd_mm > 0:
            return rng.normal(0.0, self.noise_sd_mm / self.mm_per_volt, n)
        return np.zeros(n)

    def constants(self) -> tuple:
        """The arguments after (x_mm, noise_volts) of ``read_sample``."""
        return (float(self.rest_distance_mm), float(self.mm_per_volt), float(self.volts_full_scale),
                float(self.lsb_volts), float(self.rest_code), float(self.lsb_mm))

    def as_dict(self) -> dict:
        return {**asdict(self), "lsb_mm": self.lsb_mm}
