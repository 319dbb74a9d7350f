"""The run-directory format shared by the simulator, the DDS stack, report, sweep and benchmark.

A run directory ``DIR`` holds (docs/architecture.md):

* ``metrics.json``: the run's metrics and what was run (scenario, strategy, ...);
* ``timeseries.csv``: one row per plant step, columns :data:`TIMESERIES_COLUMNS`
  first (the contract), extra columns after them;
* ``diagnostics.csv``: one row per control step, columns
  :data:`ceco_core.contracts.DIAGNOSTICS_COLUMNS` first, extras after them;
* ``bag/`` (stack runs only): the rosbag2 recording.

Numbers are written with ``repr`` (round-trip precision), so metrics recomputed
from the CSV equal ``metrics.json``; non-finite values are written as empty
cells and read back as NaN. Pure Python: csv, json, numpy.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "TIMESERIES_COLUMNS",
    "TIMESERIES_EXTRA",
    "COMFORT_COLUMNS",
    "AIR_COLUMNS",
    "format_cell",
    "write_csv",
    "read_csv_columns",
    "write_metrics_json",
    "read_metrics_json",
]

TIMESERIES_COLUMNS = (
    "t_s",
    "t_cab_c",
    "t_int_c",
    "t_shell_c",
    "t_evap_c",
    "t_vent_c",
    "t_amb_c",
    "solar_wm2",
    "speed_mps",
    "rh",
    "mdot_bl_kgps",
    "t_evap_sp_c",
    "p_comp_w",
    "p_blower_w",
    "q_evap_w",
    "cop",
    "pmv",
    "ppd",
    "pmv_lb",
    "pmv_ub",
)
"""The contract's columns of ``timeseries.csv``, in order (docs/architecture.md)."""

COMFORT_COLUMNS = (
    "pa_pa",
    "t_dew_c",
    "fog_margin_k",
    "dr_pct",
    "ta_occ_c",
    "vel_occ_mps",
    "t_mr_c",
    "w_rad_wm2",
    "iso7730_valid",
)
"""The occupant comfort series (ceco_core.cabin_comfort.OccupantComfort, docs/comfort.md): cabin vapour
pressure used in the scored PMV [Pa], cabin dew point [degC], inner glazing minus dew point [K], ISO 7730
draught rating at the occupant [%], the PMV inputs at the occupant (air temperature [degC], air speed
[m/s], mean radiant temperature [degC], absorbed sun [W/m2]) and ISO 7730 validity (1/0)."""

AIR_COLUMNS = ("co2_cab_ppm", "co2_sensor_ppm", "recirc_share", "recirc_share_cmd")
"""Cabin air quality and the door (issue 21, docs/plant.md): cabin CO2 [ppm], the CO2 sensor's reading [ppm]
(empty: no sensor or a failed one), the door's position and the door command applied over the step
(recirculated share [0..1]; the plant's default where the controller left the door alone)."""

TIMESERIES_EXTRA = (
    (
        "t_glass_c",
        "rh_cab",
        "p_cond_fan_w",
        "q_latent_w",
        "comp_speed_rpm",
        "capacity_limited",
    )
    + COMFORT_COLUMNS
    + AIR_COLUMNS
)
"""Extra columns the simulator and the stack both write after the contract's."""


def format_cell(v) -> str:
    """One CSV cell: bools as 0/1, floats with ``repr`` (empty if not finite), anything else ``str``."""
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "" if not math.isfinite(v) else repr(float(v))
    return str(v)


def write_csv(path: str | Path, columns: Sequence[str], data: Mapping[str, Sequence]) -> None:
    """Write ``data`` (column -> equal-length sequence) as a CSV with the header ``columns``."""
    lengths = {len(data[c]) for c in columns}
    if len(lengths) > 1:
        raise ValueError(f"{path}: columns of different lengths {sorted(lengths)}")
    n = lengths.pop() if lengths else 0
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for i in range(n):
            w.writerow([format_cell(data[c][i]) for c in columns])


def read_csv_columns(path: str | Path) -> dict:
    """A CSV file with a header row as ``{column: array}``.

    Float arrays for columns whose every non-empty cell parses as a number
    (empty -> NaN), string arrays otherwise. ValueError on an empty file or a ragged row.
    """
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: empty file") from None
        raw = [row for row in reader if row]
    for i, row in enumerate(raw, start=2):
        if len(row) != len(header):
            raise ValueError(f"{path}: line {i}: {len(row)} cells for {len(header)} columns")
    cols = {}
    for j, name in enumerate(header):
        cells = [r[j].strip() for r in raw]
        try:
            cols[name] = np.array([float(c) if c else np.nan for c in cells], dtype=float)
        except ValueError:
            cols[name] = np.array(cells, dtype=str)
    return cols


def write_metrics_json(path: str | Path, metrics: Mapping) -> None:
    """``metrics.json``: sorted keys, non-finite floats as ``null`` (valid JSON)."""
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in metrics.items()}
    Path(path).write_text(json.dumps(clean, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def read_metrics_json(path: str | Path) -> dict:
    """``metrics.json`` as a dict (``null`` read back as NaN for numeric keys is left to the caller)."""
    data = json.loads(Path(path).read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object")
    return data
