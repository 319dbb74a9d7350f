"""What a perfect door could save on a drive with four occupants (issue 21 part 2, docs/results.md "Air quality").

For a controller: E_door (with its door), E_rec (full recirculation), the outside air it let in (M = sum (1 - r)
mdot_bl dt) and the least outside air that keeps the CO2 at or under the limit on the same blower flow (M_min: full
recirculation until the cabin reaches the limit, then exactly the flow that holds it: n g / (X_lim - X_amb) -
leakage(V)). The price of outside air p = (E_door - E_rec) / M [kWh/kg]; a perfect door spends E_rec + p M_min.

``python docs/studies/aq-4p/door_bound.py``: the tuned PI at 25 degC and the tuned PMV PI at +0.30 (gains from the
benchmark's baselines.yaml) with the production door logic against full recirculation, on UDDS with four occupants;
``--nmpc``: ceco-pmv on hot-commute-4p (seed 0, medium previews), the door not commanded with the plant's default
share 0.8 against 1.0 (``PlantParams.recirc_fraction``).
"""


def _energy_kwh_and_air_kg(ts):
    import numpy as np

    dt = float(ts['t_s'][1] - ts['t_s'][0])
    e = float(np.sum(ts['p_comp_w'] + ts['p_blower_w'] + ts['p_cond_fan_w'])) * dt / 3.6e6
    return e, float(np.sum((1.0 - ts['recirc_share']) * ts['mdot_bl_kgps'])) * dt


def _least_air_kg(ts, sc) -> float:
    from ceco_core.air_quality import co2_generation_kgps, co2_kgkg_from_ppm, leakage_kgps
    from ceco_plant_sim.plant_params import PlantParams

    p = PlantParams()
    m_air = p.rho_air_kgm3 * p.cabin_volume_m3
    g = sc.occupants * co2_generation_kgps(p.occ_met)
    amb = float(sc.air_quality.co2_amb_ppm)
    dx_lim = co2_kgkg_from_ppm(float(sc.air_quality.co2_limit_ppm) - amb)
    dt = float(ts['t_s'][1] - ts['t_s'][0])
    x, m_min = co2_kgkg_from_ppm(float(ts['co2_cab_ppm'][0]) - amb), 0.0
    for k in range(len(ts['t_s'])):
        leak = leakage_kgps(p.infiltration_0_kgps, p.infiltration_per_mps_kgps, float(ts['speed_mps'][k]))
        need = min(max(0.0, g / dx_lim - leak) if x >= dx_lim - 1e-12 else 0.0, float(ts['mdot_bl_kgps'][k]))
        x = min(x + dt / m_air * (g - (need + leak) * x), dx_lim)
        m_min += need * dt
    return m_min


def _report(name, ts_door, ts_rec, sc) -> None:
    e_door, m_door = _energy_kwh_and_air_kg(ts_door)
    e_rec, _ = _energy_kwh_and_air_kg(ts_rec)
    m_min = _least_air_kg(ts_door, sc)
    price = (e_door - e_rec) / m_door
    e_best = e_rec + price * m_min
    print(
        f'{name}: E {e_door:.4f} kWh (CO2 max {ts_door["co2_cab_ppm"].max():.0f} ppm), full recirculation '
        f'{e_rec:.4f} kWh ({ts_rec["co2_cab_ppm"].max():.0f} ppm); outside air {m_door:.1f} kg, least {m_min:.1f} kg; '
        f'price {1000 * price:.2f} Wh/kg; perfect door {e_best:.4f} kWh: {100 * (e_door - e_best) / e_door:.1f} % less'
    )


if __name__ == '__main__':
    import dataclasses
    import sys

    from ceco_bringup.benchmark.cases import load_case
    from ceco_bringup.benchmark.runner import load_baselines
    from ceco_controller.closed_loop import SimSettings, simulate
    from ceco_v2x_preview.preview import parse_quality
    from ceco_v2x_preview.scenario import load_scenario

    if '--nmpc' in sys.argv:
        sc = load_case('hot-commute-4p').load_scenario()
        q = parse_quality('uncertain:medium')
        runs = [
            simulate(
                sc,
                'ceco-pmv',
                SimSettings(progress=False, seed=0, preview_quality=q, plant_overrides=(('recirc_fraction', s),)),
            ).timeseries
            for s in (0.8, 1.0)
        ]
        _report('ceco-pmv (door not commanded, 0.8)', runs[0], runs[1], sc)
    else:
        sc = dataclasses.replace(load_scenario('udds'), occupants=4)
        fams = load_baselines().families
        for name, law, fb in (('tuned@25.0', 'tuned', 'setpoint_c'), ('pmv@+0.30', 'pmv', 'setpoint_pmv')):
            ov = tuple(sorted({**fams[law][0], fb: 25.0 if law == 'tuned' else 0.3}.items()))
            doors = ((('door_mode', 'auto'),), (('door_mode', 'fixed'), ('door_fixed_share', 1.0)))
            ts = [
                simulate(
                    sc, 'baseline', SimSettings(progress=False, measurements=fams[law][1], strategy_overrides=ov + d)
                ).timeseries
                for d in doors
            ]
            _report(f'udds, 4 occupants, {name} with the door logic', ts[0], ts[1], sc)
