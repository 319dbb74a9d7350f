#!/usr/bin/env python3
"""Regenerate the smooth refrigerant-cycle table, ceco_plant_sim/ceco_plant_sim/data/smooth_cycle_R1234yf.npz.

Usage (from the repository root, workspace sourced):

    python tools/make_smooth_cycle_table.py            # sample the solver, write the shipped file, check it
    python tools/make_smooth_cycle_table.py --check    # exit 1 if it differs from a fresh sampling
    python tools/make_smooth_cycle_table.py --show     # print its provenance
    python tools/make_smooth_cycle_table.py --errors   # spline error against the solver off the grid

The file holds the plant's own refrigerant solve (``ceco_plant_sim.refrigerant.solve_cycle``, tolerance
1e-10 K, cold start) on ``DEFAULT_SMOOTH_GRID`` for the default ``PlantParams``: capacity, compressor
power, evaporating temperature and refrigerant flow over (speed, evaporator wall, ambient, condenser
epsc), and the inverter power-limit speed over (wall, ambient, epsc), with its provenance (the cycle
parameters, grid, solver settings, refrigerant-table source, command, date, ceco commit). The smooth
model (``PlantModel.smooth``) fits cubic B-splines through it (``ceco_plant_sim.smooth_cycle``).

``--check`` samples the solver again at every grid point and compares bit for bit (as
tests/test_smooth_cycle.py does on a random subset). Run this after changing the cycle's equations,
its parameters' defaults, the refrigerant tables or the grid. ``--errors`` prints the spline's error
against the solver at random points off the grid (the numbers of docs/plant.md, "Smooth model").
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def errors(n_points: int = 3000, seed: int = 1) -> dict:
    """Spline error of the shipped table against the solver at random off-grid points, by region."""
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_plant_sim.smooth_cycle import (
        TABLE_OUTPUTS,
        _power_limit_speed,
        _solver,
        load_smooth_cycle_file,
    )

    p = PlantParams()
    tab = load_smooth_cycle_file()
    solve = _solver(p)
    rng = np.random.default_rng(seed)
    box = tab.box()
    rows = []
    for _ in range(n_points):
        x = [rng.uniform(lo, hi) for lo, hi in box]
        x[0] = rng.uniform(p.comp_speed_min_rpm, p.comp_speed_max_rpm)
        s = solve(*x)
        got = np.array(tab.cycle(*x)).ravel()
        rows.append((x, [getattr(s, k) for k in TABLE_OUTPUTS], got, s.mop_active, s.head_pressure_control))
    out = {}
    for name, keep in (
        ("all", lambda r: True),
        ("no MOP, no head-pressure control", lambda r: not r[3] and not r[4]),
        ("MOP or head-pressure control", lambda r: r[3] or r[4]),
        ("ambient >= 28 degC", lambda r: r[0][2] >= 28.0),
    ):
        sel = [r for r in rows if keep(r)]
        ref = np.array([r[1] for r in sel])
        got = np.array([r[2] for r in sel])
        out[name] = {
            "points": len(sel),
            "q_rel_p50_p95_max": [float(v) for v in np.percentile(np.abs(got[:, 0] / ref[:, 0] - 1), [50, 95, 100])],
            "p_rel_p50_p95_max": [float(v) for v in np.percentile(np.abs(got[:, 1] / ref[:, 1] - 1), [50, 95, 100])],
            "p_abs_max_w": float(np.max(np.abs(got[:, 1] - ref[:, 1]))),
            "t_e_abs_max_k": float(np.max(np.abs(got[:, 2] - ref[:, 2]))),
        }
    lim = []
    for _ in range(max(50, n_points // 10)):
        x = [rng.uniform(lo, hi) for lo, hi in box[1:]]
        ref = _power_limit_speed(solve, p, *x)
        if ref <= p.comp_speed_max_rpm + 500.0:  # where the limit can bind (beyond: smooth_min(N, N_lim) = N)
            lim.append(abs(float(tab.n_lim(*x)) - ref))
    out["n_lim_abs_rpm_p50_p95_max (N_lim <= N_max + 500)"] = [float(v) for v in np.percentile(lim, [50, 95, 100])]
    out["n_lim_points"] = len(lim)
    return out


def main(argv=None) -> int:
    from ceco_plant_sim import smooth_cycle as sc

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=sc.SHIPPED_SMOOTH_TABLE, help="file to write or check (default: the shipped one)")
    p.add_argument("--check", action="store_true", help="compare the file with a fresh sampling of the solver")
    p.add_argument("--show", action="store_true", help="print the provenance of the file")
    p.add_argument("--errors", action="store_true", help="spline error against the solver off the grid")
    args = p.parse_args(argv)
    if args.show:
        print(json.dumps(sc._read(args.out)[0], indent=2, sort_keys=True))
        return 0
    if args.errors:
        print(json.dumps(errors(), indent=2))
        return 0
    if args.check:
        try:
            prov = sc.check_smooth_cycle_file(args.out)
        except sc.StaleSmoothTableError as err:
            print(f"STALE: {err}", file=sys.stderr)
            return 1
        print(f"{args.out}: current (generated {prov['date_utc']}, equal bit for bit to a fresh sampling)")
        return 0
    from make_refrigerant_tables import _commit  # the same provenance helper

    prov = sc.write_smooth_cycle_file(args.out, extra={"ceco_commit": _commit()})
    sc.check_smooth_cycle_file(args.out, sample=200)
    print(f"wrote {args.out}: grid {prov['grid']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
