"""Scenarios several test files share (plain data; each test writes or loads it as it needs)."""

BEYOND_THE_CYCLE = {
    'name': 'beyond_the_cycle',
    'drive_cycle': 'sc03',
    'duration_s': 20,
    'weather': {'time_s': [0, 600], 't_amb_c': 60.0, 'solar_wm2': 1400.0, 'rh': 0.05},
    'occupant': {'met': 1.2, 'clo': 0.5},
    'comfort_bounds': {'time_s': [0, 30, 300], 'pmv_lb': -0.5, 'pmv_ub': [3.0, 3.0, 0.5]},
    'initial': {'t_cab_c': 70.0, 'rh_cab': 0.1},
}
"""60 degC air, 1400 W/m2, the cabin soaked at 70 degC: the refrigerant cycle leaves its tables within seconds
(step 2 of the compiled plant; docs/scenarios.md, "What the plant can simulate")."""


def write_stale_sc03(directory, co2_limit_ppm: float = 450.0):
    """``directory/sc03_stale.yaml``: SC03 with the cabin at 900 ppm CO2 and a limit of ``co2_limit_ppm`` [ppm].

    SC03's ambient CO2 (425 ppm) is below a 450-ppm limit, so a run may or may not bring the cabin under it:
    the runs that keep recirculating break it. Returns the file's path.
    """
    from pathlib import Path

    import yaml

    from ceco_bringup import provenance

    directory = Path(directory)
    data = yaml.safe_load(provenance.copy_scenario('sc03', directory / 'copy').read_text())
    data['name'] = 'sc03_stale'
    data.setdefault('initial', {})['co2_cab_ppm'] = 900.0
    data['air_quality'] = {**data.get('air_quality', {}), 'co2_limit_ppm': co2_limit_ppm}
    path = directory / 'sc03_stale.yaml'
    path.write_text(yaml.safe_dump(data))
    return path
