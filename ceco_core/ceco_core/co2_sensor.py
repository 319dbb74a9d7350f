"""A cabin CO2 sensor as cars have it: NDIR, slow, with a gain and offset error, noise and a coarse update.

    x_f(t)  = first-order lag of the cabin CO2 C(t), time constant tau_s (t63, transport to the sensor included)
    y(t_j)  = round((1 + g) x_f(t_j) + b + n_j)       at the update instants t_j = j update_s, held between
    g ~ U(-g_max, g_max), b ~ U(-b_max, b_max)          once per sensor (a part's calibration error)
    n_j ~ N(0, sigma^2)                                 white, per update

Defaults (docs/plant.md, "CO2 sensor"): accuracy +-(30 ppm + 3 % of reading) (Sensirion SCD30 and Infineon
XENSIV PAS CO2 datasheets), t63 60 s (SCD4x), repeatability 10 ppm, an update every 5 s, 1 ppm resolution.
A dead sensor reports NaN (``fail_s``); so does a sensor that is not fitted (:class:`Co2Sensor` is then not
built: the measurement is NaN throughout).

Deterministic: the part's errors come from ``numpy.random.default_rng([seed, STREAM])`` and the noise of the
update at t_j from ``default_rng([seed, STREAM, j])``, so the readings depend only on the seed and the time,
never on the call order or the process. Pure numpy; no ROS.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ceco_core.air_quality import check_settings

__all__ = ["Co2SensorParams", "Co2Sensor", "STREAM"]

STREAM = 21
"""Second word of the sensor's random streams (apart from the preview noise's)."""


@dataclasses.dataclass(frozen=True)
class Co2SensorParams:
    """An NDIR cabin CO2 sensor (defaults: the datasheet values of docs/plant.md)."""

    tau_s: float = 60.0
    """Time constant of the reading (63 % of a step) [s]."""
    offset_max_ppm: float = 30.0
    """Largest offset error b [ppm] (drawn uniformly in +-offset_max_ppm once per sensor)."""
    gain_error_max: float = 0.03
    """Largest gain error g [-] (drawn uniformly in +-gain_error_max once per sensor)."""
    noise_std_ppm: float = 10.0
    """Standard deviation of the white noise of each reading [ppm] (repeatability)."""
    update_s: float = 5.0
    """Interval between readings [s] (the value is held between them)."""
    range_max_ppm: float = 10000.0
    """Top of the measuring range [ppm]: a reading above it is reported as NaN (out of range)."""

    def validate(self) -> Co2SensorParams:
        """Raise ValueError naming the field if a parameter is not usable; return self."""
        check_settings(self, positive=("tau_s", "update_s", "range_max_ppm"))
        if self.gain_error_max >= 0.5:
            raise ValueError("Co2SensorParams.gain_error_max: must be < 0.5")
        return self


class Co2Sensor:
    """The reading of one sensor over one run: :meth:`read` at increasing times."""

    def __init__(
        self,
        initial_ppm: float,
        seed: int,
        params: Co2SensorParams | None = None,
        fail_s: float | None = None,
    ) -> None:
        """A sensor that has sat in cabin air of ``initial_ppm`` [ppm]; ``fail_s`` [s]: dead from then on."""
        self.params = (params or Co2SensorParams()).validate()
        if not (math.isfinite(initial_ppm) and initial_ppm >= 0):
            raise ValueError(f"initial_ppm: must be finite and >= 0, got {initial_ppm!r}")
        self.seed = int(seed)
        self.fail_s = None if fail_s is None else float(fail_s)
        rng = np.random.default_rng([self.seed, STREAM])
        p = self.params
        self.gain = float(rng.uniform(-p.gain_error_max, p.gain_error_max))
        """The part's gain error g [-]."""
        self.offset_ppm = float(rng.uniform(-p.offset_max_ppm, p.offset_max_ppm))
        """The part's offset error b [ppm]."""
        self._filtered = float(initial_ppm)
        self._t: float | None = None
        self._update = -1
        self._reading = math.nan

    def read(self, t_s: float, true_ppm: float) -> float:
        """The reading at ``t_s`` [s] (non-decreasing) with the cabin at ``true_ppm`` [ppm]; NaN when dead.

        The lag integrates exactly over the interval since the last call with the truth held at ``true_ppm``
        (the plant's step); a new reading is taken at every update instant passed.
        """
        if self._t is not None:
            dt = t_s - self._t
            if dt < 0:
                raise ValueError(f"t_s: must not decrease (last {self._t}, got {t_s})")
            self._filtered += -math.expm1(-dt / self.params.tau_s) * (float(true_ppm) - self._filtered)
        elif not math.isfinite(true_ppm):
            raise ValueError(f"true_ppm: must be finite, got {true_ppm!r}")
        self._t = float(t_s)
        if self.fail_s is not None and t_s >= self.fail_s:
            return math.nan
        j = int(math.floor(t_s / self.params.update_s + 1e-9))
        if j != self._update:
            self._update = j
            noise = float(np.random.default_rng([self.seed, STREAM, j]).normal(0.0, 1.0))
            y = (1.0 + self.gain) * self._filtered + self.offset_ppm + self.params.noise_std_ppm * noise
            self._reading = float(round(y)) if 0.0 <= y <= self.params.range_max_ppm else math.nan
        return self._reading
