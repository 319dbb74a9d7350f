"""What a perfect door could save on a drive with four occupants (issue 21 part 2, docs/results.md "Air quality").

``python docs/studies/aq-4p/door_bound.py [udds]``: the tuned PI at 25 degC and the tuned PMV PI at +0.30 (gains
from the benchmark's baselines.yaml).

For a law at a set-point: E_auto (production door logic), E_rec (full recirculation), the fresh air the logic
let in (M_auto = sum (1 - r) mdot_bl dt) and the least fresh air that keeps the CO2 at or under the limit
(M_min: full recirculation until the cabin reaches the limit, then exactly the flow that holds it:
n g / (X_lim - X_amb) - leakage(V)). The price of fresh air p = (E_auto - E_rec) / M_auto [kWh/kg]; a
perfect door spends E_rec + p M_min.
"""

if __name__ == '__main__':
    import dataclasses
    import sys

    import numpy as np

    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_core.air_quality import co2_generation_kgps, co2_kgkg_from_ppm, leakage_kgps
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_v2x_preview.scenario import load_scenario

    sc = dataclasses.replace(load_scenario(sys.argv[1] if len(sys.argv) > 1 else 'udds'), occupants=4)
    p = PlantParams()
    m_air = p.rho_air_kgm3 * p.cabin_volume_m3
    g = 4 * co2_generation_kgps(p.occ_met)
    lim, amb = float(sc.air_quality.co2_limit_ppm), float(sc.air_quality.co2_amb_ppm)
    dx_lim = co2_kgkg_from_ppm(lim - amb)
    from ceco_bringup.benchmark.runner import load_baselines

    fams = load_baselines().families
    laws = {
        'tuned@25.0': tuple(sorted({**fams['tuned'][0], 'setpoint_c': 25.0}.items())),
        'pmv@+0.30': tuple(sorted({**fams['pmv'][0], 'setpoint_pmv': 0.3}.items())),
    }
    for name, law in laws.items():
        meas = 'vehicle' if dict(law).get('feedback') == 'pmv' else 'full'
        out = {}
        for door, ov in (
            ('auto', (('door_mode', 'auto'),)),
            ('recirc', (('door_mode', 'fixed'), ('door_fixed_share', 1.0))),
        ):
            r = simulate(sc, 'baseline', SimSettings(progress=False, measurements=meas, strategy_overrides=law + ov))
            ts = r.timeseries
            dt = float(ts['t_s'][1] - ts['t_s'][0])
            e_kwh = float(np.sum(ts['p_comp_w'] + ts['p_blower_w'] + ts['p_cond_fan_w'])) * dt / 3.6e6
            fresh = (1.0 - ts['recirc_share']) * ts['mdot_bl_kgps']
            out[door] = (e_kwh, float(np.sum(fresh) * dt), ts)
        e_auto, m_auto, ts = out['auto']
        e_rec, _, ts_rec = out['recirc']
        # least fresh air: full recirculation until the limit, then hold it (leakage at the drive's speed)
        dt = float(ts['t_s'][1] - ts['t_s'][0])
        x, m_min = co2_kgkg_from_ppm(float(ts['co2_cab_ppm'][0]) - amb), 0.0
        for k in range(len(ts['t_s'])):
            leak = leakage_kgps(p.infiltration_0_kgps, p.infiltration_per_mps_kgps, float(ts['speed_mps'][k]))
            need = max(0.0, g / dx_lim - leak) if x >= dx_lim - 1e-12 else 0.0
            need = min(need, float(ts['mdot_bl_kgps'][k]))
            x += dt / m_air * (g - (need + leak) * x)
            x = min(x, dx_lim)
            m_min += need * dt
        price = (e_auto - e_rec) / m_auto
        e_best = e_rec + price * m_min
        print(
            f'{sc.name} {name}: E_auto {e_auto:.4f} kWh (CO2 max {ts["co2_cab_ppm"].max():.0f} ppm), '
            f'E_recirc {e_rec:.4f} kWh ({ts_rec["co2_cab_ppm"].max():.0f} ppm); fresh air auto {m_auto:.1f} kg, '
            f'least {m_min:.1f} kg; price {1000 * price:.2f} Wh/kg; perfect door {e_best:.4f} kWh: '
            f'{100 * (e_auto - e_best) / e_auto:.1f} % below the logic'
        )
