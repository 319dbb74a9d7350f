"""Scenarios: drive cycle, weather, occupant, comfort bounds and hot-soak state.

A scenario is a YAML file a user can write (format: ``docs/scenarios.md``).
The bundled ones live in ``ceco_v2x_preview/data/scenarios/`` and are found
through :mod:`importlib.resources`, so they load the same from the source tree
and from the colcon install; nothing is read from outside the package at run
time unless the user passes a path.

Time conventions
----------------
* ``t_s`` is the time since the start of the run [s], ``t_s >= 0``.
* Weather and comfort bounds are piecewise linear between their knots and
  hold the first/last knot's value outside the knot range (``numpy.interp``).
* Vehicle speed is the 1 Hz drive-cycle trace interpolated linearly; after the
  end of the cycle it holds the last value (0 m/s for every EPA schedule: the
  vehicle stands still). Previews that reach past the end therefore hold too.
* Negative times are rejected (ValueError): nothing exists before the run.

Pure Python (numpy, pyyaml); no ROS import.
"""

from __future__ import annotations

import dataclasses
import math
import os
from importlib import resources
from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np
import yaml

__all__ = [
    "ScenarioError",
    "Environment",
    "WeatherPreview",
    "Occupant",
    "InitialState",
    "ControlDefaults",
    "DriveCycle",
    "Scenario",
    "load_scenario",
    "list_scenarios",
    "list_drive_cycles",
    "load_drive_cycle",
    "scenario_from_dict",
    "describe",
    "main",
]

_MPH_TO_MPS = 0.44704
"""1 mile/h in m/s (exact). Kept here so this package does not import
ceco_plant_sim (dependencies point the other way); equals
``ceco_plant_sim.units.mph_to_mps(1.0)``."""

# Accepted ranges for scenario values (inclusive unless noted). Chosen to catch
# typos and unit mix-ups (degF for degC, % for fractions), not to restrict
# physics: the wider climate envelope a vehicle HVAC is tested in.
_T_AMB_RANGE_C = (-40.0, 60.0)
"""Ambient air temperature: the range of automotive climate testing."""
_SOLAR_RANGE_WM2 = (0.0, 1400.0)
"""Global irradiance: 0 to just above the solar constant (1361 W/m2)."""
_T_STATE_RANGE_C = (-40.0, 120.0)
"""Initial plant temperatures: sun-soaked dashboards reach about 100 degC."""
_MET_RANGE = (0.0, 4.0)
"""Metabolic rate [met], lower bound exclusive; 4 met is ISO 7730's top."""
_CLO_RANGE = (0.0, 2.0)
"""Clothing insulation [clo]; ISO 7730 validity range 0..2 clo."""
_PMV_BOUND_RANGE = (-10.0, 10.0)
"""PMV bounds: the scale is -3..+3 but a relaxed pull-down bound may exceed it."""
_SPEED_MAX_MPS = 70.0
"""Drive-cycle speed sanity limit (252 km/h)."""


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
        _check_number("occupant.met", self.met, _MET_RANGE, low_open=True)
        _check_number("occupant.clo", self.clo, _CLO_RANGE)


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

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        for name in _TEMPERATURE_FIELDS:
            _check_number(f"initial.{name}", getattr(self, name), _T_STATE_RANGE_C)
        _check_number("initial.rh_cab", self.rh_cab, (0.0, 1.0))

    def __getitem__(self, key: str) -> float:
        if key not in _INITIAL_FIELDS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(_INITIAL_FIELDS)

    def __len__(self) -> int:
        return len(_INITIAL_FIELDS)


_TEMPERATURE_FIELDS = ("t_cab_c", "t_int_c", "t_shell_c", "t_glass_c", "t_evap_c")
_INITIAL_FIELDS = (*_TEMPERATURE_FIELDS, "rh_cab")


@dataclasses.dataclass(frozen=True)
class ControlDefaults:
    """Controller timing suggested by the scenario (controllers may override)."""

    control_period_s: float = 5.0
    """Control period Ts [s] (the paper: 5 s), > 0."""
    horizon_steps: int = 6
    """Prediction horizon Np [steps] (the paper: 6), >= 1."""

    def validate(self) -> None:
        """Raise ScenarioError naming the first bad field."""
        _check_number("control.control_period_s", self.control_period_s, (0.0, 3600.0), low_open=True)
        if isinstance(self.horizon_steps, bool) or not isinstance(self.horizon_steps, (int, np.integer)):
            raise ScenarioError(f"control.horizon_steps: must be an integer, got {self.horizon_steps!r}")
        if not 1 <= self.horizon_steps <= 1000:
            raise ScenarioError(f"control.horizon_steps: must be in 1..1000, got {self.horizon_steps}")


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
    def distance_m(self) -> float:
        """Distance driven [m], trapezoidal integral of the (linear) trace.

        Written out rather than ``np.trapezoid`` so it also runs on numpy 1.26
        (the ROS apt image, docker/)."""
        v, t = self.speed_mps, self.time_s
        return float(0.5 * np.sum((v[1:] + v[:-1]) * np.diff(t)))


def _data_dir(kind: str):
    return resources.files("ceco_v2x_preview").joinpath("data", kind)


def list_drive_cycles() -> list[str]:
    """Names of the bundled drive cycles (``sc03``, ``udds``, ...), sorted."""
    return sorted(p.name[:-4] for p in _data_dir("drive_cycles").iterdir() if p.name.endswith(".csv"))


def list_scenarios() -> list[str]:
    """Names of the bundled scenarios, sorted."""
    return sorted(p.name[:-5] for p in _data_dir("scenarios").iterdir() if p.name.endswith(".yaml"))


def _read_text(path_or_resource) -> str:
    with path_or_resource.open("r", encoding="utf-8") as fh:
        return fh.read()


def _parse_cycle_csv(text: str, name: str) -> DriveCycle:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ScenarioError(f"drive_cycle: {name}: empty file")
    header = [h.strip() for h in lines[0].split(",")]
    if len(header) != 2 or header[0] != "time_s" or header[1] not in ("speed_mph", "speed_mps"):
        raise ScenarioError(
            f"drive_cycle: {name}: header must be 'time_s,speed_mph' or 'time_s,speed_mps', got {lines[0]!r}"
        )
    rows = []
    for i, ln in enumerate(lines[1:], start=2):
        parts = ln.split(",")
        if len(parts) != 2:
            raise ScenarioError(f"drive_cycle: {name}: line {i}: expected 2 columns, got {ln!r}")
        try:
            rows.append((float(parts[0]), float(parts[1])))
        except ValueError:
            raise ScenarioError(f"drive_cycle: {name}: line {i}: not a number: {ln!r}") from None
    if len(rows) < 2:
        raise ScenarioError(f"drive_cycle: {name}: needs at least 2 samples, got {len(rows)}")
    data = np.asarray(rows, dtype=float)
    time_s, speed = data[:, 0], data[:, 1]
    if not np.all(np.isfinite(data)):
        raise ScenarioError(f"drive_cycle: {name}: NaN or infinite value")
    if time_s[0] != 0.0:
        raise ScenarioError(f"drive_cycle: {name}: time_s must start at 0, got {time_s[0]}")
    if np.any(np.diff(time_s) <= 0.0):
        raise ScenarioError(f"drive_cycle: {name}: time_s must be strictly increasing")
    speed_mps = speed * _MPH_TO_MPS if header[1] == "speed_mph" else speed
    if np.any(speed_mps < 0.0) or np.any(speed_mps > _SPEED_MAX_MPS):
        raise ScenarioError(f"drive_cycle: {name}: {header[1]} must be within 0..{_SPEED_MAX_MPS} m/s")
    time_s.setflags(write=False)
    speed_mps.setflags(write=False)
    return DriveCycle(name=name, time_s=time_s, speed_mps=speed_mps)


def load_drive_cycle(name_or_path: str | os.PathLike, base_dir: str | os.PathLike | None = None) -> DriveCycle:
    """Load a bundled drive cycle by name or a CSV file by path.

    A path that is relative is resolved against ``base_dir`` (the scenario
    file's directory) when given. Raises ScenarioError for an unknown name or
    a malformed file.
    """
    text_name = str(name_or_path)
    if text_name in list_drive_cycles():
        return _parse_cycle_csv(_read_text(_data_dir("drive_cycles").joinpath(text_name + ".csv")), text_name)
    path = Path(text_name).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if not (text_name.endswith(".csv") and path.is_file()):
        raise ScenarioError(
            f"drive_cycle: unknown drive cycle {text_name!r}: use one of {list_drive_cycles()} or a CSV path"
        )
    return _parse_cycle_csv(path.read_text(encoding="utf-8"), str(path))


def _check_number(field: str, value, bounds, low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ScenarioError(f"{field}: must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ScenarioError(f"{field}: must be finite, got {value!r}")
    lo, hi = bounds
    if (x <= lo if low_open else x < lo) or x > hi:
        op = "<" if low_open else "<="
        raise ScenarioError(f"{field}: must satisfy {lo} {op} value <= {hi}, got {x}")
    return x


def _series(section: str, block: Mapping, key: str, n: int | None, bounds) -> np.ndarray:
    field = f"{section}.{key}"
    if key not in block:
        raise ScenarioError(f"{field}: missing")
    raw = block[key]
    if isinstance(raw, (int, float)) and not isinstance(raw, bool) and n is not None:
        raw = [raw] * n  # a constant written as one number
    if not isinstance(raw, (list, tuple)):
        raise ScenarioError(f"{field}: must be a list of numbers (or one number), got {raw!r}")
    vals = [_check_number(f"{field}[{i}]", v, bounds) for i, v in enumerate(raw)]
    if n is not None and len(vals) != n:
        raise ScenarioError(f"{field}: length {len(vals)} differs from {section}.time_s length {n}")
    arr = np.asarray(vals, dtype=float)
    arr.setflags(write=False)
    return arr


def _time_grid(section: str, block: Mapping) -> np.ndarray:
    t = _series(section, block, "time_s", None, (0.0, 1.0e6))
    if t.size < 1:
        raise ScenarioError(f"{section}.time_s: needs at least one knot")
    if t[0] != 0.0:
        raise ScenarioError(f"{section}.time_s: must start at 0, got {t[0]}")
    if np.any(np.diff(t) <= 0.0):
        raise ScenarioError(f"{section}.time_s: must be strictly increasing")
    return t


def _section(data: Mapping, key: str, required: bool = True) -> Mapping:
    if key not in data or data[key] is None:
        if required:
            raise ScenarioError(f"{key}: missing")
        return {}
    block = data[key]
    if not isinstance(block, Mapping):
        raise ScenarioError(f"{key}: must be a mapping, got {type(block).__name__}")
    return block


def _reject_unknown(section: str, block: Mapping, allowed) -> None:
    extra = sorted(set(block) - set(allowed))
    if extra:
        raise ScenarioError(f"{section}.{extra[0]}: unknown field (allowed: {sorted(allowed)})")


def _saturation_pressure_pa(t_c: float) -> float:
    """Water saturation pressure [Pa], Magnus form (Alduchov & Eskridge 1996),
    within 0.4 % of IAPWS over -40..60 degC; used only for the rh_cab default."""
    return 610.94 * math.exp(17.625 * t_c / (t_c + 243.04))


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
    seed: int = 0
    """Seed for everything random in a run (preview noise)."""
    source: str = ""
    """Where the scenario was loaded from (bundled name or file path)."""

    # ------------------------------------------------------------------ truth
    def _check_t(self, t_s):
        t = np.asarray(t_s, dtype=float)
        if np.any(~np.isfinite(t)):
            raise ValueError("t_s: must be finite")
        if np.any(t < 0.0):
            raise ValueError(f"t_s: must be >= 0, got min {float(np.min(t))}")
        return t

    def _out(self, t_s, arr):
        return float(arr) if np.ndim(t_s) == 0 else arr

    def speed_mps(self, t_s):
        """Vehicle speed [m/s] at ``t_s`` (scalar or array): linear
        interpolation of the cycle, holding the last value after its end."""
        t = self._check_t(t_s)
        v = np.interp(t, self.drive_cycle.time_s, self.drive_cycle.speed_mps)
        return self._out(t_s, v)

    def env_at(self, t_s) -> Environment:
        """The true boundary conditions at ``t_s`` [s] (scalar -> floats,
        array -> arrays of the same shape)."""
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


def scenario_from_dict(data: Mapping, *, source: str = "", base_dir: str | os.PathLike | None = None) -> Scenario:
    """Validate a parsed scenario mapping and build a :class:`Scenario`.

    Raises ScenarioError (a ValueError) whose message starts with the
    offending field, e.g. ``weather.rh[2]: must satisfy 0.0 <= value <= 1.0``.
    """
    if not isinstance(data, Mapping):
        raise ScenarioError(f"scenario: top level must be a mapping, got {type(data).__name__}")
    allowed = {"name", "description", "drive_cycle", "duration_s", "weather", "occupant",
               "comfort_bounds", "initial", "control", "seed"}
    _reject_unknown("scenario", data, allowed)
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ScenarioError("name: missing or not a non-empty string")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ScenarioError("description: must be a string")
    if "drive_cycle" not in data or not isinstance(data["drive_cycle"], str):
        raise ScenarioError("drive_cycle: missing or not a string (bundled name or CSV path)")
    cycle = load_drive_cycle(data["drive_cycle"], base_dir=base_dir)

    duration_s = cycle.duration_s
    if data.get("duration_s") is not None:
        duration_s = _check_number("duration_s", data["duration_s"], (0.0, 1.0e6), low_open=True)

    weather = _section(data, "weather")
    _reject_unknown("weather", weather, {"time_s", "t_amb_c", "solar_wm2", "rh"})
    wt = _time_grid("weather", weather)
    t_amb = _series("weather", weather, "t_amb_c", wt.size, _T_AMB_RANGE_C)
    solar = _series("weather", weather, "solar_wm2", wt.size, _SOLAR_RANGE_WM2)
    rh = _series("weather", weather, "rh", wt.size, (0.0, 1.0))

    occ_block = _section(data, "occupant")
    _reject_unknown("occupant", occ_block, {"met", "clo"})
    for key in ("met", "clo"):
        if key not in occ_block:
            raise ScenarioError(f"occupant.{key}: missing")
    occupant = Occupant(met=occ_block["met"], clo=occ_block["clo"])
    occupant.validate()
    occupant = Occupant(met=float(occupant.met), clo=float(occupant.clo))

    cb = _section(data, "comfort_bounds")
    _reject_unknown("comfort_bounds", cb, {"time_s", "pmv_lb", "pmv_ub"})
    bt = _time_grid("comfort_bounds", cb)
    lb = _series("comfort_bounds", cb, "pmv_lb", bt.size, _PMV_BOUND_RANGE)
    ub = _series("comfort_bounds", cb, "pmv_ub", bt.size, _PMV_BOUND_RANGE)
    bad = np.flatnonzero(lb > ub)
    if bad.size:
        i = int(bad[0])
        raise ScenarioError(f"comfort_bounds.pmv_lb[{i}]: {lb[i]} exceeds pmv_ub[{i}] = {ub[i]}")

    ini = _section(data, "initial")
    _reject_unknown("initial", ini, set(_INITIAL_FIELDS))
    if "t_cab_c" not in ini:
        raise ScenarioError("initial.t_cab_c: missing")
    t_cab = _check_number("initial.t_cab_c", ini["t_cab_c"], _T_STATE_RANGE_C)
    if "rh_cab" in ini:
        rh_cab = ini["rh_cab"]
    else:  # same vapour pressure as the ambient air at t = 0
        p_v_pa = float(rh[0]) * _saturation_pressure_pa(float(t_amb[0]))
        # A cabin colder than the ambient dew point is saturated (the excess
        # moisture has condensed): rh_cab = 1, a physical limit.
        rh_cab = min(1.0, p_v_pa / _saturation_pressure_pa(t_cab))
    initial = InitialState(
        t_cab_c=t_cab,
        t_int_c=ini.get("t_int_c", t_cab),
        t_shell_c=ini.get("t_shell_c", t_cab),
        t_glass_c=ini.get("t_glass_c", t_cab),
        t_evap_c=ini.get("t_evap_c", t_cab),
        rh_cab=rh_cab,
    )
    initial.validate()
    initial = InitialState(**{name: float(initial[name]) for name in _INITIAL_FIELDS})

    ctl = _section(data, "control", required=False)
    _reject_unknown("control", ctl, {"control_period_s", "horizon_steps"})
    control = ControlDefaults(
        control_period_s=ctl.get("control_period_s", ControlDefaults.control_period_s),
        horizon_steps=ctl.get("horizon_steps", ControlDefaults.horizon_steps),
    )
    control.validate()
    control = ControlDefaults(float(control.control_period_s), int(control.horizon_steps))

    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"seed: must be a non-negative integer, got {seed!r}")

    return Scenario(
        name=name.strip(), description=description.strip(), drive_cycle=cycle, duration_s=float(duration_s),
        weather_time_s=wt, weather_t_amb_c=t_amb, weather_solar_wm2=solar, weather_rh=rh,
        occupant=occupant, bounds_time_s=bt, bounds_pmv_lb=lb, bounds_pmv_ub=ub,
        initial=initial, control=control, seed=int(seed), source=source,
    )


def load_scenario(name_or_path: str | os.PathLike) -> Scenario:
    """Load a bundled scenario by name (``sc03``, see :func:`list_scenarios`)
    or a YAML file by path. Raises ScenarioError naming the bad field."""
    text_name = str(name_or_path)
    if text_name in list_scenarios():
        text = _read_text(_data_dir("scenarios").joinpath(text_name + ".yaml"))
        source, base_dir = text_name, None
    else:
        path = Path(text_name).expanduser()
        if not path.is_file():
            raise ScenarioError(f"scenario: unknown scenario {text_name!r}: use one of {list_scenarios()} or a YAML path")
        text = path.read_text(encoding="utf-8")
        source, base_dir = str(path), path.parent
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ScenarioError(f"scenario: {source}: not valid YAML: {exc}") from None
    return scenario_from_dict(data, source=source, base_dir=base_dir)


def describe(scenario: Scenario) -> str:
    """A short human-readable summary of a scenario (used by the CLI)."""
    sc = scenario
    env0, env1 = sc.env_at(0.0), sc.env_at(sc.duration_s)
    lb0, ub0 = sc.pmv_bounds(0.0)
    lb1, ub1 = sc.pmv_bounds(sc.duration_s)
    ini = ", ".join(f"{k}={v:.3g}" for k, v in sc.initial.items())
    return "\n".join([
        f"scenario {sc.name} ({sc.source})",
        f"  drive cycle {sc.drive_cycle.name}: {sc.drive_cycle.duration_s:.0f} s, "
        f"{sc.drive_cycle.distance_m / 1000.0:.2f} km, max {float(np.max(sc.drive_cycle.speed_mps)):.1f} m/s; "
        f"run {sc.duration_s:.0f} s",
        f"  ambient {env0.t_amb_c:.1f} -> {env1.t_amb_c:.1f} degC, solar {env0.solar_wm2:.0f} -> "
        f"{env1.solar_wm2:.0f} W/m2, rh {env0.rh:.2f} -> {env1.rh:.2f}",
        f"  occupant met={sc.occupant.met:g} clo={sc.occupant.clo:g}; PMV bounds "
        f"[{lb0:g}, {ub0:g}] at 0 s -> [{lb1:g}, {ub1:g}] at the end",
        f"  initial {ini}",
        f"  control Ts={sc.control.control_period_s:g} s Np={sc.control.horizon_steps}; seed {sc.seed}",
    ])


def main(argv=None) -> int:
    """``python -m ceco_v2x_preview.scenario [NAME_OR_PATH ...]``: validate and
    summarise scenarios (all bundled ones without arguments). Exit status 1
    and the field-naming message on the first invalid one."""
    import argparse  # noqa: PLC0415
    import sys  # noqa: PLC0415

    parser = argparse.ArgumentParser(prog="python -m ceco_v2x_preview.scenario",
                                     description="Validate and summarise ceco scenario files.")
    parser.add_argument("scenarios", nargs="*", help="bundled names or YAML paths (default: all bundled)")
    args = parser.parse_args(argv)
    status = 0
    for name in args.scenarios or list_scenarios():
        try:
            print(describe(load_scenario(name)))
        except ScenarioError as exc:
            print(f"{name}: invalid: {exc}", file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    raise SystemExit(main())
