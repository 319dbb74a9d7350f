"""Identification data: excitation drives of the plant recorded at 1 s, and their CSV files.

The plant (``ceco_plant_sim``) is driven through soak and pre-cooled starts with random
held inputs (:class:`ExcitationSettings`, :func:`generate_excitation`); the series are
stored as CSV (:data:`SERIES_COLUMNS`, ``data/identification/``) so a fit can be repeated
without the plant. The least-squares fit is :mod:`ceco_controller.identification`.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import math
import pathlib
from typing import Any

import numpy as np

__all__ = [
    "SERIES_COLUMNS",
    "PACKAGE_DIR",
    "DEFAULT_DATA_DIR",
    "TRAIN_DRIVES",
    "VALIDATION_DRIVES",
    "ExcitationSettings",
    "generate_excitation",
    "CO2_SERIES_COLUMNS",
    "CO2_TRAIN_DRIVE",
    "CO2_VALIDATION_DRIVE",
    "generate_co2_excitation",
    "read_series_csv",
    "write_series_csv",
]


SERIES_COLUMNS = (
    "segment",
    "t_s",
    "t_cab_c",
    "t_int_c",
    "t_shell_c",
    "t_evap_c",
    "t_vent_c",
    "t_amb_c",
    "solar_wm2",
    "speed_mps",
    "mdot_bl_kgps",
    "t_evap_sp_c",
    "p_comp_w",
    "p_blower_w",
)
"""Columns the fit needs (a subset of the run directory's timeseries.csv, plus ``segment``)."""

PACKAGE_DIR = pathlib.Path(__file__).resolve().parent.parent
DEFAULT_DATA_DIR = PACKAGE_DIR / "ceco_controller" / "data" / "identification"
TRAIN_DRIVES = (
    ("sc03", "soak"),
    ("udds", "soak"),
    ("hwfet", "soak"),
    ("sc03_mild", "soak"),
    ("sc03", "precooled"),
    ("hwfet", "precooled"),
)
"""(scenario, initial condition) of the training drives."""
VALIDATION_DRIVES = (("us06", "soak"), ("us06", "precooled"))
"""Validation drives (never used for fitting)."""
CO2_SERIES_COLUMNS = (
    "t_s",
    "co2_cab_ppm",
    "recirc_share",
    "mdot_bl_kgps",
    "speed_mps",
    "w_cab_kgkg",
    "t_evap_c",
    "t_amb_c",
    "rh_amb",
)
"""Columns of the air-quality fits (:func:`ceco_controller.identification.fit_co2_balance`,
:func:`~ceco_controller.identification.fit_moisture_balance`): time [s], cabin CO2 [ppm], the door's actual
recirculated share [-], blower flow [kg/s], vehicle speed [m/s], cabin humidity ratio [kg/kg], evaporator wall
temperature [degC], ambient temperature [degC] and relative humidity [-]."""
CO2_TRAIN_DRIVE = ("udds", 4)
"""(scenario, occupants) of the CO2 balance's training drive (1369 s, speeds 0-25 m/s)."""
CO2_VALIDATION_DRIVE = ("hwfet", 2)
"""(scenario, occupants) of its validation drive (765 s, never used for fitting)."""


@dataclasses.dataclass(frozen=True)
class ExcitationSettings:
    """Input excitation used to generate identification data."""

    seed: int = 1
    """Seed of the random input levels and hold times."""
    hold_min_s: float = 15.0
    """Shortest hold of a level [s]."""
    hold_max_s: float = 120.0
    """Longest hold of a level [s]."""
    ts_s: float = 5.0
    """Model step; holds are whole multiples of it [s]."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if not 0 < self.hold_min_s <= self.hold_max_s:
            raise ValueError("ExcitationSettings.hold_min_s must satisfy 0 < min <= hold_max_s")
        if not self.ts_s > 0:
            raise ValueError("ExcitationSettings.ts_s must be > 0")


_PRECOOLED = {"t_cab_c": 27.0, "t_int_c": 38.0, "t_shell_c": 36.0, "t_evap_c": 12.0}
"""Initial state of a cabin that has already been cooled for a while [degC]."""


def _hold_s(rng, settings: ExcitationSettings) -> float:
    """A random hold of the excitation's levels [s]: a whole number of model steps in [hold_min_s, hold_max_s]."""
    return settings.ts_s * rng.integers(
        int(settings.hold_min_s / settings.ts_s), int(settings.hold_max_s / settings.ts_s) + 1
    )


def generate_excitation(
    drives=TRAIN_DRIVES,
    settings: ExcitationSettings = ExcitationSettings(),
    seed_offset: int = 0,
    extra_states: tuple = (),
) -> dict:
    """Simulate the plant under multi-level random input steps; return 1 s series (SERIES_COLUMNS).

    ``extra_states``: further plant temperatures recorded as columns after SERIES_COLUMNS (fields of
    ``PlantState``/``PlantOutputs``, e.g. ``("t_glass_c", "t_duct_c")`` for the state estimator's
    data, ``estimator_id``); the other columns do not depend on it.
    """
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.plant import CabinPlant, PlantState
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_v2x_preview.scenario import load_scenario

    settings.validate()
    rng = np.random.default_rng(settings.seed + seed_offset)
    rows: dict[str, list] = {c: [] for c in SERIES_COLUMNS + tuple(extra_states)}
    pp = PlantParams()
    for seg, (name, init) in enumerate(drives):
        sc = load_scenario(name)
        ini = dataclasses.asdict(sc.initial)
        if init == "precooled":
            ini.update(_PRECOOLED)
        plant = CabinPlant(pp, PlantState.from_initial(ini, pp, sc.env_at(0.0)))
        st = plant.state
        meas = (st.t_cab_c, st.t_int_c, st.t_shell_c, st.t_evap_c, st.t_evap_c)
        extra = tuple(getattr(st, c) for c in extra_states)
        n = int(sc.duration_s)
        t_next = 0.0
        cmd = None
        for i in range(n):
            t = float(i)
            if t >= t_next:
                # strong cooling during the first minute of a hot soak (what every controller does)
                if init == "soak" and t < 60.0:
                    cmd = AcInput(0.17, 3.0)
                    hold = 60.0
                else:
                    cmd = AcInput(float(rng.uniform(0.05, 0.17)), float(rng.uniform(3.0, 10.0)))
                    hold = _hold_s(rng, settings)
                t_next = t + hold
            assert cmd is not None  # set at t = 0 (t_next = 0)
            env = sc.env_at(t)
            out = plant.step(cmd, env, 1.0)
            vals: dict[str, Any] = dict(zip(("t_cab_c", "t_int_c", "t_shell_c", "t_evap_c", "t_vent_c"), meas))
            vals.update(
                segment=seg,
                t_s=t,
                t_amb_c=env.t_amb_c,
                solar_wm2=env.solar_wm2,
                speed_mps=env.speed_mps,
                mdot_bl_kgps=cmd.mdot_bl_kgps,
                t_evap_sp_c=cmd.t_evap_sp_c,
                p_comp_w=out.p_comp_w,
                p_blower_w=out.p_blower_w,
                **dict(zip(extra_states, extra)),
            )
            for c in rows:
                rows[c].append(vals[c])
            meas = (out.t_cab_c, out.t_int_c, out.t_shell_c, out.t_evap_c, out.t_vent_c)
            extra = tuple(getattr(out, c) for c in extra_states)
    return {c: np.asarray(v, dtype=float) for c, v in rows.items()}


def generate_co2_excitation(drive=CO2_TRAIN_DRIVE, settings: ExcitationSettings = ExcitationSettings()) -> dict:
    """Simulate the CO2 excitation: the plant on one drive, random held door shares, blower flows, set-points.

    ``drive``: (scenario, occupants). Returns 1 s series (:data:`CO2_SERIES_COLUMNS`) and the drive's
    ``n_occupants`` and ``co2_amb_ppm``.

    The door moves over its whole range (0..1) and the speed varies with the drive: what the CO2 balance's fit
    needs to tell the fresh air, the leakage at rest and its growth with speed apart. The door column is its
    actual position (the plant's state, after its travel limit), as a car's door-position feedback reports it.
    The levels come from their own generator (``settings.seed`` + 2000): the thermal excitation
    (:func:`generate_excitation`) is unchanged by this one.
    """
    from ceco_core.air_quality import co2_ppm_from_kgkg
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.plant import CabinPlant, PlantState
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_v2x_preview.scenario import load_scenario

    settings.validate()
    name, n_occ = drive
    rng = np.random.default_rng(settings.seed + 2000)
    sc = load_scenario(name)
    pp = dataclasses.replace(PlantParams(), n_occupants=int(n_occ), co2_amb_ppm=float(sc.air_quality.co2_amb_ppm))
    plant = CabinPlant(pp, PlantState.from_initial(dataclasses.asdict(sc.initial), pp, sc.env_at(0.0)))
    rows: dict[str, list] = {c: [] for c in CO2_SERIES_COLUMNS}
    st = plant.state
    co2, door, w_cab, t_ev = co2_ppm_from_kgkg(st.co2_cab_kgkg), st.recirc_share, st.w_cab_kgkg, st.t_evap_c
    t_next, cmd = 0.0, None
    for i in range(int(sc.duration_s)):
        t = float(i)
        if t >= t_next:
            cmd = AcInput(float(rng.uniform(0.05, 0.17)), float(rng.uniform(3.0, 10.0)), float(rng.uniform(0.0, 1.0)))
            t_next = t + _hold_s(rng, settings)
        assert cmd is not None  # set at t = 0 (t_next = 0)
        env = sc.env_at(t)
        out = plant.step(cmd, env, 1.0)
        vals = (t, co2, door, cmd.mdot_bl_kgps, env.speed_mps, w_cab, t_ev, env.t_amb_c, env.rh)
        for c, v in zip(CO2_SERIES_COLUMNS, vals):
            rows[c].append(v)
        co2, door, w_cab, t_ev = out.co2_cab_ppm, out.recirc_share, out.w_cab_kgkg, out.t_evap_c
    series: dict[str, Any] = {c: np.asarray(v, dtype=float) for c, v in rows.items()}
    series.update(n_occupants=int(n_occ), co2_amb_ppm=float(sc.air_quality.co2_amb_ppm))
    return series


CO2_FINE_COLUMNS = ("co2_cab_ppm", "w_cab_kgkg", "t_evap_c")
"""Columns of the CO2 identification CSVs written with 9 significant digits (their differences over 1 s are what
the balances' fits read); the rest 6."""


def write_series_csv(series: dict, path, columns: tuple = SERIES_COLUMNS, fine: tuple = ()) -> str:
    """Write a series dict as CSV; return its sha256.

    ``columns`` (default SERIES_COLUMNS) in that order, those in ``fine`` with 9 significant digits, the rest 6.
    """
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in zip(*(series[c] for c in columns)):
            w.writerow([f"{v:.9g}" if c in fine else f"{v:.6g}" for c, v in zip(columns, row)])
    return hashlib.sha256(path.read_bytes()).hexdigest()


def read_series_csv(path, columns: tuple = SERIES_COLUMNS, optional: tuple = ()) -> dict:
    """Read a CSV with (at least) ``columns`` (default SERIES_COLUMNS); ``segment`` defaults to 0 (one run).

    ``optional``: columns of ``columns`` the file may lack (NaN then); present, they are read like every other,
    except that NaN is allowed there (not measured on that row, as a missing column).
    A missing column, a value that is not a number, or one that is not finite (NaN, inf; NaN outside
    ``optional``) is a ValueError naming the file, the line and the column.
    """
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        data: dict[str, list] = {c: [] for c in columns}
        for line, r in enumerate(reader, start=2):
            for c in columns:
                if c not in r:
                    if c == "segment" or c in optional:
                        data[c].append(0.0 if c == "segment" else math.nan)
                        continue
                    raise ValueError(f"{path}: missing column {c!r}")
                try:
                    v = float(r[c])
                except (TypeError, ValueError):
                    raise ValueError(f"{path}: line {line}, column {c!r}: {r[c]!r} is not a number") from None
                if not (math.isfinite(v) or (math.isnan(v) and c in optional)):
                    raise ValueError(
                        f"{path}: line {line}, column {c!r}: {r[c]!r} is not a finite number: give a measured "
                        "value, or split the file there"
                    )
                data[c].append(v)
    return {c: np.asarray(v) for c, v in data.items()}
