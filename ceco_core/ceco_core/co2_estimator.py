"""Cabin CO2 estimate of a controller that sees only the vehicle's sensors (``measurements: vehicle``).

A three-state Kalman filter (Simon, *Optimal State Estimation*, 2006, ch. 5: the discrete filter of a
linear time-varying model) on the cabin CO2 balance, a rate bias and the sensor's lag, the balance written
once in :mod:`ceco_core.air_quality`:

    dC/dt = F / m_air (C_amb - C) + n g / (m_air k) + b    cabin CO2 C [ppm]
    db/dt = w_b                                              rate bias b [ppm/s] (random walk): the car's
                                                             leakage and the occupants' metabolism off nominal
    dY/dt = (C - Y) / tau_s                                  the sensor's lagged value Y [ppm]
    y_j   = Y(t_j) + v_j                                     a reading (NaN: none)

with F = (1 - r) mdot_bl + mdot_inf(V) [kg/s] from the measured door position r, the blower command and the
speed, n the occupants (seat-occupancy detection), g the generation per occupant [kg/s], k = 1.519e-6 kg/kg per
ppm. The step is exact for the held inputs (matrix exponential by scipy). The reading's error v combines the
sensor's noise and its per-run offset and gain error (variances of the uniform draws); the model's
uncertainty (leakage, metabolic rate) enters as process noise on C.

Without a reading (no sensor fitted, or it failed) the filter runs on the balance alone, its variance
growing: the estimate stays defined and says so (``Co2Estimate.source``).

Pure numpy/scipy; no ROS.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.linalg import expm

from ceco_core.air_quality import (
    CO2_AMB_PPM_DEFAULT,
    KGKG_PER_PPM,
    check_settings,
    co2_generation_kgps,
    leakage_kgps,
)
from ceco_core.co2_sensor import Co2SensorParams

__all__ = ["Co2EstimatorParams", "Co2Estimate", "Co2Estimator"]

_SENSOR = Co2SensorParams()
"""The datasheet sensor the estimator assumes (its lag, noise and error bounds: one set of values)."""


@dataclasses.dataclass(frozen=True)
class Co2EstimatorParams:
    """The estimator's model of the car: the nominal values of docs/plant.md's table.

    A controller does not read the simulated car's ``PlantParams``; a car that differs is what the rate bias is for.
    """

    m_air_kg: float = 3.48
    """Dry-air mass of the cabin [kg] (3.0 m3 x 1.16 kg/m3, docs/plant.md)."""
    leak_0_kgps: float = 0.0015
    """Leakage at rest [kg/s] (docs/plant.md)."""
    leak_per_mps_kgps: float = 0.0002
    """Leakage growth with speed [kg/s per m/s]."""
    met: float = 1.2
    """Occupants' metabolic rate [met]."""
    co2_amb_ppm: float = CO2_AMB_PPM_DEFAULT
    """Assumed ambient CO2 [ppm] (the cabin sensor cannot see it)."""
    tau_s: float = _SENSOR.tau_s
    """Sensor lag t63 [s] (``Co2SensorParams``, docs/plant.md)."""
    noise_std_ppm: float = _SENSOR.noise_std_ppm
    """Sensor noise [ppm]."""
    offset_max_ppm: float = _SENSOR.offset_max_ppm
    """Half-width of the sensor's uniform offset [ppm]."""
    gain_error_max: float = _SENSOR.gain_error_max
    """Half-width of the sensor's uniform gain error [-]."""
    process_std_ppm_per_s: float = 0.5
    """Process noise on C [ppm per sqrt(s)]."""
    bias_std_ppm_per_s2: float = 0.01
    """Process noise on the rate bias b [ppm/s per sqrt(s)]: how fast the leakage or metabolism error may change."""
    initial_std_ppm: float = 200.0
    """Standard deviation of the key-on estimate [ppm]."""

    def validate(self) -> Co2EstimatorParams:
        """Raise ValueError naming the field if a value is not finite or not positive; return self."""
        check_settings(self, positive=("m_air_kg", "tau_s", "met", "co2_amb_ppm"))
        return self


@dataclasses.dataclass(frozen=True)
class Co2Estimate:
    """The estimate after one update."""

    co2_cab_ppm: float
    """Estimated cabin CO2 [ppm]."""
    std_ppm: float
    """Its standard deviation [ppm]."""
    source: str
    """'sensor' (the last update used a reading) or 'balance' (no reading: the model alone)."""
    inputs_held: tuple = ()
    """Inputs of the last prediction that were missing or implausible (NaN, a door share outside 0..1, a negative
    flow or speed) and were replaced by their last valid value (at key-on: door 0.8, 0.05 kg/s, standing)."""


class Co2Estimator:
    """``update(t_s, reading_ppm, recirc_share, mdot_bl_kgps, speed_mps, n_occupants) -> Co2Estimate``."""

    def __init__(self, params: Co2EstimatorParams | None = None, initial_ppm: float | None = None):
        self.params = (params or Co2EstimatorParams()).validate()
        self._initial = self.params.co2_amb_ppm if initial_ppm is None else float(initial_ppm)
        self.reset()

    def reset(self) -> None:
        """Key-on: C = Y = the initial value (a parked car flushed to ambient by default)."""
        s = self.params.initial_std_ppm
        self.x = np.array([self._initial, self._initial, 0.0])
        self.P = np.array([[s * s, s * s, 0.0], [s * s, s * s, 0.0], [0.0, 0.0, 0.0]])
        self.t_s: float | None = None
        self._last_inputs = {"recirc_share": 0.8, "mdot_bl_kgps": 0.05, "speed_mps": 0.0}
        self._held: tuple = ()

    def _inputs(self, **given) -> tuple:
        """The inputs to predict with: each valid one, else its last valid value (named in ``self._held``)."""
        held = []
        for name, v in given.items():
            ok = math.isfinite(v) and v >= 0.0 and (name != "recirc_share" or v <= 1.0)
            if ok:
                self._last_inputs[name] = float(v)
            else:
                held.append(name)
        self._held = tuple(held)
        return tuple(self._last_inputs[name] for name in given)

    def _predict(self, dt: float, r: float, m: float, v: float, n: int) -> None:
        p = self.params
        fresh = (1.0 - r) * m + leakage_kgps(p.leak_0_kgps, p.leak_per_mps_kgps, v)
        a = fresh / p.m_air_kg
        src = a * p.co2_amb_ppm + n * co2_generation_kgps(p.met) / (p.m_air_kg * KGKG_PER_PPM)
        # augmented [C, Y, b, 1]: the constant input enters through the last column (exact for held inputs)
        ac = np.array(
            [
                [-a, 0.0, 1.0, src],
                [1.0 / p.tau_s, -1.0 / p.tau_s, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0],
            ]
        )
        phi = expm(ac * dt)
        ad, bd = phi[:3, :3], phi[:3, 3]
        q = np.diag([p.process_std_ppm_per_s**2 * dt, 0.0, p.bias_std_ppm_per_s2**2 * dt])
        self.x = ad @ self.x + bd
        self.P = ad @ self.P @ ad.T + q

    def update(
        self,
        t_s: float,
        reading_ppm: float,
        recirc_share: float,
        mdot_bl_kgps: float,
        speed_mps: float,
        n_occupants: int,
    ) -> Co2Estimate:
        """Advance to ``t_s`` [s] with the inputs held since the last update, then correct with the reading.

        ``reading_ppm`` NaN (no sensor, or it failed): prediction only. A door share, blower flow or speed that is
        NaN or implausible is never clamped: its last valid value is held and named in
        ``Co2Estimate.inputs_held``. A time that does not advance corrects without predicting; a time going back
        is refused (ValueError).
        """
        if not math.isfinite(t_s):
            raise ValueError(f"t_s: must be finite, got {t_s!r}")
        if self.t_s is not None and t_s < self.t_s:
            raise ValueError(f"t_s: {t_s} is before the last update {self.t_s}")
        r, m, v = self._inputs(recirc_share=recirc_share, mdot_bl_kgps=mdot_bl_kgps, speed_mps=speed_mps)
        if self.t_s is not None and t_s > self.t_s:
            self._predict(t_s - self.t_s, r, m, v, int(n_occupants))
        self.t_s = float(t_s)
        held, self._held = self._held, ()
        used = False
        if math.isfinite(reading_ppm) and reading_ppm >= 0:
            p = self.params
            r_var = p.noise_std_ppm**2 + p.offset_max_ppm**2 / 3.0 + (p.gain_error_max * reading_ppm) ** 2 / 3.0
            h = np.array([0.0, 1.0, 0.0])
            s = float(h @ self.P @ h) + r_var
            k = self.P @ h / s
            self.x = self.x + k * (reading_ppm - self.x[1])
            self.P = self.P - np.outer(k, h @ self.P)
            used = True
        std = float(math.sqrt(max(self.P[0, 0], 0.0)))
        return Co2Estimate(float(self.x[0]), std, "sensor" if used else "balance", held)
