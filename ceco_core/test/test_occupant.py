"""Tests of the environment at the occupant (ceco_core.occupant): vent jets, body-average air, T_mr."""

import dataclasses

import casadi
import numpy as np
import pytest

from ceco_core.occupant import (
    OccupantAirParams,
    RadiantParams,
    mean_radiant_temperature_c,
    occupant_air,
    shell_inside_surface_c,
    vent_speed_mps,
)


def test_vent_speed_and_the_documented_ranges():
    p = OccupantAirParams()
    # ideal-gas density at 7 degC: 101325 / (287.05 * 280.15) = 1.2600 kg/m3 over 0.03 m2
    assert float(vent_speed_mps(0.17, 7.0, p)) == pytest.approx(0.17 / (1.26000 * 0.03), rel=1e-4)
    # free-jet centreline ratio 6.5 sqrt(0.0075) / 0.65 = 0.866
    assert p.phi_exact == pytest.approx(0.8660, abs=1e-4)
    lo = occupant_air(t_cab_c=25.0, t_vent_c=7.0, mdot_bl_kgps=0.05, params=p)
    hi = occupant_air(t_cab_c=25.0, t_vent_c=7.0, mdot_bl_kgps=0.17, params=p)
    # the ranges quoted in docs/comfort.md (body average for the PMV, jet at the upper body for DR)
    assert float(lo.vel_occ_mps) == pytest.approx(0.211, abs=2e-3)
    assert float(hi.vel_occ_mps) == pytest.approx(0.454, abs=2e-3)
    assert float(lo.vel_jet_mps) == pytest.approx(1.146, abs=2e-3)
    assert float(hi.vel_jet_mps) == pytest.approx(3.895, abs=2e-3)
    # jet temperature excess ratio 0.8 * 0.866 (the smooth cap at 1 lowers phi by 2.5e-5): 25 - 0.6928 * 18
    assert float(hi.ta_jet_c) == pytest.approx(25.0 - 0.8 * 0.8660254 * 18.0, abs=1e-3)
    # the old linear map gave 0.37 .. 1.0 m/s on the whole body; the body average is about half
    assert 0.15 < float(lo.vel_occ_mps) < 0.3 and 0.35 < float(hi.vel_occ_mps) < 0.55


def test_body_average_reproduces_the_area_weighted_forced_convection():
    p = OccupantAirParams()
    o = occupant_air(t_cab_c=26.0, t_vent_c=9.0, mdot_bl_kgps=0.12, params=p)
    u0 = float(o.vel_vent_mps)
    v_room = p.v_still_mps + p.c_room * u0
    f = p.jet_body_fraction
    t_cl = 31.0
    h = lambda v: 12.1 * np.sqrt(v)  # noqa: E731  (ISO 7730 forced convection)
    split = f * h(float(o.vel_jet_mps)) * (t_cl - float(o.ta_jet_c)) + (1 - f) * h(v_room) * (t_cl - 26.0)
    lumped = h(float(o.vel_occ_mps)) * (t_cl - float(o.ta_occ_c))
    assert lumped == pytest.approx(split, rel=1e-6)
    # no flow: still air at the cabin temperature
    z = occupant_air(t_cab_c=26.0, t_vent_c=9.0, mdot_bl_kgps=0.0, params=p)
    assert float(z.vel_occ_mps) == pytest.approx(p.v_still_mps * (1 - f) ** 2, rel=1e-3)
    assert float(z.ta_occ_c) == pytest.approx(26.0, abs=1e-4)


def test_casadi_matches_numpy():
    x = casadi.SX.sym("x", 3)
    o = occupant_air(t_cab_c=x[0], t_vent_c=x[1], mdot_bl_kgps=x[2], params=OccupantAirParams())
    f = casadi.Function("occ", [x], [casadi.vertcat(o.ta_occ_c, o.vel_occ_mps, o.ta_jet_c, o.vel_jet_mps)])
    g = casadi.Function("g", [x], [casadi.jacobian(f(x), x)])
    for p in ([25.0, 7.0, 0.05], [40.0, 30.0, 0.17], [22.0, 12.0, 0.1]):
        n = occupant_air(t_cab_c=p[0], t_vent_c=p[1], mdot_bl_kgps=p[2], params=OccupantAirParams())
        np.testing.assert_allclose(
            np.asarray(f(p)).ravel(), [n.ta_occ_c, n.vel_occ_mps, n.ta_jet_c, n.vel_jet_mps], rtol=1e-12
        )
        assert np.all(np.isfinite(np.asarray(g(p))))


def test_mean_radiant_temperature_and_shell_surface():
    rp = RadiantParams()
    assert float(
        mean_radiant_temperature_c(t_glass_c=30.0, t_shell_in_c=30.0, t_int_c=30.0, params=rp)
    ) == pytest.approx(30.0, abs=1e-9)
    # fourth-power mean: above the linear mean for spread temperatures
    t = float(mean_radiant_temperature_c(t_glass_c=20.0, t_shell_in_c=30.0, t_int_c=50.0, params=rp))
    k4 = 0.22 * 293.15**4 + 0.26 * 303.15**4 + 0.52 * 323.15**4
    assert t == pytest.approx(k4**0.25 - 273.15, abs=1e-9)
    assert t > 0.22 * 20.0 + 0.26 * 30.0 + 0.52 * 50.0 + 0.7  # 0.78 K above the linear mean here
    # trim surface: 3.5/8 of the way from the air to the sheet
    assert shell_inside_surface_c(26.0, 42.0, 3.5, 8.0) == pytest.approx(26.0 + 0.4375 * 16.0)
    x = casadi.SX.sym("x", 3)
    f = casadi.Function(
        "tmr", [x], [mean_radiant_temperature_c(t_glass_c=x[0], t_shell_in_c=x[1], t_int_c=x[2], params=rp)]
    )
    assert float(f([20.0, 30.0, 50.0])) == pytest.approx(t, abs=1e-12)


def test_parameter_validation():
    with pytest.raises(ValueError, match="jet_body_fraction"):
        dataclasses.replace(OccupantAirParams(), jet_body_fraction=1.5).validate()
    with pytest.raises(ValueError, match="a_vents_m2"):
        dataclasses.replace(OccupantAirParams(), a_vents_m2=0.0).validate()
    with pytest.raises(ValueError, match="a_outlet_m2"):
        dataclasses.replace(OccupantAirParams(), a_outlet_m2=0.05).validate()
    with pytest.raises(ValueError, match="f_interior"):
        dataclasses.replace(RadiantParams(), f_glass=0.5).validate()
    with pytest.raises(ValueError, match="h_film"):
        shell_inside_surface_c(26.0, 40.0, 9.0, 8.0)


def test_draught_location_follows_the_vent_aim():
    aimed = occupant_air(t_cab_c=25.0, t_vent_c=7.0, mdot_bl_kgps=0.1, params=OccupantAirParams())
    assert float(aimed.ta_dr_c) == float(aimed.ta_jet_c) and float(aimed.vel_dr_mps) == float(aimed.vel_jet_mps)
    away_p = dataclasses.replace(OccupantAirParams(), jet_body_fraction=0.0, dr_in_jet=False)
    away = occupant_air(t_cab_c=25.0, t_vent_c=7.0, mdot_bl_kgps=0.1, params=away_p)
    assert float(away.ta_dr_c) == 25.0 and float(away.vel_dr_mps) == pytest.approx(float(away.vel_room_mps))
    # no jet on the body: the PMV sees the cabin air at the room speed
    assert float(away.ta_occ_c) == pytest.approx(25.0, abs=1e-9)
    assert float(away.vel_occ_mps) == pytest.approx(float(away.vel_room_mps), rel=1e-9)
