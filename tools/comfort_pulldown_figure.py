#!/usr/bin/env python3
"""The hot-soak pull-down at the occupant, against what could be cited (docs/comfort.md, docs/plant.md).

Writes ``docs/figures/comfort_pulldown.png`` and prints the numbers quoted in
the docs. Full cooling (0.17 kg/s, 3 degC set-point) from the soak of
``sc03`` (SC03 regulation soak, cabin 43 degC) and ``sc03_hotsoak`` (one-hour
soak, cabin 57 degC), 30 min with the SC03 weather held after 600 s:

* left: mean cabin air, the occupant's body-average air (PMV input), the jet
  air at the upper body, the vent air and the HVAC case/duct wall, and the
  same cabin air without most of the duct mass (c_duct 0.7 kJ/K: close to the
  plant before the duct node); for sc03_hotsoak the informal press test
  (53 degC at key-on, 43 / 41 / 39 degC after 10 / 15 / 20 min, max A/C,
  parked, ~38 degC ambient; Thrillist, reported by danviet.com) as points;
* right: vent (discharge) air against the recirculated inlet air over the
  pull-down, with the production A/C performance table of a service manual
  (Nissan GT-R 2010 ESM: after 10 min of max A/C at idle, recirculation,
  maximum blower; inlet 25 / 30 degC -> centre vent 8.4-10.9 / 14.5-17.5 degC
  at 50-60 % RH, 10.9-13.4 / 17.5-20.5 degC at 60-70 % RH) as bars.

No measured SC03 pull-down curve was found to compare with (docs/comfort.md).

Usage (repository root)::

    .venv/bin/python tools/comfort_pulldown_figure.py [--out docs/figures] [--no-plot]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from ceco_core.cabin_comfort import comfort_params_for, evaluate_cabin_comfort
from ceco_core.contracts import AcInput
from ceco_plant_sim.plant import CabinPlant, PlantState
from ceco_plant_sim.plant_params import PlantParams
from ceco_v2x_preview.scenario import Environment, load_scenario

REPO = Path(__file__).resolve().parents[1]
FULL = AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0)
N_S = 1800
PRESS_TEST = ((0.0, 53.0), (600.0, 43.0), (900.0, 41.0), (1200.0, 39.0))
"""Informal press test (t [s], cabin air [degC]); not a test procedure."""
GTR_TABLE = (
    (25.0, 8.4, 10.9, "50-60 % RH"),
    (30.0, 14.5, 17.5, "50-60 % RH"),
    (25.0, 10.9, 13.4, "60-70 % RH"),
    (30.0, 17.5, 20.5, "60-70 % RH"),
)
"""Nissan GT-R 2010 ESM: (recirculated inlet [degC], centre-vent discharge min, max [degC], inlet RH)."""


def _env(sc, t_s):
    if t_s < sc.duration_s:
        return sc.env_at(t_s)
    end = sc.env_at(sc.duration_s)
    return Environment(end.t_amb_c, end.solar_wm2, sc.speed_mps(t_s % sc.duration_s), end.rh)


def pulldown(scenario: str, params: PlantParams | None = None, n_s: int = N_S) -> dict:
    """Full cooling from the scenario's soak: series at the start of every 1 s step (the run-directory sampling)."""
    sc = load_scenario(scenario)
    p = params or PlantParams()
    plant = CabinPlant(p, PlantState.from_initial(sc.initial, p, sc.env_at(0.0)))
    cp = comfort_params_for(sc, glazing_tau=p.tau_glass, u_shell_in_wm2k=p.u_shell_in_wm2k)
    snap = plant.snapshot(FULL, sc.env_at(0.0))
    rows = {
        k: []
        for k in (
            "t_s",
            "t_cab_c",
            "t_vent_c",
            "t_duct_c",
            "t_mix_c",
            "ta_occ_c",
            "ta_jet_c",
            "t_mr_c",
            "pmv",
            "rh_cab",
        )
    }
    meas = snap
    for k in range(n_s):
        env = _env(sc, float(k))
        c = evaluate_cabin_comfort(
            t_cab_c=meas.t_cab_c,
            t_vent_c=meas.t_vent_c,
            t_int_c=meas.t_int_c,
            t_shell_c=meas.t_shell_c,
            t_glass_c=meas.t_glass_c,
            rh_cab=meas.rh_cab,
            mdot_bl_kgps=FULL.mdot_bl_kgps,
            solar_wm2=env.solar_wm2,
            params=cp,
        )
        r = p.recirc_fraction
        vals = dict(
            t_s=float(k),
            t_cab_c=meas.t_cab_c,
            t_vent_c=meas.t_vent_c,
            t_duct_c=meas.t_duct_c,
            t_mix_c=r * meas.t_cab_c + (1 - r) * env.t_amb_c,
            ta_occ_c=float(c.ta_occ_c),
            ta_jet_c=float(c.ta_jet_c),
            t_mr_c=float(c.t_mr_c),
            pmv=float(c.pmv),
            rh_cab=meas.rh_cab,
        )
        for key, v in vals.items():
            rows[key].append(v)
        meas = plant.step(FULL, env, 1.0)
    return {k: np.asarray(v) for k, v in rows.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    ap.add_argument("--no-plot", action="store_true")
    args = ap.parse_args(argv)
    light = dataclasses.replace(PlantParams(), c_duct_jpk=700.0)
    runs = {name: (pulldown(name), pulldown(name, light)) for name in ("sc03", "sc03_hotsoak")}
    marks = (30, 60, 120, 300, 600, 900, 1200, 1800)
    for name, (r, rl) in runs.items():
        print(f"{name}: t [s] " + " ".join(f"{t:>6d}" for t in marks))
        for key, lab in (
            ("t_cab_c", "cabin air"),
            ("ta_occ_c", "occupant air"),
            ("ta_jet_c", "jet air"),
            ("t_vent_c", "vent air"),
            ("t_duct_c", "duct wall"),
            ("t_mr_c", "T_mr"),
            ("pmv", "PMV"),
        ):
            print(f"  {lab:>14s} " + " ".join(f"{r[key][min(t, N_S - 1)]:6.1f}" for t in marks))
        print(f"  {'cabin, 0.7kJ/K':>14s} " + " ".join(f"{rl['t_cab_c'][min(t, N_S - 1)]:6.1f}" for t in marks))
        t25 = r["t_s"][np.argmax(r["t_cab_c"] <= 25.0)] if np.any(r["t_cab_c"] <= 25.0) else float("nan")
        print(
            f"  cabin air reaches 25 degC at {t25:.0f} s; PMV first <= 0.5 at "
            f"{r['t_s'][np.argmax(r['pmv'] <= 0.5)] if np.any(r['pmv'] <= 0.5) else float('nan'):.0f} s"
        )
        i600 = 600
        print(
            f"  at 600 s: recirculated inlet {r['t_mix_c'][i600]:.1f} degC -> vent {r['t_vent_c'][i600]:.1f} degC "
            f"(cabin RH {r['rh_cab'][i600]:.2f})"
        )
    if args.no_plot:
        return 0
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8), gridspec_kw={"width_ratios": [1, 1, 0.8]})
    for ax, (name, (r, rl)) in zip(axes[:2], runs.items()):
        tm = r["t_s"] / 60.0
        ax.plot(tm, r["t_cab_c"], "k-", label="mean cabin air")
        ax.plot(tm, rl["t_cab_c"], "k:", label="mean cabin air, duct mass 0.7 kJ/K")
        ax.plot(tm, r["ta_occ_c"], "C0-", label="occupant air (body average, PMV)")
        ax.plot(tm, r["ta_jet_c"], "C0--", label="jet air at the upper body (DR)")
        ax.plot(tm, r["t_vent_c"], "C1-", label="vent air")
        ax.plot(tm, r["t_duct_c"], "C2-", lw=0.8, label="HVAC case / duct wall")
        ax.plot(tm, r["t_mr_c"], "C3-", lw=0.8, label="mean radiant temperature")
        if name == "sc03_hotsoak":
            pt = np.array(PRESS_TEST)
            ax.plot(pt[:, 0] / 60.0, pt[:, 1], "ms", label="informal press test (other car, ~38 degC amb.)")
        ax.set_title(f"{name}: full cooling from the soak")
        ax.set_xlabel("time [min]")
        ax.set_ylabel("temperature [degC]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[1].legend(fontsize=7, loc="upper right")
    ax = axes[2]
    for name, (r, _) in runs.items():
        sel = r["t_s"] >= 60
        ax.plot(r["t_mix_c"][sel], r["t_vent_c"][sel], label=f"plant, {name} (t >= 1 min)")
    for i, (t_in, lo, hi, rh) in enumerate(GTR_TABLE):
        ax.plot(
            [t_in + (0.3 if i >= 2 else -0.3)] * 2,
            [lo, hi],
            "C3" if i < 2 else "C4",
            lw=4,
            label=f"GT-R 2010 ESM, {rh}" if i in (0, 2) else None,
        )
    ax.set_xlabel("recirculated inlet air [degC]")
    ax.set_ylabel("vent (discharge) air [degC]")
    ax.set_title("vent air vs inlet air")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "comfort_pulldown.png", dpi=110)
    print(f"wrote {args.out / 'comfort_pulldown.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
