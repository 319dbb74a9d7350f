"""Tests of the occupant comfort layer (ceco_core.cabin_comfort): scored PMV, draught, fog margin."""

import dataclasses

import casadi
import numpy as np
import pytest

from ceco_core import cabin_comfort as cc
from ceco_core import psychro
from ceco_core.comfort import pmv
from ceco_core.occupant import occupant_air
from ceco_core.scenario_types import SunGeometry
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.scenario_plant import ScenarioPlant
from ceco_v2x_preview.scenario import load_scenario

STATE = dict(
    t_cab_c=np.array([45.0, 30.0, 25.0]),
    t_vent_c=np.array([40.0, 8.0, 10.0]),
    mdot_bl_kgps=np.array([0.05, 0.17, 0.08]),
)


def test_one_glazing_transmittance_and_scenario_geometry():
    assert PlantParams().tau_glass == cc.GLAZING_TAU == cc.ComfortParams().solar.glazing_tau == 0.45
    assert PlantParams().u_shell_in_wm2k == cc.ComfortParams().u_shell_in_wm2k
    sc = load_scenario("sc03")
    p = cc.comfort_params_for(sc)
    assert (p.solar.altitude_deg, p.solar.sharp_deg) == (60.0, 0.0)  # defaults: sun ahead, 60 deg
    # the sun's azimuth relative to the heading: sun in the east, driving north -> from the right (90 deg)
    east = dataclasses.replace(sc, sun=SunGeometry(altitude_deg=30.0, azimuth_deg=90.0, heading_deg=0.0))
    assert cc.comfort_params_for(east).solar.sharp_deg == 90.0
    # W_rad at 850 W/m2 with the defaults: 0.67 * 0.696 * 0.262 * 0.45 * 0.5 * 850
    assert cc.cabin_w_rad_wm2(850.0, p) == pytest.approx(23.366, abs=1e-3)
    assert cc.cabin_w_rad_wm2(850.0, cc.comfort_params_for(east)) < cc.cabin_w_rad_wm2(850.0, p)
    # a plant with other glazing scores with that glazing (one value for physics and comfort)
    tinted = ScenarioPlant(sc, 1.0, dataclasses.replace(PlantParams(), tau_glass=0.3))
    assert tinted.comfort.solar.glazing_tau == 0.3
    with pytest.raises(ValueError, match="sharp_deg"):
        cc.SolarParams(sharp_deg=200.0).validate()
    with pytest.raises(ValueError, match="met"):
        dataclasses.replace(p, met=-1.0).validate()


def test_cabin_pmv_is_iso_pmv_of_the_occupant_environment_and_casadi_agrees():
    params = cc.ComfortParams()
    t_mr = np.array([55.0, 35.0, 27.0])
    w_rad = np.array([23.0, 23.0, 0.0])
    got = cc.cabin_pmv(**STATE, t_mr_c=t_mr, w_rad_wm2=w_rad, pa_pa=1200.0, params=params)
    air = occupant_air(**STATE, params=params.air)
    direct = pmv(ta_c=air.ta_occ_c, tr_c=t_mr, vel_mps=air.vel_occ_mps, pa_pa=1200.0, met=1.2, clo=0.5, w_rad_wm2=w_rad)
    np.testing.assert_allclose(got, direct, atol=1e-12)
    syms = [casadi.SX.sym(k) for k in ("t_cab", "t_vent", "mdot", "t_mr", "w_rad", "pa")]
    f = casadi.Function(
        "pmv",
        syms,
        [
            cc.cabin_pmv(
                t_cab_c=syms[0],
                t_vent_c=syms[1],
                mdot_bl_kgps=syms[2],
                t_mr_c=syms[3],
                w_rad_wm2=syms[4],
                pa_pa=syms[5],
                params=params,
            )
        ],
    )
    for i in range(3):
        args = [STATE["t_cab_c"][i], STATE["t_vent_c"][i], STATE["mdot_bl_kgps"][i], t_mr[i], w_rad[i], 1200.0]
        assert float(f(*args)) == pytest.approx(float(got[i]), abs=1e-10)
    # more cold air lowers PMV, the sun and humidity raise it
    base = dict(t_cab_c=26.0, t_vent_c=8.0, t_mr_c=33.0, w_rad_wm2=20.0, pa_pa=900.0, params=params)
    flows = cc.cabin_pmv(mdot_bl_kgps=np.array([0.05, 0.1, 0.17]), **base)
    assert np.all(np.diff(flows) < -0.05)
    assert cc.cabin_pmv(mdot_bl_kgps=0.1, **{**base, "pa_pa": 1700.0}) - cc.cabin_pmv(
        mdot_bl_kgps=0.1, **base
    ) == pytest.approx(0.16, abs=0.04)  # the paper's 1700 Pa against a dry cabin's 900 Pa


def test_evaluate_cabin_comfort_series():
    params = cc.ComfortParams()
    meas = dict(t_cab_c=25.7, t_vent_c=6.9, t_int_c=37.4, t_shell_c=36.8, t_glass_c=36.3, rh_cab=0.26)
    c = cc.evaluate_cabin_comfort(**meas, mdot_bl_kgps=0.113, solar_wm2=650.0, params=params)
    pa = float(psychro.vapour_pressure_pa(25.7, 0.26))
    assert float(c.pa_pa) == pytest.approx(pa, rel=1e-12)
    assert float(c.t_dew_c) == pytest.approx(float(psychro.dew_point_c(pa)), abs=1e-12)
    assert float(c.fog_margin_k) == pytest.approx(36.3 - float(c.t_dew_c), abs=1e-12)
    assert 4.0 < float(c.t_dew_c) < 6.0  # 25.7 degC / 26 % RH: dew point ~5 degC
    # the comfort-zone state: body-average speed about half the paper's 0.70 m/s, T_mr below T_int
    assert 0.3 < float(c.vel_occ_mps) < 0.36 and float(c.t_mr_c) < 37.4 - 1.5
    assert float(c.dr_pct) == 100.0 and float(c.vel_jet_mps) > 2.0  # the face jet: DR saturated (exact ISO)
    assert bool(c.iso7730_valid)
    paper = cc.evaluate_cabin_comfort(**meas, mdot_bl_kgps=0.113, solar_wm2=650.0, params=params, pa_pa=cc.PAPER_PA_PA)
    assert float(paper.pmv) - float(c.pmv) == pytest.approx(0.19, abs=0.05)
    # the scored constant is the PMV's only: dew point and fog margin stay the cabin air's
    assert float(paper.pa_pa) == cc.PAPER_PA_PA
    assert (float(paper.t_dew_c), float(paper.fog_margin_k)) == (float(c.t_dew_c), float(c.fog_margin_k))
    # a hot-soaked cabin is computed and flagged outside ISO 7730
    hot = cc.evaluate_cabin_comfort(
        t_cab_c=43.0,
        t_vent_c=40.0,
        t_int_c=46.0,
        t_shell_c=48.0,
        t_glass_c=43.0,
        rh_cab=0.26,
        mdot_bl_kgps=0.17,
        solar_wm2=850.0,
        params=params,
    )
    assert not bool(hot.iso7730_valid) and float(hot.pmv) > 3.0


def test_draught_in_the_jet_and_its_uncapped_intensity():
    params = cc.ComfortParams()
    dr = cc.cabin_draught_pct(t_cab_c=25.0, t_vent_c=8.0, mdot_bl_kgps=np.array([0.05, 0.17]), params=params)
    assert np.allclose(dr, 100.0, atol=1e-6)
    raw = cc.cabin_draught_pct(
        t_cab_c=25.0, t_vent_c=8.0, mdot_bl_kgps=np.array([0.05, 0.17]), params=params, cap=False
    )
    assert 100.0 < raw[0] < raw[1]
    # no flow: the still air at 25 degC is not a draught
    still = cc.cabin_draught_pct(t_cab_c=25.0, t_vent_c=8.0, mdot_bl_kgps=0.0, params=params)
    assert float(still) < 15.0


def test_public_api_of_the_simulator_package():
    from ceco_plant_sim import comfort

    for name in (
        "pmv",
        "ppd",
        "cabin_pmv",
        "draught_rating",
        "evaluate_cabin_comfort",
        "ComfortParams",
        "comfort_params_for",
        "iso7730_validity",
    ):
        assert name in comfort.__all__ and callable(getattr(comfort, name))
    assert comfort.draught_rating(21.0, 0.7, 40.0) == pytest.approx(100.0)
