"""The compressor's COP against the evaporator wall temperature at a fixed load: the plant against the control model.

    python tools/cop_sweep.py [--load-w 4150] [--t-amb 35] [--speed 0] [--walls 2.5,3,3.5,4,5,6,7,8,9]
                              [--model-params FILE]

For each evaporator wall temperature of ``--walls`` [degC]:

* the plant (``ceco_plant_sim.refrigerant.solve_cycle``, the plant's own quasi-steady cycle with its compressor
  maps, ``plant_equations.compressor_model`` of the default ``PlantParams``): the compressor speed at which the
  refrigerant takes ``--load-w`` [W] (Brent's method on the speed, up to 1.5 times its maximum: the load
  decides, not the inverter's limit), the condenser air at ``--t-amb`` and its capacity rate at ``--speed``
  [m/s]; its electrical power, pressure ratio and COP = load / power;
* the control model (``ceco_controller.model``, the shipped or ``--model-params`` file): its COP at the same
  load, ``1 / (c0 + c1 * softplus(T_amb - T_wall))`` times eta_AC(speed) (:func:`~ceco_controller.model.p_comp_w`).

The last columns are each COP's rise per kelvin of wall temperature to the next row [%/K]. The control model's
load is the air-side sensible heat (identified on the plant's data), so its COP's level is not the plant's; the
rise per kelvin is what a warmer coil saves at a fixed load. At equal comfort the air a warmer coil needs counts
too, and on the hot soak's band phase it decides the split (docs/results.md, "The hot soak's gap, window by
window").
A study, not a test.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import brentq

from ceco_controller import model as cm
from ceco_plant_sim.plant_equations import compressor_model, condenser_eps_c_wpk
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.refrigerant import cycle_tables, solve_cycle


def plant_point(p: PlantParams, load_w: float, t_wall_c: float, t_amb_c: float, speed_mps: float):
    """The plant's cycle at the compressor speed where the refrigerant takes ``load_w`` [W]."""
    tab = cycle_tables(p.refrigerant, float(p.superheat_k), float(p.subcool_k))
    comp = compressor_model(p)
    epsc = float(condenser_eps_c_wpk(p, speed_mps))

    def solve(n_rpm: float):
        return solve_cycle(tab, comp, n_rpm, t_wall_c, p.ua_evap_ref_wpk, t_amb_c, epsc, p.te_mop_c, pr_min=p.pr_min)

    n = brentq(lambda n: solve(n).q_evap_ref_w - load_w, p.comp_speed_min_rpm, 1.5 * p.comp_speed_max_rpm)
    return n, solve(n)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='cop_sweep', description=__doc__.split('\n\n')[0])
    ap.add_argument('--load-w', type=float, default=4150.0, help='evaporator load [W] (default 4150)')
    ap.add_argument('--t-amb', type=float, default=35.0, help='ambient and condenser air [degC] (default 35)')
    ap.add_argument('--speed', type=float, default=0.0, help='vehicle speed [m/s] (default 0)')
    ap.add_argument('--walls', default='2.5,3,3.5,4,5,6,7,8,9', help='evaporator wall temperatures [degC]')
    ap.add_argument('--model-params', default=None, help='control-model file (default: the shipped one)')
    args = ap.parse_args(argv)
    walls = [float(x) for x in args.walls.split(',') if x.strip()]
    p, mp = PlantParams(), cm.load_params(args.model_params)
    rows = []
    for t_wall in walls:
        n, s = plant_point(p, args.load_w, t_wall, args.t_amb, args.speed)
        q_model = np.float64(args.load_w)
        cop_model = float(q_model / cm.p_comp_w(mp, q_model, args.t_amb, t_wall, args.speed))
        rows.append((t_wall, n, s.pressure_ratio, s.p_comp_w, args.load_w / s.p_comp_w, cop_model))
    print(f'load {args.load_w:g} W, T_amb {args.t_amb:g} degC, speed {args.speed:g} m/s')
    print(
        'T_wall [degC] | speed [rpm] | pressure ratio | plant P_comp [W] | plant COP | model COP '
        '| rise [%/K] plant, model'
    )
    for i, (t_wall, n, pr, pw, cop, cop_m) in enumerate(rows):
        rise = ''
        if i + 1 < len(rows):
            dt = rows[i + 1][0] - t_wall
            rise = f'{100 * (rows[i + 1][4] / cop - 1) / dt:5.2f}, {100 * (rows[i + 1][5] / cop_m - 1) / dt:5.2f}'
        print(f'{t_wall:13.2f} | {n:11.0f} | {pr:14.3f} | {pw:16.1f} | {cop:9.3f} | {cop_m:9.3f} | {rise}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
