"""The coil/blower split at equal comfort: the plant against the control model, at one operating point.

    python tools/split_study.py [--t-amb 35] [--solar 700] [--speed 10] [--rh 0.4] [--pmv 0.45]
                                [--model-params FILE]

For each evaporator set-point of a grid, the blower flow that holds the cabin PMV at ``--pmv`` and the power
it takes, twice:

* on the plant (``ceco_plant_sim.plant``): from one settled cabin state (900 s at 0.10 kg/s and 8 degC in the
  constant weather given), each (flow, set-point) pair held for 240 s; the scored PMV at the end
  (``acc_law.feedback_pmv`` on the plant's true states), the mean compressor, blower and condenser-fan power
  over the last 60 s;
* in the control model the NMPC plans with (``ceco_controller.model``, the shipped or ``--model-params`` file):
  the same start, T_int and T_shell held (as the NLP holds them), 48 model steps (240 s) with the pair held;
  the NLP's PMV (measured humidity and T_mr held, as ``pmv_pa_source: measured``), the model's compressor and
  blower power at the end (the model has no condenser fan).

The flow at the target PMV is interpolated linearly between the grid's flows (12 flows, 0.06-0.17 kg/s). The
set-point where each curve is lowest is the split each one would choose; a model that ranks the split as the
plant does has its minimum at the plant's (docs/controller.md, "The fresh-air share"). A study, not a test:
the powers are quasi-steady (the interior and shell drift during the 240 s).

``--case CASE --at-s T [--strategy ceco-pmv] [--seed 0] [--hold-s 120]``: the same grid from the state a
benchmark run reaches at T s instead of a settled cabin: the case's cell of ``--strategy`` and ``--seed`` is run as
``ceco benchmark`` runs it (``runner.case_cells``, ``closed_loop.simulate``), its commands are replayed on the plant
of the case's scenario (``ScenarioPlant``, the weather and speed of the scenario after T) up to T, and each pair is
held from there for ``--hold-s`` (the powers: the mean of its last 60 s; the PMV: the scored one at its end). The
control model starts from the plant's state at T with the scenario's weather at T held; its PMV is read against
the target moved by its own offset where the plant holds the target at the run's set-point at T (the bias a
controller's PMV feedback removes, docs/controller.md §4.7), so both curves hold the same PMV as the plant sees
it. This reaches the operating points of a hard pull-down's band phase, which a settled cabin does not
(docs/results.md, "The hot soak's gap, window by window").
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

FLOWS_KGPS = np.linspace(0.06, 0.17, 12)
SET_POINTS_C = (3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0)
RUN_SET_POINTS_C = (3.0, 3.5, 4.0, 4.5, 5.0, 6.0, 7.0)
"""The set-points of ``--case`` (a band phase near the coil's 3 degC floor: finer there)."""
HOLD_S, MEAN_S, MODEL_STEPS = 240, 60, 48


def _at_target(points, pmv: float):
    """(flow [kg/s], power [W]) where the (PMV, power) ``points`` over :data:`FLOWS_KGPS` reach ``pmv``; None if not."""
    y, e = np.array([q[0] for q in points]), np.array([q[1] for q in points])
    if not y.min() <= pmv <= y.max():
        return None
    order = np.argsort(y)
    mdot = float(np.interp(pmv, y[order], FLOWS_KGPS[order]))
    return mdot, float(np.interp(mdot, FLOWS_KGPS, e))


def study(t_amb_c: float, solar_wm2: float, speed_mps: float, rh: float, pmv: float, model_params=None) -> dict:
    """Per set-point: (flow [kg/s], total power [W]) at the target PMV, plant and model (None: not reachable)."""
    from ceco_controller import model as cm
    from ceco_core import psychro
    from ceco_core.acc_law import feedback_pmv
    from ceco_core.cabin_comfort import cabin_mrt_c, cabin_pmv, cabin_w_rad_wm2, comfort_params_for
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.plant import CabinPlant, PlantState
    from ceco_plant_sim.plant_equations import Env
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_v2x_preview.scenario import scenario_from_dict

    sc = scenario_from_dict(
        {
            "name": "split_study",
            "description": "constant weather",
            "drive_cycle": "sc03",
            "duration_s": 600,
            "weather": {"time_s": [0, 600], "t_amb_c": [t_amb_c] * 2, "solar_wm2": [solar_wm2] * 2, "rh": [rh] * 2},
            "occupant": {"met": 1.2, "clo": 0.5},
            "comfort_bounds": {"time_s": [0, 600], "pmv_lb": [-0.5] * 2, "pmv_ub": [0.5] * 2},
            "initial": {"t_cab_c": 27.0, "t_int_c": 33.0, "t_shell_c": 34.0},
            "control": {"control_period_s": 5, "horizon_steps": 6},
            "seed": 0,
        }
    )
    cp = comfort_params_for(sc)
    pp = PlantParams()
    env = Env(t_amb_c, solar_wm2, speed_mps, rh)
    mp = cm.load_params(model_params)
    plant = CabinPlant(pp, PlantState.from_initial({**dataclasses.asdict(sc.initial), "rh_cab": rh}, pp, env))
    for _ in range(900):
        o0 = plant.step(AcInput(0.10, 8.0), env, 1.0)
    start = plant.state

    def plant_pmv(o, mdot):
        return feedback_pmv(
            t_cab_c=o.t_cab_c,
            t_vent_c=o.t_vent_c,
            t_int_c=o.t_int_c,
            t_shell_c=o.t_shell_c,
            t_glass_c=o.t_glass_c,
            rh_cab=o.rh_cab,
            mdot_bl_kgps=mdot,
            solar_wm2=solar_wm2,
            params=cp,
        )

    def on_plant(mdot, sp):
        p = CabinPlant(pp, start)
        powers = []
        for k in range(HOLD_S):
            o = p.step(AcInput(mdot, sp), env, 1.0)
            if k >= HOLD_S - MEAN_S:
                powers.append(o.p_comp_w + o.p_blower_w + o.p_cond_fan_w)
        return plant_pmv(o, mdot), float(np.mean(powers))

    pa = float(psychro.vapour_pressure_pa(o0.t_cab_c, o0.rh_cab))
    t_mr = float(
        cabin_mrt_c(t_cab_c=o0.t_cab_c, t_int_c=o0.t_int_c, t_shell_c=o0.t_shell_c, t_glass_c=o0.t_glass_c, params=cp)
    )
    w_rad = float(cabin_w_rad_wm2(solar_wm2, cp))

    def in_model(mdot, sp):
        tc, te = o0.t_cab_c, o0.t_evap_c
        for _ in range(MODEL_STEPS):
            tc, te, _, pc, pb = cm.step(mp, tc, te, mdot, sp, o0.t_int_c, o0.t_shell_c, t_amb_c, speed_mps)
        tain = cm.t_ain_c(mp, te, mdot)
        y = cabin_pmv(t_cab_c=tc, t_vent_c=tain, mdot_bl_kgps=mdot, t_mr_c=t_mr, w_rad_wm2=w_rad, pa_pa=pa, params=cp)
        return float(y), float(pc + pb)

    rows = {}
    for sp in SET_POINTS_C:
        rows[sp] = (
            _at_target([on_plant(m, sp) for m in FLOWS_KGPS], pmv),
            _at_target([in_model(m, sp) for m in FLOWS_KGPS], pmv),
        )
    return {"start_pmv": plant_pmv(o0, 0.10), "t_cab_c": o0.t_cab_c, "rows": rows}


def run_study(
    case_name: str, strategy: str, seed: int, at_s: float, hold_s: float, pmv: float, model_params=None
) -> dict:
    """:func:`study`'s rows from the plant state of a benchmark run at ``at_s`` (module docstring, ``--case``)."""
    import sys

    from variant_headroom import strategy_cells  # tools/

    from ceco_bringup.benchmark.cases import load_case
    from ceco_bringup.sweep.cells import settings_from_spec
    from ceco_controller import model as cm
    from ceco_controller.closed_loop import simulate
    from ceco_core import psychro
    from ceco_core.cabin_comfort import cabin_mrt_c, cabin_pmv, cabin_w_rad_wm2
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.scenario_plant import ScenarioPlant
    from ceco_v2x_preview.scenario import scenario_from_dict

    cells = [c for c in strategy_cells(load_case(case_name), strategy) if c.axes['seed'] in (seed, None)]
    if not cells:
        sys.exit(f'split_study: no cell of {strategy!r} with seed {seed} on {case_name}')
    spec = cells[0].spec
    scenario = scenario_from_dict(spec['scenario'])
    settings = settings_from_spec(spec)
    ts = simulate(scenario, strategy, settings).timeseries
    dt = float(ts['t_s'][1] - ts['t_s'][0])
    n0 = int(round(at_s / dt))
    if not (0 < n0 and n0 + int(round(hold_s / dt)) <= len(ts['t_s'])):
        sys.exit(
            f'split_study: --at-s {at_s} plus --hold-s {hold_s} must lie inside the run (0..{ts["t_s"][-1] + dt:g} s)'
        )
    door = ts.get('recirc_share_cmd')

    def command(k: int) -> AcInput:
        r = float(door[k]) if door is not None else float('nan')
        return AcInput(float(ts['mdot_bl_kgps'][k]), float(ts['t_evap_sp_c'][k]), r)

    def plant_at_start() -> ScenarioPlant:
        p = ScenarioPlant(scenario, dt, evaluation=None)
        for k in range(n0):
            p.step(command(k))
        return p

    start = plant_at_start()
    m0, env = dict(start.meas), scenario.env_at(n0 * dt)
    held = command(n0)
    n_hold, n_mean = int(round(hold_s / dt)), int(round(MEAN_S / dt))

    def on_plant(mdot, sp):
        p = plant_at_start()
        powers = []
        for k in range(n_hold):
            rec = p.step(AcInput(mdot, sp, held.recirc_share))
            if k >= n_hold - n_mean:
                powers.append(rec.out.p_comp_w + rec.out.p_blower_w + rec.out.p_cond_fan_w)
        return rec.pmv, float(np.mean(powers))

    mp, cp = cm.load_params(model_params), start.comfort
    pa = float(psychro.vapour_pressure_pa(m0['t_cab_c'], m0['rh_cab']))
    t_mr = float(
        cabin_mrt_c(
            t_cab_c=m0['t_cab_c'],
            t_int_c=m0['t_int_c'],
            t_shell_c=m0['t_shell_c'],
            t_glass_c=m0['t_glass_c'],
            params=cp,
        )
    )
    w_rad = float(cabin_w_rad_wm2(env.solar_wm2, cp))
    n_model = int(round(hold_s / mp.ts_s))

    def in_model(mdot, sp):
        tc, te = m0['t_cab_c'], m0['t_evap_c']
        for _ in range(n_model):
            tc, te, _, pc, pb = cm.step(
                mp, tc, te, mdot, sp, m0['t_int_c'], m0['t_shell_c'], env.t_amb_c, env.speed_mps
            )
        tain = cm.t_ain_c(mp, te, mdot)
        y = cabin_pmv(t_cab_c=tc, t_vent_c=tain, mdot_bl_kgps=mdot, t_mr_c=t_mr, w_rad_wm2=w_rad, pa_pa=pa, params=cp)
        return float(y), float(pc + pb)

    plant_rows = {sp: _at_target([on_plant(m, sp) for m in FLOWS_KGPS], pmv) for sp in RUN_SET_POINTS_C}
    # the model's offset where the plant holds the PMV at the run's own set-point
    ref = _at_target([on_plant(m, held.t_evap_sp_c) for m in FLOWS_KGPS], pmv)
    if ref is None:
        sys.exit(
            f'split_study: the plant does not reach PMV {pmv:+.2f} at the run\'s set-point {held.t_evap_sp_c:.2f} degC'
        )
    offset = in_model(ref[0], held.t_evap_sp_c)[0] - pmv
    rows = {
        sp: (plant_rows[sp], _at_target([in_model(m, sp) for m in FLOWS_KGPS], pmv + offset)) for sp in RUN_SET_POINTS_C
    }
    head = (
        f'{case_name} {strategy} seed {seed} at {at_s:g} s (T_cab {m0["t_cab_c"]:.2f} degC, T_int {m0["t_int_c"]:.2f}, '
        f'T_shell {m0["t_shell_c"]:.2f}; its command {held.t_evap_sp_c:.2f} degC / {held.mdot_bl_kgps:.4f} kg/s); each '
        f'pair held {hold_s:g} s; the model\'s PMV offset at the run\'s set-point and the plant\'s flow '
        f'{ref[0]:.4f} kg/s: {offset:+.3f}'
    )
    run_state = {k: float(ts[k][n0]) for k in m0 if k in ts}
    return {'head': head, 'rows': rows, 'offset': offset, 'start': m0, 'run_state': run_state}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="split_study", description=__doc__.split("\n\n")[2])
    ap.add_argument("--t-amb", type=float, default=35.0, help="ambient [degC] (default 35)")
    ap.add_argument("--solar", type=float, default=700.0, help="solar irradiance [W/m2] (default 700)")
    ap.add_argument("--speed", type=float, default=10.0, help="vehicle speed [m/s] (default 10)")
    ap.add_argument("--rh", type=float, default=0.4, help="ambient RH [0..1] (default 0.4)")
    ap.add_argument("--pmv", type=float, default=0.45, help="the PMV held [-] (default 0.45)")
    ap.add_argument("--model-params", default=None, help="control-model file (default: the shipped one)")
    ap.add_argument("--case", default=None, help="start from a benchmark run of this case (module docstring)")
    ap.add_argument("--at-s", type=float, default=None, help="with --case: the run's time to start from [s]")
    ap.add_argument("--strategy", default="ceco-pmv", help="with --case: the run's controller (default ceco-pmv)")
    ap.add_argument("--seed", type=int, default=0, help="with --case: the run's seed (default 0)")
    ap.add_argument(
        "--hold-s", type=float, default=120.0, help="with --case: how long each pair is held [s] (default 120)"
    )
    a = ap.parse_args(argv)
    if a.case is not None:
        if a.at_s is None:
            ap.error("--case needs --at-s")
        res = run_study(a.case, a.strategy, a.seed, a.at_s, a.hold_s, a.pmv, a.model_params)
        print(res["head"])
        print(f"PMV held {a.pmv:+.2f}")
    else:
        res = study(a.t_amb, a.solar, a.speed, a.rh, a.pmv, a.model_params)
        print(f"start: T_cab {res['t_cab_c']:.2f} degC, PMV {res['start_pmv']:+.3f}; PMV held {a.pmv:+.2f}")
    print(f"{'T_evap,sp':>9} | {'plant flow':>10} {'power [W]':>9} | {'model flow':>10} {'power [W]':>9}")
    best = {}
    for sp, (pl, md) in res["rows"].items():
        cells = []
        for k, r in (("plant", pl), ("model", md)):
            cells.append(f"{r[0]:10.4f} {r[1]:9.0f}" if r else f"{'n/a':>10} {'':>9}")
            if r and (k not in best or r[1] < best[k][1]):
                best[k] = (sp, r[1])
        print(f"{sp:9.1f} | {cells[0]} | {cells[1]}")
    for k in ("plant", "model"):
        if k in best:
            print(f"{k}: least power at T_evap,sp {best[k][0]:.1f} degC ({best[k][1]:.0f} W)")
        else:
            print(f"{k}: the PMV {a.pmv:+.2f} is not reachable on the grid")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
