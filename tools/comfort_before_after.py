#!/usr/bin/env python3
"""The issue-9 before/after comfort table on SC03 (docs/comfort.md), from run directories.

Usage (repository root)::

    # before: the code before issue 9 (main at cd24f7a), e.g. in a scratch worktree
    python -m ceco_controller.closed_loop --scenario sc03 --strategy all --out /tmp/before --no-progress
    # after: this code, the paper's p_a in the NMPC (default) and the measured RH
    python -m ceco_controller.closed_loop --scenario sc03 --strategy all --out /tmp/after --no-progress
    python -m ceco_controller.closed_loop --scenario sc03 --strategy all --out /tmp/after_rh --no-progress \\
        --set pmv_pa_source=measured
    .venv/bin/python tools/comfort_before_after.py --before /tmp/before --after /tmp/after --after-rh /tmp/after_rh

Columns per run, over the comfort-zone phase (the samples where the PMV upper bound is at its
tightest, SC03: t >= 300 s):

* ``PMV``: the mean of the run's own scored PMV (before: the paper's model as the old code scored it;
  after: the occupant-environment PMV of ceco_core.cabin_comfort);
* ``PMV new``: the same run re-scored with the new comfort model (from its recorded states: the
  old controllers' behaviour under the new score);
* ``DR>20``: share of samples with an ISO 7730 draught rating above 20 % (category B) [%] and the mean
  DR [%]. Before: the old code's occupant definitions (t_a = 0.75 T_cab + 0.25 T_vent, v = 0.1 + 5.3
  mdot, Tu 40 %, ISO 7730's value when unknown); after: the run's ``dr_pct`` (jet at the upper body);
* ``RH``: mean cabin relative humidity; ``fog``: minimum and mean windscreen fog margin (glass minus
  cabin dew point) [K]; energy of the whole run [kWh] and of the comfort-zone phase [kJ].
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ceco_core import psychro
from ceco_core.cabin_comfort import comfort_params_for, evaluate_cabin_comfort
from ceco_core.contracts import STRATEGIES
from ceco_core.draught import DR_EXACT, draught_rating
from ceco_core.rundir import read_csv_columns
from ceco_v2x_preview.scenario import load_scenario


def _zone(ts):
    return ts["pmv_ub"] <= np.min(ts["pmv_ub"]) + 1e-9


def row(run_dir: Path, label: str, old_model: bool) -> dict:
    """Comfort-zone statistics of one run directory."""
    ts = read_csv_columns(run_dir / "timeseries.csv")
    z = _zone(ts)
    if old_model:
        ta = 0.75 * ts["t_cab_c"] + 0.25 * ts["t_vent_c"]
        v = 0.1 + 5.3 * ts["mdot_bl_kgps"]
        dr = draught_rating(ta, v, 40.0, smoothing=DR_EXACT)
        pa = psychro.vapour_pressure_pa(ts["t_cab_c"], ts["rh_cab"])
        fog = ts["t_glass_c"] - psychro.dew_point_c(pa)
    else:
        dr, fog = ts["dr_pct"], ts["fog_margin_k"]
    rescored = evaluate_cabin_comfort(
        t_cab_c=ts["t_cab_c"],
        t_vent_c=ts["t_vent_c"],
        t_int_c=ts["t_int_c"],
        t_shell_c=ts["t_shell_c"],
        t_glass_c=ts["t_glass_c"],
        rh_cab=ts["rh_cab"],
        mdot_bl_kgps=ts["mdot_bl_kgps"],
        solar_wm2=ts["solar_wm2"],
        params=comfort_params_for(load_scenario("sc03")),
    ).pmv
    e = ts["p_comp_w"] + ts["p_blower_w"]
    return {
        "label": label,
        "pmv": float(np.mean(ts["pmv"][z])),
        "pmv_new": float(np.mean(rescored[z])),
        "dr_share": float(100.0 * np.mean(dr[z] > 20.0)),
        "dr_mean": float(np.mean(dr[z])),
        "rh": float(np.mean(ts["rh_cab"][z])),
        "fog_min": float(np.min(fog)),
        "fog_zone": float(np.mean(fog[z])),
        "e_kwh": float(np.sum(e) / 3.6e6),
        "e_zone_kj": float(np.sum(e[z]) / 1e3),
        "mdot": float(np.mean(ts["mdot_bl_kgps"][z])),
        "sp": float(np.mean(ts["t_evap_sp_c"][z])),
        "t_cab": float(np.mean(ts["t_cab_c"][z])),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--after-rh", type=Path, default=None, help="after, NMPC with pmv_pa_source=measured")
    args = ap.parse_args(argv)
    sets = [("before", args.before, True), ("after", args.after, False)]
    if args.after_rh is not None:
        sets.append(("after, RH", args.after_rh, False))
    print(
        "| strategy | code | PMV (own score) | PMV (new score) | DR > 20 % [%] | DR mean [%] | cabin RH | "
        "fog margin min / zone mean [K] | mean mdot [kg/s] / set-point [degC] / T_cab [degC] | E [kWh] | "
        "E zone [kJ] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for s in STRATEGIES:
        for label, d, old in sets:
            if label == "after, RH" and s == "baseline":
                continue
            r = row(d / s, label, old)
            print(
                f"| {s} | {label} | {r['pmv']:.3f} | {r['pmv_new']:.3f} | {r['dr_share']:.0f} | {r['dr_mean']:.0f} | "
                f"{r['rh']:.3f} | {r['fog_min']:.1f} / {r['fog_zone']:.1f} | {r['mdot']:.3f} / {r['sp']:.1f} / "
                f"{r['t_cab']:.1f} | {r['e_kwh']:.4f} | {r['e_zone_kj']:.0f} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
