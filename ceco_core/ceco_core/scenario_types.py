"""Scenario data types: drive cycle, weather, occupant, comfort bounds, hot-soak state.

The dataclasses a scenario is made of and the truth it answers (environment,
perfect previews, PMV bounds at any time). Files are read and validated by
``ceco_v2x_preview.scenario`` (``load_scenario``), which re-exports these types.

Time conventions
----------------
* ``t_s`` is the time since the start of the run [s], ``t_s >= 0``.
* Weather and comfort bounds are piecewise linear between their knots and
  hold the first/last knot's value outside the knot range (``numpy.interp``).
* Vehicle speed is the 1 Hz drive-cycle trace interpolated linearly; after the
  end of the cycle it holds the last value.
* Negative times are rejected (ValueError): nothing exists before the run.

Pure Python (numpy); no ROS import.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ceco_core.air_quality import CO2_AMB_PPM_DEFAULT, AirQualityLimits
from ceco_core.contracts import CONTROL_PERIOD_RANGE_S, HORIZON_RANGE, PLANT_STEP_S
from ceco_core.control_grid import floor_steps, whole_steps
from ceco_core.observation_check import OBSERVATION_LIMITS

__all__ = [
    "ScenarioError",
    "yaml_number_hint",
    "RH_RANGE",
    "Environment",
    "WeatherPreview",
    "Occupant",
    "InitialState",
    "ControlDefaults",
    "SunGeometry",
    "AirQuality",
    "CO2_SENSORS",
    "OCCUPANTS_RANGE",
    "DriveCycle",
    "Scenario",
    "check_number",
    "INITIAL_FIELDS",
    "TEMPERATURE_FIELDS",
]

# Accepted ranges for scenario values (inclusive unless noted). Chosen to catch
# typos and unit mix-ups (degF for degC, % for fractions), not to restrict
# physics: the wider climate envelope a vehicle HVAC is tested in.
T_AMB_RANGE_C = (-40.0, 60.0)
"""Ambient air temperature: the range of automotive climate testing."""
SOLAR_RANGE_WM2 = (0.0, 1400.0)
"""Global irradiance: 0 to just above the solar constant (1361 W/m2)."""
T_STATE_RANGE_C = (-40.0, 120.0)
"""Initial plant temperatures: sun-soaked dashboards reach about 100 degC."""
MET_RANGE = (0.0, 4.0)
"""Metabolic rate [met], lower bound exclusive; 4 met is ISO 7730's top."""
CLO_RANGE = (0.0, 2.0)
"""Clothing insulation [clo]; ISO 7730 validity range 0..2 clo."""
PMV_BOUND_RANGE = OBSERVATION_LIMITS.pmv
"""PMV bounds: ISO 7730's scale, -3..+3, the range the controllers take (``ceco_core.observation_check``; a
scenario with bounds of +-5 ran every NMPC step on its fallback law)."""
RH_RANGE = (0.0, 1.0)
"""Relative humidity [-], ambient and initial cabin: above 0 (the lower bound is open: with no vapour at all the dew
point, and with it the fog margin, is minus infinity) up to saturation."""
SPEED_MAX_MPS = 70.0
"""Drive-cycle speed sanity limit (252 km/h)."""
OCCUPANTS_RANGE = (1, 5)
"""Number of people in the car: the driver up to a five-seat car full."""
CO2_AMB_RANGE_PPM = (300.0, 2000.0)
"""Ambient CO2 [ppm]: pre-industrial 280 below, a congested tunnel's few hundred above background."""
CO2_CAB_RANGE_PPM = (300.0, 20000.0)
"""Initial cabin CO2 [ppm]: up to a crowded car left closed (well above any limit)."""
CO2_SENSORS = ("ndir", "none")
"""Cabin CO2 sensor fitted: an NDIR sensor (docs/plant.md: accuracy, lag, noise) or none."""


class ScenarioError(ValueError):
    """An invalid scenario file or drive cycle; the message names the field."""


@dataclasses.dataclass(frozen=True)
class Environment:
    """Boundary conditions of the cabin at one time (or a vector of times).

    Fields are floats from :meth:`Scenario.env_at` with a scalar time, numpy
    arrays of the time array's shape otherwise.
    """

    t_amb_c: Any
    """Ambient (outdoor) air temperature [degC]."""
    solar_wm2: Any
    """Solar irradiance on the vehicle [W/m2], >= 0."""
    speed_mps: Any
    """Vehicle speed [m/s], >= 0."""
    rh: Any
    """Ambient relative humidity [-], fraction 0..1."""


@dataclasses.dataclass(frozen=True, eq=False)
class WeatherPreview:
    """Weather sampled on a uniform grid ``t_s = t0_s + i*step_s``, i = 0..n-1."""

    t_s: np.ndarray
    """Sample times [s]."""
    t_amb_c: np.ndarray
    """Ambient air temperature [degC]."""
    solar_wm2: np.ndarray
    """Solar irradiance [W/m2]."""
    rh: np.ndarray
    """Ambient relative humidity [-], 0..1."""


@dataclasses.dataclass(frozen=True)
class Occupant:
    """The occupant whose comfort is evaluated."""

    met: float = 1.2
    """Metabolic rate [met] (1 met = 58.15 W/m2), 0 < met <= 4."""
    clo: float = 0.5
    """Clothing insulation [clo] (1 clo = 0.155 m2K/W), 0..2."""

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        check_number("occupant.met", self.met, MET_RANGE, low_open=True)
        check_number("occupant.clo", self.clo, CLO_RANGE)


@dataclasses.dataclass(frozen=True)
class InitialState(Mapping):
    """Plant temperatures at ``t_s = 0`` (the end of the hot soak).

    Also a read-only mapping field name -> value (``initial["t_cab_c"]``,
    ``"t_glass_c" in initial``, ``dict(initial)``), so plant code can take it
    or a plain dict alike.

    Defaults when a field is omitted from the file (documented in
    docs/scenarios.md): ``t_int_c``, ``t_shell_c``, ``t_glass_c`` and
    ``t_evap_c`` = ``t_cab_c`` (the interior, the body, the glazing and the
    HVAC module soak with the cabin air); ``rh_cab`` from the ambient vapour
    pressure at ``t_cab_c`` (a closed car keeps the outdoor moisture content).
    """

    t_cab_c: float
    """Cabin air temperature [degC]."""
    t_int_c: float
    """Cabin interior mass (seats, dashboard, trim) temperature [degC]."""
    t_shell_c: float
    """Cabin shell (roof, body panels) temperature [degC]."""
    t_glass_c: float
    """Glazing temperature [degC]."""
    t_evap_c: float
    """Evaporator wall temperature [degC]."""
    rh_cab: float
    """Cabin air relative humidity [-], 0..1."""
    co2_cab_ppm: float = CO2_AMB_PPM_DEFAULT
    """Cabin CO2 [ppm] (the loader's default: the scenario's ambient CO2)."""

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        for name in TEMPERATURE_FIELDS:
            check_number(f"initial.{name}", getattr(self, name), T_STATE_RANGE_C)
        check_number("initial.rh_cab", self.rh_cab, RH_RANGE, low_open=True)
        check_number("initial.co2_cab_ppm", self.co2_cab_ppm, CO2_CAB_RANGE_PPM)

    def __getitem__(self, key: str) -> float:
        if key not in INITIAL_FIELDS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(INITIAL_FIELDS)

    def __len__(self) -> int:
        return len(INITIAL_FIELDS)


TEMPERATURE_FIELDS = ("t_cab_c", "t_int_c", "t_shell_c", "t_glass_c", "t_evap_c")
INITIAL_FIELDS = (*TEMPERATURE_FIELDS, "rh_cab", "co2_cab_ppm")


@dataclasses.dataclass(frozen=True)
class ControlDefaults:
    """Controller timing suggested by the scenario (controllers may override)."""

    control_period_s: float = 5.0
    """Control period Ts [s] (the paper: 5 s), in :data:`~ceco_core.contracts.CONTROL_PERIOD_RANGE_S`."""
    horizon_steps: int = 6
    """Prediction horizon Np [steps] (the paper: 6), in :data:`~ceco_core.contracts.HORIZON_RANGE`."""

    def timing(self, control_period_s: float | None = None, horizon_steps: int | None = None) -> tuple[float, int]:
        """``(Ts [s], Np [steps])`` of a run: each given value where set (not None or 0), else the scenario's."""
        return float(control_period_s or self.control_period_s), int(horizon_steps or self.horizon_steps)

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field.

        The ranges are the nodes' and every verb's flags' (``ceco_core.contracts``): a scenario cannot ask for a
        Ts or an Np that ``ceco run``'s nodes would refuse.
        """
        lo_s, hi_s = CONTROL_PERIOD_RANGE_S
        ts = check_number("control.control_period_s", self.control_period_s, (lo_s, hi_s))
        if whole_steps(ts, PLANT_STEP_S) is None:  # (at least one: the range starts at 0.1 s)
            raise ScenarioError(
                f"control.control_period_s: {ts:g} s is not a whole number of plant steps ({PLANT_STEP_S:g} s, the "
                "simulator's and plant_node's)"
            )
        if isinstance(self.horizon_steps, bool) or not isinstance(self.horizon_steps, (int, np.integer)):
            raise ScenarioError(f"control.horizon_steps: must be an integer, got {self.horizon_steps!r}")
        lo, hi = HORIZON_RANGE
        if not lo <= self.horizon_steps <= hi:
            raise ScenarioError(f"control.horizon_steps: must be in {lo}..{hi}, got {self.horizon_steps}")


@dataclasses.dataclass(frozen=True)
class AirQuality:
    """The air around and inside the car, and the limits a run is scored against (scenario ``air_quality:``)."""

    co2_amb_ppm: float = CO2_AMB_PPM_DEFAULT
    """Ambient CO2 [ppm] (mole fraction in dry air), constant over the run; 300..2000."""
    co2_limit_ppm: float = AirQualityLimits.co2_limit_ppm
    """Largest acceptable cabin CO2 [ppm] (``AirQualityLimits``); 450..10000."""
    fog_margin_min_k: float = AirQualityLimits.fog_margin_min_k
    """Smallest acceptable windshield fog margin [K] (``AirQualityLimits``); 0..10."""
    co2_sensor: str = "ndir"
    """Cabin CO2 sensor of the car: ``ndir`` (fitted) or ``none`` (:data:`CO2_SENSORS`)."""
    co2_sensor_fail_s: float | None = None
    """Time from which the CO2 sensor reports no value (a dead sensor) [s]; None: it never fails."""

    @property
    def limits(self) -> AirQualityLimits:
        """The scored limits."""
        return AirQualityLimits(self.co2_limit_ppm, self.fog_margin_min_k)

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        check_number("air_quality.co2_amb_ppm", self.co2_amb_ppm, CO2_AMB_RANGE_PPM)
        check_number("air_quality.co2_limit_ppm", self.co2_limit_ppm, (450.0, 10000.0))
        check_number("air_quality.fog_margin_min_k", self.fog_margin_min_k, (0.0, 10.0))
        if self.co2_sensor not in CO2_SENSORS:
            raise ScenarioError(f"air_quality.co2_sensor: must be one of {CO2_SENSORS}, got {self.co2_sensor!r}")
        if self.co2_sensor_fail_s is not None:
            check_number("air_quality.co2_sensor_fail_s", self.co2_sensor_fail_s, (0.0, 1.0e6))
        if self.co2_limit_ppm <= self.co2_amb_ppm:
            raise ScenarioError(
                f"air_quality.co2_limit_ppm: {self.co2_limit_ppm} must exceed co2_amb_ppm {self.co2_amb_ppm}"
            )


@dataclasses.dataclass(frozen=True, eq=False)
class DriveCycle:
    """A speed trace: strictly increasing times and non-negative speeds."""

    name: str
    """Bundled name or the CSV path it was read from."""
    time_s: np.ndarray
    """Sample times [s], strictly increasing, starting at 0."""
    speed_mps: np.ndarray
    """Vehicle speed [m/s], >= 0."""

    @property
    def duration_s(self) -> float:
        """Time of the last sample [s]."""
        return float(self.time_s[-1])

    @property
    def run_duration_s(self) -> float:
        """The longest run the cycle gives [s]: :attr:`duration_s` floored to whole plant steps (``PLANT_STEP_S``)."""
        return floor_steps(self.duration_s, PLANT_STEP_S) * PLANT_STEP_S

    @property
    def distance_m(self) -> float:
        """Distance driven [m], trapezoidal integral of the (linear) trace.

        Written out rather than ``np.trapezoid`` so it also runs on numpy 1.26
        (the ROS apt image, docker/).
        """
        v, t = self.speed_mps, self.time_s
        return float(0.5 * np.sum((v[1:] + v[:-1]) * np.diff(t)))


def yaml_number_hint(value) -> str:
    """A hint for a number YAML read as text.

    PyYAML (YAML 1.1) takes an exponent only after a decimal point and with a sign (``1.0e+9``); ``1e9``,
    ``1.0e9`` and ``1e+9`` are strings.
    """
    if isinstance(value, str):
        mantissa, sep, exponent = value.strip().lower().partition("e")
        try:
            float(value)
        except ValueError:
            return ""
        if sep:
            mantissa = mantissa if "." in mantissa else f"{mantissa}.0"
            exponent = exponent if exponent[:1] in "+-" else f"+{exponent}"
            return f" (YAML reads {value} as text: write {mantissa}e{exponent})"
    return ""


def check_number(field: str, value, bounds, low_open: bool = False) -> float:
    """A scenario number checked against its range, as a float.

    Args:
        field: the field's name, used in the error message.
        value: the value read from the scenario (int or float; bool is refused).
        bounds: ``(lo, hi)``, in the field's unit; ``hi`` is inclusive.
        low_open: if True, ``lo`` itself is refused (``lo < value``), else ``lo <= value``.

    Returns:
        ``float(value)``.

    Raises:
        ScenarioError naming ``field``: not a number, not finite, or out of range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ScenarioError(f"{field}: must be a number, got {value!r}{yaml_number_hint(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ScenarioError(f"{field}: must be finite, got {value!r}")
    lo, hi = bounds
    if (x <= lo if low_open else x < lo) or x > hi:
        op = "<" if low_open else "<="
        raise ScenarioError(f"{field}: must satisfy {lo} {op} value <= {hi}, got {x}")
    return x


@dataclasses.dataclass(frozen=True)
class SunGeometry:
    """Where the sun is relative to the car (constant over a run): the SolarCal geometry.

    Defaults (docs/scenarios.md): the sun 60 deg above the horizon, due south,
    and the car heading south, i.e. the sun straight ahead through the
    windshield (SHARP 0): the midday summer sun of an SC03 day, and the
    direction of the overhead lamp bank's beam through the windshield.
    """

    altitude_deg: float = 60.0
    """Solar altitude above the horizon [deg], 0..90."""
    azimuth_deg: float = 180.0
    """Compass bearing of the sun [deg], 0..360 (0 north, 90 east)."""
    heading_deg: float = 180.0
    """Compass bearing of the car's direction of travel [deg], 0..360."""

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        check_number("sun.altitude_deg", self.altitude_deg, (0.0, 90.0))
        check_number("sun.azimuth_deg", self.azimuth_deg, (0.0, 360.0))
        check_number("sun.heading_deg", self.heading_deg, (0.0, 360.0))


@dataclasses.dataclass(frozen=True, eq=False)
class Scenario:
    """A validated scenario. Build with :func:`load_scenario`."""

    name: str
    """Scenario name."""
    description: str
    """Free text."""
    drive_cycle: DriveCycle
    """The speed trace."""
    duration_s: float
    """Run length [s] (defaults to the cycle's)."""
    weather_time_s: np.ndarray
    """Weather knots [s]."""
    weather_t_amb_c: np.ndarray
    """Ambient temperature at the knots [degC]."""
    weather_solar_wm2: np.ndarray
    """Solar irradiance at the knots [W/m2]."""
    weather_rh: np.ndarray
    """Ambient relative humidity at the knots [-]."""
    occupant: Occupant
    """Occupant metabolic rate and clothing."""
    bounds_time_s: np.ndarray
    """Comfort-bound knots [s]."""
    bounds_pmv_lb: np.ndarray
    """Lower PMV bound at the knots [-]."""
    bounds_pmv_ub: np.ndarray
    """Upper PMV bound at the knots [-]."""
    initial: InitialState
    """Plant temperatures at t = 0."""
    control: ControlDefaults = ControlDefaults()
    """Suggested control period and horizon."""
    sun: SunGeometry = SunGeometry()
    """Sun position and car heading (SolarCal geometry of the occupant's solar gain)."""
    occupants: int = 1
    """People in the car, 1..5 (their CO2, moisture and heat scale with the number; the scored occupant is one)."""
    air_quality: AirQuality = AirQuality()
    """Ambient CO2, the CO2 sensor and the air-quality limits."""
    seed: int = 0
    """Seed for everything random in a run (preview noise)."""
    source: str = ""
    """Where the scenario was loaded from (bundled name or file path)."""

    # ------------------------------------------------------------------ truth
    def _check_t(self, t_s):
        if type(t_s) is float:  # the simulator's per-step call: the same checks without numpy's overhead
            if not math.isfinite(t_s):
                raise ValueError("t_s: must be finite")
            if t_s < 0.0:
                raise ValueError(f"t_s: must be >= 0, got min {t_s}")
            return t_s
        t = np.asarray(t_s, dtype=float)
        if not np.isfinite(t).all():  # (the methods, not np.any / np.all: a third of the cost on a preview grid)
            raise ValueError("t_s: must be finite")
        if (t < 0.0).any():
            raise ValueError(f"t_s: must be >= 0, got min {float(np.min(t))}")
        return t

    def _out(self, t_s, arr):
        return float(arr) if np.ndim(t_s) == 0 else arr

    def speed_mps(self, t_s):
        """Vehicle speed [m/s] at ``t_s`` [s] (scalar or array).

        Linear interpolation of the cycle, holding the last value after its end.
        """
        t = self._check_t(t_s)
        v = np.interp(t, self.drive_cycle.time_s, self.drive_cycle.speed_mps)
        return self._out(t_s, v)

    def env_at(self, t_s) -> Environment:
        """The true boundary conditions at ``t_s`` [s].

        A scalar ``t_s`` gives floats, an array gives arrays of the same shape.
        """
        t = self._check_t(t_s)
        wt = self.weather_time_s
        return Environment(
            t_amb_c=self._out(t_s, np.interp(t, wt, self.weather_t_amb_c)),
            solar_wm2=self._out(t_s, np.interp(t, wt, self.weather_solar_wm2)),
            speed_mps=self._out(t_s, np.interp(t, self.drive_cycle.time_s, self.drive_cycle.speed_mps)),
            rh=self._out(t_s, np.interp(t, wt, self.weather_rh)),
        )

    def env_series(self, t_s) -> Environment:
        """Vectorised :meth:`env_at`: always returns arrays (1-D at least)."""
        return self.env_at(np.atleast_1d(np.asarray(t_s, dtype=float)))

    @staticmethod
    def _grid(t0_s: float, step_s: float, n: int) -> np.ndarray:
        if not (math.isfinite(t0_s) and t0_s >= 0.0):
            raise ValueError(f"t0_s: must be finite and >= 0, got {t0_s}")
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise ValueError(f"step_s: must be finite and > 0, got {step_s}")
        if isinstance(n, bool) or int(n) != n or n < 1:
            raise ValueError(f"n: must be an integer >= 1, got {n}")
        return t0_s + step_s * np.arange(int(n), dtype=float)

    def weather_preview(self, t0_s: float, step_s: float, n: int) -> WeatherPreview:
        """True weather at ``t0_s + i*step_s``, i = 0..n-1 (a perfect forecast).

        Noisy, delayed or missing forecasts: :mod:`ceco_v2x_preview.preview`.
        """
        t = self._grid(t0_s, step_s, n)
        env = self.env_at(t)
        return WeatherPreview(t_s=t, t_amb_c=env.t_amb_c, solar_wm2=env.solar_wm2, rh=env.rh)

    def speed_preview(self, t0_s: float, step_s: float, n: int) -> np.ndarray:
        """True vehicle speed [m/s] at ``t0_s + i*step_s``, i = 0..n-1."""
        return self.speed_mps(self._grid(t0_s, step_s, n))

    def pmv_bounds(self, t_s):
        """(lower, upper) PMV bounds at ``t_s`` (scalar -> floats, array -> arrays)."""
        t = self._check_t(t_s)
        lb = np.interp(t, self.bounds_time_s, self.bounds_pmv_lb)
        ub = np.interp(t, self.bounds_time_s, self.bounds_pmv_ub)
        return self._out(t_s, lb), self._out(t_s, ub)

    def time_grid(self, dt_s: float = 1.0) -> np.ndarray:
        """Sample times ``0, dt, 2dt, ... < duration_s`` of a run [s]."""
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s}")
        return dt_s * np.arange(int(math.floor(self.duration_s / dt_s + 1e-9)), dtype=float)
