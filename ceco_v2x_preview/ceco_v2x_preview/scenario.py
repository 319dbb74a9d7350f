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
import os
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ceco_core import psychro, units, yamlio
from ceco_core.contracts import PLANT_STEP_S
from ceco_core.control_grid import floor_steps, whole_steps
from ceco_core.scenario_types import (
    INITIAL_FIELDS,
    OCCUPANTS_RANGE,
    PMV_BOUND_RANGE,
    RH_RANGE,
    SOLAR_RANGE_WM2,
    SPEED_MAX_MPS,
    T_AMB_RANGE_C,
    T_STATE_RANGE_C,
    AirQuality,
    ControlDefaults,
    DriveCycle,
    Environment,
    InitialState,
    Occupant,
    Scenario,
    ScenarioError,
    SunGeometry,
    WeatherPreview,
    check_number,
    yaml_number_hint,
)

__all__ = [
    "ScenarioError",
    "Environment",
    "WeatherPreview",
    "Occupant",
    "InitialState",
    "ControlDefaults",
    "SunGeometry",
    "AirQuality",
    "DriveCycle",
    "Scenario",
    "load_scenario",
    "load_scenario_param",
    "list_scenarios",
    "list_drive_cycles",
    "load_drive_cycle",
    "scenario_from_dict",
    "describe",
    "main",
]


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
    mph = header[1] == "speed_mph"
    speed_mps = units.mph_to_mps(speed) if mph else speed
    if np.any(speed_mps < 0.0) or np.any(speed_mps > SPEED_MAX_MPS):
        limit = f"{SPEED_MAX_MPS / units.mph_to_mps(1.0):.1f} mph" if mph else f"{SPEED_MAX_MPS:g} m/s"
        raise ScenarioError(f"drive_cycle: {name}: {header[1]} must be within 0..{limit} ({SPEED_MAX_MPS:g} m/s)")
    time_s.setflags(write=False)
    speed_mps.setflags(write=False)
    return DriveCycle(name=name, time_s=time_s, speed_mps=speed_mps)


def load_drive_cycle(name_or_path: str | os.PathLike, base_dir: str | os.PathLike | None = None) -> DriveCycle:
    """Load a bundled drive cycle by name or a CSV file by path.

    A path that is relative is resolved against ``base_dir`` (the scenario
    file's directory) when given. Raises ScenarioError for an unknown name or
    a malformed file, and for a CSV path (a name ending in ``.csv``) where no file is (naming the path looked at).
    """
    text_name = str(name_or_path)
    if text_name in list_drive_cycles():
        return _parse_cycle_csv(_read_text(_data_dir("drive_cycles").joinpath(text_name + ".csv")), text_name)
    path = Path(text_name).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if not text_name.endswith(".csv"):
        raise ScenarioError(
            f"drive_cycle: unknown drive cycle {text_name!r}: use one of {list_drive_cycles()} or a CSV path"
        )
    if not path.is_file():
        why = "is a directory, not a file" if path.is_dir() else "not found"
        raise ScenarioError(f"drive_cycle: CSV file {text_name!r} {why} (looked for {path.absolute()})")
    try:  # utf-8-sig: a spreadsheet's CSV often starts with a byte-order mark (it was refused as a bad header)
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"drive_cycle: {path}: not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    return _parse_cycle_csv(text, str(path))


def _series(section: str, block: Mapping, key: str, n: int | None, bounds, low_open: bool = False) -> np.ndarray:
    field = f"{section}.{key}"
    if key not in block:
        raise ScenarioError(f"{field}: missing")
    raw = block[key]
    if isinstance(raw, (int, float)) and not isinstance(raw, bool) and n is not None:
        raw = [raw] * n  # a constant written as one number
    if not isinstance(raw, (list, tuple)):
        what = "a list of numbers" if n is None else "a list of numbers (or one number)"  # a time grid: a list
        raise ScenarioError(f"{field}: must be {what}, got {raw!r}{yaml_number_hint(raw)}")
    vals = [check_number(f"{field}[{i}]", v, bounds, low_open) for i, v in enumerate(raw)]
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


def scenario_from_dict(data: Mapping, *, source: str = "", base_dir: str | os.PathLike | None = None) -> Scenario:
    """Validate a parsed scenario mapping and build a :class:`Scenario`.

    Raises ScenarioError (a ValueError) whose message starts with the
    offending field, e.g. ``weather.rh[2]: must satisfy 0.0 <= value <= 1.0``.
    """
    if not isinstance(data, Mapping):
        raise ScenarioError(f"scenario: top level must be a mapping, got {type(data).__name__}")
    allowed = {
        "name",
        "description",
        "drive_cycle",
        "duration_s",
        "weather",
        "occupant",
        "comfort_bounds",
        "initial",
        "control",
        "sun",
        "occupants",
        "air_quality",
        "seed",
    }
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

    # a run is a whole number of plant steps: the cycle's length is floored to one, a duration_s must be one
    duration_s = cycle.run_duration_s
    if data.get("duration_s") is not None:
        duration_s = check_number("duration_s", data["duration_s"], (0.0, 1.0e6), low_open=True)
        n = whole_steps(duration_s, PLANT_STEP_S)
        if n is None or n < 2:
            raise ScenarioError(
                f"duration_s: {duration_s:g} s is not a whole number (>= 2) of plant steps ({PLANT_STEP_S:g} s): "
                f"give e.g. {max(floor_steps(duration_s, PLANT_STEP_S), 2) * PLANT_STEP_S:g}"
            )

    weather = _section(data, "weather")
    _reject_unknown("weather", weather, {"time_s", "t_amb_c", "solar_wm2", "rh"})
    wt = _time_grid("weather", weather)
    t_amb = _series("weather", weather, "t_amb_c", wt.size, T_AMB_RANGE_C)
    solar = _series("weather", weather, "solar_wm2", wt.size, SOLAR_RANGE_WM2)
    rh = _series("weather", weather, "rh", wt.size, RH_RANGE, low_open=True)

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
    lb = _series("comfort_bounds", cb, "pmv_lb", bt.size, PMV_BOUND_RANGE)
    ub = _series("comfort_bounds", cb, "pmv_ub", bt.size, PMV_BOUND_RANGE)
    bad = np.flatnonzero(lb > ub)
    if bad.size:
        i = int(bad[0])
        raise ScenarioError(f"comfort_bounds.pmv_lb[{i}]: {lb[i]} exceeds pmv_ub[{i}] = {ub[i]}")

    occupants = data.get("occupants", 1)
    if isinstance(occupants, bool) or not isinstance(occupants, (int, np.integer)):
        raise ScenarioError(f"occupants: must be an integer, got {occupants!r}")
    if not OCCUPANTS_RANGE[0] <= occupants <= OCCUPANTS_RANGE[1]:
        raise ScenarioError(f"occupants: must be in {OCCUPANTS_RANGE[0]}..{OCCUPANTS_RANGE[1]}, got {occupants}")

    aq_block = _section(data, "air_quality", required=False)
    aq_fields = {f.name for f in dataclasses.fields(AirQuality)}
    _reject_unknown("air_quality", aq_block, aq_fields)
    air_quality = AirQuality(**{k: aq_block[k] for k in aq_fields if k in aq_block and aq_block[k] is not None})
    air_quality.validate()
    air_quality = dataclasses.replace(
        air_quality,
        co2_amb_ppm=float(air_quality.co2_amb_ppm),
        co2_limit_ppm=float(air_quality.co2_limit_ppm),
        fog_margin_min_k=float(air_quality.fog_margin_min_k),
        co2_sensor_fail_s=None if air_quality.co2_sensor_fail_s is None else float(air_quality.co2_sensor_fail_s),
    )

    ini = _section(data, "initial")
    _reject_unknown("initial", ini, set(INITIAL_FIELDS))
    if "t_cab_c" not in ini:
        raise ScenarioError("initial.t_cab_c: missing")
    t_cab = check_number("initial.t_cab_c", ini["t_cab_c"], T_STATE_RANGE_C)
    if "rh_cab" in ini:
        rh_cab = ini["rh_cab"]
    else:  # same vapour pressure as the ambient air at t = 0
        p_v_pa = float(rh[0]) * psychro.saturation_vapour_pressure_pa(float(t_amb[0]))
        # A cabin colder than the ambient dew point is saturated (the excess
        # moisture has condensed): rh_cab = 1, a physical limit.
        rh_cab = min(1.0, p_v_pa / psychro.saturation_vapour_pressure_pa(t_cab))
    initial = InitialState(
        t_cab_c=t_cab,
        t_int_c=ini.get("t_int_c", t_cab),
        t_shell_c=ini.get("t_shell_c", t_cab),
        t_glass_c=ini.get("t_glass_c", t_cab),
        t_evap_c=ini.get("t_evap_c", t_cab),
        rh_cab=rh_cab,
        co2_cab_ppm=ini.get("co2_cab_ppm", air_quality.co2_amb_ppm),
    )
    initial.validate()
    initial = InitialState(**{name: float(initial[name]) for name in INITIAL_FIELDS})

    ctl = _section(data, "control", required=False)
    _reject_unknown("control", ctl, {"control_period_s", "horizon_steps"})
    control = ControlDefaults(
        control_period_s=ctl.get("control_period_s", ControlDefaults.control_period_s),
        horizon_steps=ctl.get("horizon_steps", ControlDefaults.horizon_steps),
    )
    control.validate()
    control = ControlDefaults(float(control.control_period_s), int(control.horizon_steps))

    sun_block = _section(data, "sun", required=False)
    _reject_unknown("sun", sun_block, {"altitude_deg", "azimuth_deg", "heading_deg"})
    sun = SunGeometry(
        **{k: sun_block.get(k, getattr(SunGeometry, k)) for k in ("altitude_deg", "azimuth_deg", "heading_deg")}
    )
    sun.validate()
    sun = SunGeometry(float(sun.altitude_deg), float(sun.azimuth_deg), float(sun.heading_deg))

    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"seed: must be a non-negative integer, got {seed!r}")

    return Scenario(
        name=name.strip(),
        description=description.strip(),
        drive_cycle=cycle,
        duration_s=float(duration_s),
        weather_time_s=wt,
        weather_t_amb_c=t_amb,
        weather_solar_wm2=solar,
        weather_rh=rh,
        occupant=occupant,
        bounds_time_s=bt,
        bounds_pmv_lb=lb,
        bounds_pmv_ub=ub,
        initial=initial,
        control=control,
        sun=sun,
        occupants=int(occupants),
        air_quality=air_quality,
        seed=int(seed),
        source=source,
    )


def load_scenario(name_or_path: str | os.PathLike) -> Scenario:
    """Load a bundled scenario by name (``sc03``, see :func:`list_scenarios`) or a YAML file by path.

    Raises ScenarioError naming the bad field.
    """
    text_name = str(name_or_path)
    if text_name in list_scenarios():
        data = yamlio.safe_load(_read_text(_data_dir("scenarios").joinpath(text_name + ".yaml")))
        return scenario_from_dict(data, source=text_name, base_dir=None)
    else:
        path = Path(text_name).expanduser()
        if not path.is_file():
            if text_name.endswith((".yaml", ".yml")) or os.sep in text_name:  # meant as a file
                why = "is a directory" if path.is_dir() else "no such file"
                raise ScenarioError(f"scenario: {text_name}: {why}: give a scenario YAML file or a bundled name")
            raise ScenarioError(
                f"scenario: unknown scenario {text_name!r}: use one of {list_scenarios()} or a YAML path"
            )
        try:  # (not YAML, not UTF-8 text: one line naming the file)
            doc: Any = yamlio.load_file(path)  # (checked by scenario_from_dict)
        except ValueError as exc:
            raise ScenarioError(f"scenario: {exc}") from None
        return scenario_from_dict(doc, source=str(path), base_dir=path.parent)


def load_scenario_param(name: str, parameter: str = "scenario") -> Scenario:
    """:func:`load_scenario` for a node parameter: ValueError naming the parameter and the reason."""
    try:
        return load_scenario(name)
    except (ValueError, OSError) as err:
        raise ValueError(f"invalid parameter {parameter}={name!r}: {err}") from None


def describe(scenario: Scenario) -> str:
    """A short human-readable summary of a scenario (used by the CLI)."""
    sc = scenario
    env0, env1 = sc.env_at(0.0), sc.env_at(sc.duration_s)
    lb0, ub0 = sc.pmv_bounds(0.0)
    lb1, ub1 = sc.pmv_bounds(sc.duration_s)
    ini = ", ".join(f"{k}={v:.3g}" for k, v in sc.initial.items())
    return "\n".join(
        [
            f"scenario {sc.name} ({sc.source})",
            f"  drive cycle {sc.drive_cycle.name}: {sc.drive_cycle.duration_s:.0f} s, "
            f"{sc.drive_cycle.distance_m / 1000.0:.2f} km, max {float(np.max(sc.drive_cycle.speed_mps)):.1f} m/s; "
            f"run {sc.duration_s:.0f} s",
            f"  ambient {env0.t_amb_c:.1f} -> {env1.t_amb_c:.1f} degC, solar {env0.solar_wm2:.0f} -> "
            f"{env1.solar_wm2:.0f} W/m2, rh {env0.rh:.2f} -> {env1.rh:.2f}",
            f"  occupant met={sc.occupant.met:g} clo={sc.occupant.clo:g}; PMV bounds "
            f"[{lb0:g}, {ub0:g}] at 0 s -> [{lb1:g}, {ub1:g}] at the end",
            f"  initial {ini}",
            f"  sun altitude {sc.sun.altitude_deg:g} deg, azimuth {sc.sun.azimuth_deg:g} deg; heading "
            f"{sc.sun.heading_deg:g} deg",
            f"  occupants {sc.occupants}; ambient CO2 {sc.air_quality.co2_amb_ppm:g} ppm, limits CO2 "
            f"{sc.air_quality.co2_limit_ppm:g} ppm, fog margin {sc.air_quality.fog_margin_min_k:g} K; CO2 sensor "
            f"{sc.air_quality.co2_sensor}"
            + (
                ""
                if sc.air_quality.co2_sensor_fail_s is None
                else f" (fails at {sc.air_quality.co2_sensor_fail_s:g} s)"
            ),
            f"  control Ts={sc.control.control_period_s:g} s Np={sc.control.horizon_steps}; seed {sc.seed}",
        ]
    )


def main(argv=None) -> int:
    """``python -m ceco_v2x_preview.scenario [NAME_OR_PATH ...]``: validate and summarise scenarios.

    Without arguments, all bundled ones. Exit status 1 and the field-naming
    message on the first invalid one.
    """
    import argparse
    import sys

    parser = argparse.ArgumentParser(
        prog="python -m ceco_v2x_preview.scenario", description="Validate and summarise ceco scenario files."
    )
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
