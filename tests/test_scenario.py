"""Scenario files: bundled data, interpolation conventions, validation."""

import copy
import math

import numpy as np
import pytest
import yaml

from ceco_v2x_preview.scenario import (
    Environment,
    ScenarioError,
    SunGeometry,
    list_drive_cycles,
    list_scenarios,
    load_drive_cycle,
    load_scenario,
    scenario_from_dict,
)

MI_M = 1609.344


def test_bundled_names():
    assert list_drive_cycles() == ["hwfet", "hwfet_udds", "sc03", "sc03_idle", "sc03_stop", "udds", "us06"]
    assert {"sc03", "udds", "hwfet", "us06", "sc03_mild", "tunnel", "sun_shade", "sc03_idle", "hwfet_udds"} <= set(
        list_scenarios()
    )


def test_constructed_cycles_are_their_recipes():
    """tools/compose_drive_cycles.py's pieces, sample by sample (and its comment header is skipped on load)."""
    sc03, udds, hwfet = (load_drive_cycle(n).speed_mps for n in ("sc03", "udds", "hwfet"))
    idle = load_drive_cycle("sc03_idle").speed_mps
    assert idle.size == 901 and np.array_equal(idle[:361], sc03[:361]) and np.array_equal(idle[661:], sc03[361:])
    assert np.all(idle[350:671] == 0.0)  # SC03's stop at 350 s stretched to 320 s
    hu = load_drive_cycle("hwfet_udds").speed_mps
    assert hu.size == 1271 and np.array_equal(hu[:766], hwfet) and np.array_equal(hu[766:], udds[1:506])
    stop = load_drive_cycle("sc03_stop").speed_mps
    assert stop.size == 1081 and np.array_equal(stop[:601], sc03) and np.array_equal(stop[841:], sc03[1:241])
    assert np.all(stop[594:841] == 0.0)


def test_previewable_disturbance_scenarios():
    tun = load_scenario("tunnel")
    assert tun.duration_s == 900 and tun.env_at(470.0).solar_wm2 > 700.0
    assert tun.env_at(482.0).solar_wm2 == 0.0 and tun.env_at(660.0).solar_wm2 == 0.0
    assert tun.env_at(670.0).solar_wm2 > 600.0
    sh = load_scenario("sun_shade")
    assert [sh.env_at(t).solar_wm2 for t in (500.0, 700.0, 850.0)] == pytest.approx([150.0, 655.5, 150.0], abs=0.1)
    stop = load_scenario("sc03_stop")
    assert stop.pmv_bounds(700.0)[1] == 3.0 and stop.pmv_bounds(900.0)[1] == 0.5 and stop.env_at(700.0).speed_mps == 0
    assert load_scenario("hwfet_udds").duration_s == 1270 and load_scenario("sc03_idle").duration_s == 900


@pytest.mark.parametrize(
    "name, duration_s, distance_mi, vmax_mph",
    [("sc03", 600, 3.58, 54.8), ("udds", 1369, 7.45, 56.7), ("hwfet", 765, 10.26, 59.9), ("us06", 600, 8.01, 80.3)],
)
def test_drive_cycles_match_epa_figures(name, duration_s, distance_mi, vmax_mph):
    cyc = load_drive_cycle(name)
    assert cyc.duration_s == duration_s
    assert np.all(np.diff(cyc.time_s) == 1.0)
    assert cyc.distance_m / MI_M == pytest.approx(distance_mi, abs=0.006)
    assert cyc.speed_mps.max() == pytest.approx(vmax_mph * 0.44704, rel=1e-12)
    sc = load_scenario(name)
    assert sc.duration_s == duration_s


def test_sc03_conditions_and_interpolation():
    sc = load_scenario("sc03")
    e0 = sc.env_at(0.0)
    assert isinstance(e0, Environment)
    assert (e0.t_amb_c, e0.solar_wm2, e0.rh, e0.speed_mps) == (35.0, 850.0, 0.4, 0.0)
    assert sc.env_at(300.0).solar_wm2 == pytest.approx(725.0)
    assert sc.env_at(600.0).solar_wm2 == pytest.approx(600.0)
    # Linear interpolation of the 1 Hz trace between two samples.
    cyc = sc.drive_cycle
    i = int(np.argmax(np.abs(np.diff(cyc.speed_mps))))  # steepest step of the cycle
    v_mid = 0.5 * (cyc.speed_mps[i] + cyc.speed_mps[i + 1])
    assert sc.env_at(cyc.time_s[i] + 0.5).speed_mps == pytest.approx(v_mid, rel=1e-12)
    assert sc.speed_mps(cyc.time_s[i] + 0.25) == pytest.approx(0.75 * cyc.speed_mps[i] + 0.25 * cyc.speed_mps[i + 1])
    # Beyond the end: everything holds the last value.
    late = sc.env_at(700.0)
    assert (late.t_amb_c, late.solar_wm2, late.speed_mps) == (35.0, 600.0, float(cyc.speed_mps[-1]))
    assert sc.occupant.met == 1.2 and sc.occupant.clo == 0.5
    assert sc.control.control_period_s == 5.0 and sc.control.horizon_steps == 6
    assert sc.initial.t_int_c > sc.initial.t_cab_c > sc.env_at(0.0).t_amb_c


def test_vectorised_env_and_previews():
    sc = load_scenario("udds")
    t = np.array([[0.0, 10.5], [100.0, 2000.0]])
    env = sc.env_at(t)
    assert env.speed_mps.shape == (2, 2) and env.solar_wm2.shape == (2, 2)
    assert env.speed_mps[0, 1] == pytest.approx(sc.env_at(10.5).speed_mps)
    series = sc.env_series(5.0)
    assert series.t_amb_c.shape == (1,)
    wp = sc.weather_preview(100.0, 5.0, 7)
    np.testing.assert_allclose(wp.t_s, 100.0 + 5.0 * np.arange(7))
    np.testing.assert_allclose(wp.solar_wm2, 850.0 - 250.0 * wp.t_s / 1369.0)
    np.testing.assert_allclose(sc.speed_preview(100.0, 5.0, 7), [sc.speed_mps(x) for x in wp.t_s])
    with pytest.raises(ValueError, match="t_s"):
        sc.env_at(-1.0)
    with pytest.raises(ValueError, match="step_s"):
        sc.weather_preview(0.0, 0.0, 3)
    assert sc.time_grid(1.0).size == 1369


def test_pmv_bounds_piecewise_linear():
    sc = load_scenario("sc03_hotsoak")
    assert sc.pmv_bounds(0.0) == (-0.5, 3.0)
    assert sc.pmv_bounds(270.0) == (-0.5, 3.0)
    assert sc.pmv_bounds(465.0) == pytest.approx((-0.5, 1.75))
    lb, ub = sc.pmv_bounds(np.array([600.0, 660.0]))
    np.testing.assert_allclose(ub, [0.5 + 2.5 * 60.0 / 390.0, 0.5])
    assert load_scenario("udds").pmv_bounds(1000.0) == (-0.5, 0.5)
    np.testing.assert_allclose(lb, [-0.5, -0.5])
    # sc03 (10-minute soak): 3 to 30 s, linear to 0.5 at 300 s, then 0.5.
    sc03 = load_scenario("sc03")
    assert sc03.pmv_bounds(165.0) == pytest.approx((-0.5, 1.75))
    assert sc03.pmv_bounds(450.0) == (-0.5, 0.5)


def test_mild_day_is_milder():
    hot, mild = load_scenario("sc03"), load_scenario("sc03_mild")
    assert mild.env_at(0.0).t_amb_c == 28.0 and mild.env_at(0.0).solar_wm2 == 400.0
    assert mild.initial.t_cab_c < hot.initial.t_cab_c


def _sc03_dict():
    from importlib import resources

    text = resources.files("ceco_v2x_preview").joinpath("data", "scenarios", "sc03.yaml").read_text()
    return yaml.safe_load(text)


# Water saturation pressure [Pa] (IAPWS-95 via CoolProp 8.0.0,
# PropsSI('P', 'T', t + 273.15, 'Q', 0, 'Water')), kept as numbers so the test
# does not pay CoolProp's import time.
_PSAT_PA = {35.0: 5629.016, 57.0: 17335.643}


def test_initial_defaults_and_humidity():
    d = _sc03_dict()
    d["initial"] = {"t_cab_c": 57.0}
    sc = scenario_from_dict(d)
    ini = sc.initial
    assert ini.t_int_c == ini.t_shell_c == ini.t_glass_c == ini.t_evap_c == 57.0
    # InitialState is also a read-only mapping (the plant takes dicts too).
    assert dict(ini) == {
        "t_cab_c": 57.0,
        "t_int_c": 57.0,
        "t_shell_c": 57.0,
        "t_glass_c": 57.0,
        "t_evap_c": 57.0,
        "rh_cab": ini.rh_cab,
        "co2_cab_ppm": 425.0,  # the ambient's (the scenario's default air_quality)
    }
    assert "t_glass_c" in ini and ini.get("t_seat_c") is None
    # Same vapour pressure as the ambient air (35 degC, 40 %).
    assert ini.rh_cab * _PSAT_PA[57.0] == pytest.approx(0.4 * _PSAT_PA[35.0], rel=0.005)
    assert 0.12 < ini.rh_cab < 0.14


def _mutate(path, value):
    d = _sc03_dict()
    node = d
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


_DELETE = object()


@pytest.mark.parametrize(
    "path, value, field",
    [
        (("weather",), _DELETE, "weather: missing"),
        (("weather", "rh"), [0.4, 1.2], "weather.rh[1]"),
        (("weather", "solar_wm2"), [850.0, 700.0, 600.0], "weather.solar_wm2: length"),
        (("weather", "time_s"), [0, 0], "weather.time_s: must be strictly increasing"),
        (("weather", "t_amb_c"), [35.0, float("nan")], "weather.t_amb_c[1]"),
        (("weather", "t_amb_c"), [95.0, 95.0], "weather.t_amb_c[0]"),  # degF by mistake
        (("occupant", "met"), 0.0, "occupant.met"),
        (("occupant", "clo"), _DELETE, "occupant.clo: missing"),
        (("drive_cycle",), "wltp", "drive_cycle: unknown drive cycle"),
        (("comfort_bounds", "pmv_lb"), [-0.5, -0.5, 0.6, -0.5], "comfort_bounds.pmv_lb[2]"),
        (("comfort_bounds", "pmv_ub"), [3.0, 0.5], "comfort_bounds.pmv_ub: length"),
        (("comfort_bounds", "time_s"), [0, 270, 50], "comfort_bounds.time_s"),
        (("initial", "t_cab_c"), _DELETE, "initial.t_cab_c: missing"),
        (("initial", "rh_cab"), 40.0, "initial.rh_cab"),
        (("control", "horizon_steps"), 0, "control.horizon_steps"),
        (("control", "control_period_s"), -5, "control.control_period_s"),
        (("seed",), -1, "seed"),
        (("duration_s",), -10, "duration_s"),
        (("weather", "wind_mps"), [1, 2], "weather.wind_mps: unknown field"),
        (("name",), "", "name"),
        # found by testing unseen scenarios: each was accepted and then failed in the run or gave a wrong number
        (("weather", "rh"), 0.0, "weather.rh[0]: must satisfy 0.0 < value <= 1.0, got 0.0"),  # dew point -inf
        (("initial", "rh_cab"), 0.0, "initial.rh_cab: must satisfy 0.0 < value <= 1.0, got 0.0"),
        (("comfort_bounds", "pmv_ub"), 5.0, "comfort_bounds.pmv_ub[0]: must satisfy -3.0 <= value <= 3.0, got 5.0"),
        (
            ("duration_s",),
            123.7,
            "duration_s: 123.7 s is not a whole number (>= 2) of plant steps (1 s): give e.g. 123",
        ),
        (("duration_s",), 1, "duration_s: 1 s is not a whole number (>= 2) of plant steps (1 s): give e.g. 2"),
        (("weather", "time_s"), 0, "weather.time_s: must be a list of numbers, got 0"),
    ],
)
def test_invalid_scenarios_name_the_field(path, value, field):
    d = _mutate(path, value)
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(d)
    assert isinstance(err.value, ValueError)
    assert str(err.value).startswith(field.split(":")[0])
    assert field in str(err.value)


def test_the_control_block_takes_the_nodes_ranges():
    """A scenario's Ts and Np are held to the range every node and every verb's flags take (0.1..300 s, 1..60),
    and Ts to whole plant steps: a scenario with Ts 600 s ran in the simulator, where `ceco run`'s nodes refuse
    it."""
    for key, value, message in [
        ("control_period_s", 600.0, "control.control_period_s: must satisfy 0.1 <= value <= 300.0, got 600.0"),
        ("control_period_s", 0.05, "control.control_period_s: must satisfy 0.1 <= value <= 300.0, got 0.05"),
        # and a whole number of plant steps (1 s): the simulator and plant_node refused 0.1 s only when run
        (
            "control_period_s",
            0.1,
            "control.control_period_s: 0.1 s is not a whole number of plant steps (1 s, the simulator's and "
            "plant_node's)",
        ),
        (
            "control_period_s",
            7.5,
            "control.control_period_s: 7.5 s is not a whole number of plant steps (1 s, the simulator's and "
            "plant_node's)",
        ),
        ("horizon_steps", 61, "control.horizon_steps: must be in 1..60, got 61"),
        ("horizon_steps", 6.0, "control.horizon_steps: must be an integer, got 6.0"),
    ]:
        with pytest.raises(ScenarioError) as err:
            scenario_from_dict(_mutate(("control", key), value))
        assert str(err.value) == message
    sc = scenario_from_dict(_mutate(("control",), {"control_period_s": 300.0, "horizon_steps": 60}))
    assert (sc.control.control_period_s, sc.control.horizon_steps) == (300.0, 60)
    sc = scenario_from_dict(_mutate(("control",), {"control_period_s": 1.0, "horizon_steps": 1}))
    assert (sc.control.control_period_s, sc.control.horizon_steps) == (1.0, 1)
    # a run's timing: each flag where given, else the scenario's (None and 0 both mean "not given")
    assert sc.control.timing() == (1.0, 1) and sc.control.timing(None, 0) == (1.0, 1)
    assert sc.control.timing(10.0) == (10.0, 1) and sc.control.timing(horizon_steps=12) == (1.0, 12)
    assert sc.control.timing(0.0, 24) == (1.0, 24)


def test_user_files_and_csv_cycles(tmp_path):
    (tmp_path / "cycles").mkdir()
    (tmp_path / "cycles" / "ramp.csv").write_text("time_s,speed_mps\n0,0\n10,10\n20,10\n")
    d = _sc03_dict()
    d.update(name="ramp", drive_cycle="cycles/ramp.csv")
    del d["duration_s"]
    (tmp_path / "ramp.yaml").write_text(yaml.safe_dump(d))
    sc = load_scenario(tmp_path / "ramp.yaml")
    assert sc.duration_s == 20.0  # defaults to the cycle's
    assert sc.speed_mps(5.0) == pytest.approx(5.0)
    assert sc.drive_cycle.distance_m == pytest.approx(150.0)

    (tmp_path / "bad.csv").write_text("time_s,speed_kmh\n0,0\n1,1\n")
    with pytest.raises(ScenarioError, match="header"):
        load_drive_cycle(str(tmp_path / "bad.csv"))
    (tmp_path / "neg.csv").write_text("time_s,speed_mph\n0,0\n1,-1\n")
    with pytest.raises(ScenarioError, match="drive_cycle"):
        load_drive_cycle(str(tmp_path / "neg.csv"))
    # the limit in the column's own unit (it said "speed_mph must be within 0..70.0 m/s")
    (tmp_path / "fast.csv").write_text("time_s,speed_mph\n0,0\n1,160\n")
    with pytest.raises(ScenarioError) as err:
        load_drive_cycle(str(tmp_path / "fast.csv"))
    assert str(err.value).endswith("fast.csv: speed_mph must be within 0..156.6 mph (70 m/s)")
    # a cycle whose last time is not a whole second runs its whole plant steps, and the scenario says so
    (tmp_path / "cycles" / "odd.csv").write_text("time_s,speed_mps\n0,0\n10,10\n20.7,10\n")
    d.update(name="odd", drive_cycle="cycles/odd.csv")
    (tmp_path / "odd.yaml").write_text(yaml.safe_dump(d))
    assert load_scenario(tmp_path / "odd.yaml").duration_s == 20.0
    # a spreadsheet's CSV with a byte-order mark is read as without it; bytes that are not UTF-8 are one line
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbftime_s,speed_mps\r\n0,0\r\n10,10\r\n")
    assert load_drive_cycle(str(tmp_path / "bom.csv")).distance_m == pytest.approx(50.0)
    (tmp_path / "latin1.csv").write_bytes(b"time_s,speed_mps\n0,0\n1,1 \xb0\n")
    with pytest.raises(ScenarioError, match=r"latin1\.csv: not a UTF-8 text file \(invalid start byte at byte 25\)"):
        load_drive_cycle(str(tmp_path / "latin1.csv"))
    (tmp_path / "back.csv").write_text("time_s,speed_mph\n0,0\n2,1\n1,1\n")
    with pytest.raises(ScenarioError, match="strictly increasing"):
        load_drive_cycle(str(tmp_path / "back.csv"))
    (tmp_path / "broken.yaml").write_text("name: [unclosed\n")
    with pytest.raises(ScenarioError, match=r"broken\.yaml: not valid YAML at line 2, column 1: "):
        load_scenario(tmp_path / "broken.yaml")
    # a file that is not UTF-8 text: named, one line (it was a bare UnicodeDecodeError)
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe")
    with pytest.raises(ScenarioError, match=r"binary\.yaml: not a UTF-8 text file \(invalid start byte at byte 0\)"):
        load_scenario(tmp_path / "binary.yaml")
    with pytest.raises(ScenarioError, match="unknown scenario"):
        load_scenario("no_such_scenario")
    # a path that is not there is said as such, not as an unknown bundled name
    with pytest.raises(ScenarioError, match=r"mine\.yaml: no such file: give a scenario YAML file"):
        load_scenario(str(tmp_path / "mine.yaml"))
    with pytest.raises(ScenarioError, match="is a directory"):
        load_scenario(str(tmp_path) + "/")


def test_constant_written_as_one_number():
    d = copy.deepcopy(_sc03_dict())
    d["weather"]["rh"] = 0.3
    sc = scenario_from_dict(d)
    assert sc.env_at(123.0).rh == 0.3
    assert math.isclose(sc.env_at(600.0).rh, 0.3)


def test_cli_validates_and_summarises(tmp_path, capsys):
    from ceco_v2x_preview.scenario import main

    assert main(["sc03"]) == 0
    out = capsys.readouterr().out
    assert "solar 850 -> 600 W/m2" in out and "t_cab_c=43" in out
    bad = tmp_path / "bad.yaml"
    d = _sc03_dict()
    d["occupant"]["met"] = -1.0
    bad.write_text(yaml.safe_dump(d))
    assert main([str(bad)]) == 1
    assert "occupant.met" in capsys.readouterr().err


def test_sun_geometry_block():
    d = _sc03_dict()
    assert scenario_from_dict(d).sun == SunGeometry(60.0, 180.0, 180.0)  # defaults: sun ahead, 60 deg
    d["sun"] = {"altitude_deg": 35, "azimuth_deg": 250.0}
    sc = scenario_from_dict(d)
    assert (sc.sun.altitude_deg, sc.sun.azimuth_deg, sc.sun.heading_deg) == (35.0, 250.0, 180.0)
    assert isinstance(sc.sun.altitude_deg, float)
    for bad, field in (
        ({"altitude_deg": 95.0}, "sun.altitude_deg"),
        ({"heading_deg": -1.0}, "sun.heading_deg"),
        ({"zenith_deg": 10.0}, "sun.zenith_deg: unknown field"),
    ):
        d["sun"] = bad
        with pytest.raises(ScenarioError, match=field):
            scenario_from_dict(d)


def test_occupants_and_air_quality_fields():
    """Issue 21: occupants 1..5, ambient CO2, the limits, the sensor; defaults; each bad value names its field."""
    sc = scenario_from_dict(_sc03_dict())
    assert sc.occupants == 1 and sc.air_quality.co2_amb_ppm == 425.0 and sc.initial.co2_cab_ppm == 425.0
    assert sc.air_quality.limits.co2_limit_ppm == 1500.0 and sc.air_quality.limits.fog_margin_min_k == 3.0
    assert sc.air_quality.co2_sensor == "ndir" and sc.air_quality.co2_sensor_fail_s is None
    d = _sc03_dict()
    d.update(occupants=4, air_quality={"co2_amb_ppm": 450, "co2_limit_ppm": 1000, "co2_sensor": "none"})
    sc = scenario_from_dict(d)
    assert sc.occupants == 4 and sc.initial.co2_cab_ppm == 450.0  # default: the ambient's
    assert sc.air_quality.limits.co2_limit_ppm == 1000.0 and sc.air_quality.co2_sensor == "none"
    bad = [
        ({"occupants": 0}, "occupants: must be in 1..5"),
        ({"occupants": 6}, "occupants: must be in 1..5"),
        ({"occupants": 2.5}, "occupants: must be an integer"),
        ({"air_quality": {"co2_amb_ppm": 42.5}}, "air_quality.co2_amb_ppm"),  # percent for ppm by mistake
        ({"air_quality": {"co2_limit_ppm": 400}}, "air_quality.co2_limit_ppm"),
        ({"air_quality": {"co2_amb_ppm": 800, "co2_limit_ppm": 700}}, "air_quality.co2_limit_ppm"),
        ({"air_quality": {"fog_margin_min_k": -1}}, "air_quality.fog_margin_min_k"),
        ({"air_quality": {"co2_sensor": "laser"}}, "air_quality.co2_sensor"),
        ({"air_quality": {"co2_sensor_fail_s": float("nan")}}, "air_quality.co2_sensor_fail_s"),
        ({"air_quality": {"co2_ppm": 400}}, "air_quality.co2_ppm: unknown field"),
    ]
    for change, field in bad:
        d = _sc03_dict()
        d.update(change)
        with pytest.raises(ScenarioError) as err:
            scenario_from_dict(d)
        assert str(err.value).startswith(field.split(":")[0]) and field in str(err.value), (change, str(err.value))
    d = _sc03_dict()
    d["initial"] = {**d["initial"], "co2_cab_ppm": 100.0}
    with pytest.raises(ScenarioError, match="initial.co2_cab_ppm"):
        scenario_from_dict(d)


@pytest.mark.parametrize('text, fix', [('1e9', '1.0e+9'), ('1.5e3', '1.5e+3'), ('-2E-3', '-2.0e-3')])
def test_a_number_yaml_reads_as_text_says_how_to_write_it(tmp_path, text, fix):
    """PyYAML (YAML 1.1) reads 1e9 and 1.5e3 as strings; the error says so and gives the form it reads as a number
    (and that form is read as the same number)."""
    import pathlib

    import ceco_v2x_preview

    bundled = pathlib.Path(ceco_v2x_preview.__file__).parent / 'data' / 'scenarios' / 'sc03.yaml'
    doc = yaml.safe_load(bundled.read_text(encoding='utf-8'))
    doc['duration_s'] = text
    path = tmp_path / 'mine.yaml'
    path.write_text(yaml.safe_dump(doc).replace(f"'{text}'", text))
    with pytest.raises(ScenarioError, match=f'YAML reads {text} as text: write {fix}'.replace('+', r'\+')):
        load_scenario(str(path))
    assert yaml.safe_load(f'x: {fix}')['x'] == float(text)


def test_one_number_yaml_reads_as_text_says_how_to_write_it(tmp_path):
    """A series written as one number, ``solar_wm2: 1e3``, is text to PyYAML (YAML 1.1): refused with the form it
    reads as a number, as a list's entry is (it said only 'must be a list of numbers (or one number)' before)."""
    doc = _sc03_dict()
    doc['weather'] = {**doc['weather'], 'solar_wm2': 1000.0}
    path = tmp_path / 'mine.yaml'
    path.write_text(yaml.safe_dump(doc).replace('solar_wm2: 1000.0', 'solar_wm2: 1e3'), encoding='utf-8')
    with pytest.raises(ScenarioError) as err:
        load_scenario(str(path))
    assert str(err.value) == (
        "weather.solar_wm2: must be a list of numbers (or one number), got '1e3' (YAML reads 1e3 as text: write 1.0e+3)"
    )


def test_a_csv_drive_cycle_not_found_names_the_path_looked_for(tmp_path):
    """A drive cycle given as a CSV path where no file is: 'not found' with the path it looked at (relative to the
    scenario file), not 'unknown drive cycle ... or a CSV path'; a name that is no CSV path keeps that message."""
    doc = _sc03_dict()
    doc['drive_cycle'] = 'cycles/mine.csv'
    path = tmp_path / 'mine.yaml'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    with pytest.raises(ScenarioError) as err:
        load_scenario(str(path))
    looked = tmp_path / 'cycles' / 'mine.csv'
    assert str(err.value) == f"drive_cycle: CSV file 'cycles/mine.csv' not found (looked for {looked})"
    (tmp_path / 'cycles' / 'mine.csv').mkdir(parents=True)
    with pytest.raises(ScenarioError, match=r"^drive_cycle: CSV file 'cycles/mine.csv' is a directory, not a file"):
        load_scenario(str(path))
    doc['drive_cycle'] = 'wltp'
    path.write_text(yaml.safe_dump(doc), encoding='utf-8')
    with pytest.raises(ScenarioError, match=r"^drive_cycle: unknown drive cycle 'wltp': use one of \["):
        load_scenario(str(path))
