"""Figures and headline numbers of the cabin + A/C plant (docs/plant.md).

Writes ``docs/figures/plant_pulldown.png`` (SC03 hot-soak pull-down at full
cooling) and ``docs/figures/plant_cop_vs_speed.png`` (compressor power and
COP versus vehicle speed at fixed cooling loads), and prints the numbers
quoted in docs/plant.md, including the wall time of a 600 s simulation.

Usage::

    .venv/bin/python tools/plant_figures.py [--out docs/figures] [--no-plots]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from ceco_core.contracts import AcInput
from ceco_plant_sim.plant import CabinPlant, PlantState, steady_cycle_at_load
from ceco_plant_sim.plant_params import PlantParams
from ceco_v2x_preview.scenario import Environment, load_scenario

REPO = Path(__file__).resolve().parents[1]
FULL = AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0)


def sc03_env(sc, t_s: float) -> Environment:
    """SC03 for its 600 s; afterwards the SC03 speed trace repeats with the weather held at its end values."""
    if t_s < sc.duration_s:
        return sc.env_at(t_s)
    end = sc.env_at(sc.duration_s)
    return Environment(end.t_amb_c, end.solar_wm2, sc.speed_mps(t_s % sc.duration_s), end.rh)


def pulldown(params: PlantParams, n_s: int = 1800, dt_s: float = 1.0, scenario: str = "sc03_hotsoak"):
    """Full cooling (0.17 kg/s, 3 degC set-point) from a scenario's soak; returns (t_s, outputs, envs)."""
    sc = load_scenario(scenario)
    plant = CabinPlant(params, PlantState.from_initial(sc.initial, params, sc.env_at(0.0)))
    outs, envs = [], []
    for k in range(int(n_s / dt_s)):
        env = sc03_env(sc, k * dt_s)
        envs.append(env)
        outs.append(plant.step(FULL, env, dt_s))
    return np.arange(1, len(outs) + 1) * dt_s, outs, envs


def bench(params: PlantParams, repeats: int = 3) -> float:
    """Best-of-``repeats`` wall time [s] of 600 plant steps of 1 s (SC03, full cooling, tables prebuilt)."""
    sc = load_scenario("sc03_hotsoak")
    envs = [sc.env_at(float(k)) for k in range(600)]
    CabinPlant(params, PlantState.from_initial(sc.initial, params, envs[0]))  # build the tables once
    best = float("inf")
    for _ in range(repeats):
        plant = CabinPlant(params, PlantState.from_initial(sc.initial, params, envs[0]))
        t0 = time.perf_counter()
        for env in envs:
            plant.step(FULL, env, 1.0)
        best = min(best, time.perf_counter() - t0)
    return best


def speed_map(
    params: PlantParams, loads_w=(2000.0, 3000.0, 4000.0), t_wall_c: float = 5.0, t_amb_c: float = 35.0, speeds_mps=None
):
    """Steady cycle at fixed cooling loads versus vehicle speed: dict load -> arrays (speed, P_comp, COP, T_c)."""
    speeds = np.arange(0.0, 35.01, 2.5) if speeds_mps is None else np.asarray(speeds_mps, float)
    out = {}
    for q in loads_w:
        rows = []
        for v in speeds:
            _, s = steady_cycle_at_load(params, q, t_wall_c, t_amb_c, float(v))
            rows.append((v, s.p_comp_w, s.q_evap_ref_w / s.p_comp_w, s.t_cond_c))
        out[q] = np.array(rows)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs" / "figures"), help="output directory for the PNGs")
    ap.add_argument("--no-plots", action="store_true", help="print the numbers only")
    args = ap.parse_args(argv)
    params = PlantParams()

    t_s, outs, envs = pulldown(params)
    t_cab = np.array([o.t_cab_c for o in outs])
    reached = t_cab <= 25.0
    t25 = float(t_s[np.argmax(reached)]) if reached.any() else float("nan")
    p_comp = np.array([o.p_comp_w for o in outs])
    p_bl = np.array([o.p_blower_w for o in outs])
    q_ref = np.array([o.q_evap_ref_w for o in outs])
    print(f"sc03_hotsoak (one-hour soak; t_cab {outs[0].t_cab_c:.1f} degC after 1 s), full cooling:")
    print(
        f"  cabin air reaches 25 degC after {t25:.0f} s ({t25 / 60:.1f} min); "
        f"t_cab at 600/1200/1800 s: {t_cab[599]:.1f} / {t_cab[1199]:.1f} / {t_cab[-1]:.1f} degC"
    )
    for a, b in ((0, 600), (0, 1800)):
        print(
            f"  {a}-{b} s: mean P_comp {p_comp[a:b].mean():.0f} W, P_blower {p_bl[a:b].mean():.0f} W, "
            f"P_comp+P_blower max {(p_comp + p_bl)[a:b].max():.0f} W, "
            f"COP (energy ratio) {q_ref[a:b].sum() / p_comp[a:b].sum():.2f}, "
            f"mean Q_evap {np.mean([o.q_evap_w for o in outs[a:b]]):.0f} W "
            f"(latent {np.mean([o.q_latent_w for o in outs[a:b]]):.0f} W)"
        )
    cop = np.array([o.cop for o in outs])
    print(
        f"  instantaneous COP after 60 s: {cop[60:].min():.2f} .. {cop[60:].max():.2f}; "
        f"T_cond {min(o.t_cond_c for o in outs[60:]):.1f} .. {max(o.t_cond_c for o in outs[60:]):.1f} degC; "
        f"T_vent after 900 s {min(o.t_vent_c for o in outs[900:]):.1f} .. "
        f"{max(o.t_vent_c for o in outs[900:]):.1f} degC"
    )

    _, o_reg, _ = pulldown(params, n_s=600, scenario="sc03")
    t_reg = np.array([o.t_cab_c for o in o_reg])
    print(
        f"sc03 (the regulation's 10-minute soak; t_cab {o_reg[0].t_cab_c:.1f} degC after 1 s), full cooling: "
        f"25 degC after {float(np.argmax(t_reg <= 25.0) + 1):.0f} s, {t_reg[-1]:.1f} degC at 600 s"
    )

    smap = speed_map(params)
    print("Fixed cooling load, 5 degC evaporator wall, 35 degC ambient (steady cycle):")
    for q, arr in smap.items():
        i25 = int(np.argmin(np.abs(arr[:, 0] - 25.0)))
        print(
            f"  {q / 1000:.0f} kW: COP {arr[0, 2]:.2f} at 0 m/s -> {arr[i25, 2]:.2f} at 25 m/s "
            f"(+{100 * (arr[i25, 2] / arr[0, 2] - 1):.0f} %), P_comp {arr[0, 1]:.0f} -> {arr[i25, 1]:.0f} W, "
            f"T_cond {arr[0, 3]:.1f} -> {arr[i25, 3]:.1f} degC"
        )

    for sub in (0.25,):
        _, o2, _ = pulldown(dataclasses.replace(params, substep_s=sub), n_s=600)
        d_cab = max(abs(a.t_cab_c - b.t_cab_c) for a, b in zip(outs[:600], o2))
        d_ev = max(abs(a.t_evap_c - b.t_evap_c) for a, b in zip(outs[:600], o2))
        print(
            f"Sub-step {params.substep_s} s vs {sub} s over the 600 s SC03 pull-down: "
            f"max |dT_cab| {d_cab:.4f} K, max |dT_evap| {d_ev:.4f} K"
        )
    iters = [o.cycle_iterations for o in outs]
    print(f"Refrigerant loop: {np.mean(iters):.2f} Newton evaluations per solve at step ends (max {max(iters)})")
    wall = bench(params)
    print(
        f"Wall time of 600 s simulated at 1 s steps (sub-step {params.substep_s} s): {wall:.3f} s "
        f"(real-time factor {600.0 / wall:.0f}x)"
    )

    if args.no_plots:
        return 0
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tm = t_s / 60.0
    fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for name, lab in (
        ("t_cab_c", "cabin air"),
        ("t_int_c", "interior mass"),
        ("t_shell_c", "shell"),
        ("t_glass_c", "glazing"),
        ("t_vent_c", "vent air"),
        ("t_evap_c", "evaporator wall"),
    ):
        ax[0].plot(tm, [getattr(o, name) for o in outs], label=lab)
    ax[0].axhline(25.0, color="k", ls=":", lw=0.8)
    if np.isfinite(t25):
        ax[0].axvline(t25 / 60.0, color="k", ls=":", lw=0.8)
    ax[0].set_ylabel("temperature [degC]")
    ax[0].legend(ncol=3, fontsize=8)
    ax[0].set_title(
        "SC03 after a one-hour hot soak (sc03_hotsoak), full cooling (0.17 kg/s, 3 degC set-point)", fontsize=10
    )
    ax[1].plot(tm, p_comp / 1000, label="compressor (electrical)")
    ax[1].plot(tm, p_bl / 1000, label="blower")
    ax[1].plot(tm, [o.q_evap_w / 1000 for o in outs], label="evaporator heat (air side)")
    ax[1].plot(tm, [o.q_latent_w / 1000 for o in outs], label="of which latent")
    ax[1].set_ylabel("power [kW]")
    ax[1].legend(ncol=2, fontsize=8)
    ax[2].plot(tm, cop, label="COP")
    ax2 = ax[2].twinx()
    ax2.plot(tm, [e.speed_mps for e in envs], color="0.6", lw=0.8, label="vehicle speed")
    ax2.set_ylabel("speed [m/s]")
    ax[2].set_ylabel("COP [-]")
    ax[2].set_xlabel("time [min]")
    ax[2].legend(loc="upper left", fontsize=8)
    ax2.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "plant_pulldown.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 3, figsize=(12, 3.8))
    for q, arr in smap.items():
        ax[0].plot(arr[:, 0], arr[:, 2], marker="o", ms=3, label=f"{q / 1000:.0f} kW")
        ax[1].plot(arr[:, 0], arr[:, 1], marker="o", ms=3, label=f"{q / 1000:.0f} kW")
        ax[2].plot(arr[:, 0], arr[:, 3], marker="o", ms=3, label=f"{q / 1000:.0f} kW")
    ax[0].set_ylabel("COP = Q_evap / P_comp,el [-]")
    ax[1].set_ylabel("compressor electrical power [W]")
    ax[2].set_ylabel("condensing temperature [degC]")
    for a in ax:
        a.set_xlabel("vehicle speed [m/s]")
        a.grid(alpha=0.3)
        a.legend(title="cooling load", fontsize=8)
    fig.suptitle(
        "Fixed cooling load, 5 degC evaporator wall, 35 degC ambient: ram air lowers the condensing temperature",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(out / "plant_cop_vs_speed.png", dpi=110)
    plt.close(fig)
    print(f"wrote {out / 'plant_pulldown.png'} and {out / 'plant_cop_vs_speed.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
