"""ceco-pmv on hot-commute-4p (door not commanded: the plant's default share) and what a perfect door would add.

Runs ceco-pmv (seed 0, medium previews) with the plant's default share 0.8 and with 1.0 (PlantParams.recirc_fraction),
then the same estimate as door_bound.py: the price of fresh air from the two runs, the least fresh air that holds
the CO2 limit on its own blower flow, the energy of a perfect door.
"""

if __name__ == '__main__':
    import numpy as np

    from ceco_bringup.benchmark.cases import load_case
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_core.air_quality import co2_generation_kgps, co2_kgkg_from_ppm, leakage_kgps
    from ceco_plant_sim.plant_params import PlantParams
    from ceco_v2x_preview.preview import parse_quality

    case = load_case('hot-commute-4p')
    sc = case.load_scenario()
    p = PlantParams()
    m_air = p.rho_air_kgm3 * p.cabin_volume_m3
    g = sc.occupants * co2_generation_kgps(p.occ_met)
    lim, amb = float(sc.air_quality.co2_limit_ppm), float(sc.air_quality.co2_amb_ppm)
    dx_lim = co2_kgkg_from_ppm(lim - amb)
    out = {}
    for share in (0.8, 1.0):
        st = SimSettings(
            progress=False,
            seed=0,
            preview_quality=parse_quality('uncertain:medium'),
            plant_overrides=(('recirc_fraction', share),),
        )
        ts = simulate(sc, 'ceco-pmv', st).timeseries
        dt = float(ts['t_s'][1] - ts['t_s'][0])
        e = float(np.sum(ts['p_comp_w'] + ts['p_blower_w'] + ts['p_cond_fan_w'])) * dt / 3.6e6
        fresh = float(np.sum((1.0 - ts['recirc_share']) * ts['mdot_bl_kgps'])) * dt
        out[share] = (e, fresh, ts)
        print(
            f'ceco-pmv, share {share}: E {e:.4f} kWh, CO2 max {ts["co2_cab_ppm"].max():.0f} ppm, '
            f'fresh air {fresh:.1f} kg'
        )
    (e8, m8, ts), (e10, _, _) = out[0.8], out[1.0]
    dt = float(ts['t_s'][1] - ts['t_s'][0])
    x, m_min = co2_kgkg_from_ppm(float(ts['co2_cab_ppm'][0]) - amb), 0.0
    for k in range(len(ts['t_s'])):
        leak = leakage_kgps(p.infiltration_0_kgps, p.infiltration_per_mps_kgps, float(ts['speed_mps'][k]))
        need = max(0.0, g / dx_lim - leak) if x >= dx_lim - 1e-12 else 0.0
        need = min(need, float(ts['mdot_bl_kgps'][k]))
        x = min(x + dt / m_air * (g - (need + leak) * x), dx_lim)
        m_min += need * dt
    price = (e8 - e10) / m8
    e_best = e10 + price * m_min
    print(
        f'least fresh air {m_min:.1f} kg; price {1000 * price:.2f} Wh/kg; perfect door {e_best:.4f} kWh '
        f'({100 * (e8 - e_best) / e8:.1f} % below ceco-pmv at 0.8)'
    )
