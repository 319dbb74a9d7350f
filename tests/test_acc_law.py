"""Production ACC law (baseline and fallback): modes, bounds, anti-windup."""
import math

import numpy as np
import pytest

from ceco_core.acc_law import AccLaw, AccSettings


def test_pulldown_commands_max_cooling():
    law = AccLaw()
    c = law.step(50.0, 5.0)
    assert c.mode == "pulldown"
    assert c.mdot_bl_kgps == pytest.approx(0.17) and c.t_evap_sp_c == pytest.approx(3.0)


def test_commands_always_within_bounds_and_monotone_map():
    law = AccLaw()
    for t in np.concatenate([np.linspace(60, 20, 200), np.linspace(20, 35, 200)]):
        c = law.step(float(t), 5.0)
        assert 0.05 <= c.mdot_bl_kgps <= 0.17 and 3.0 <= c.t_evap_sp_c <= 10.0
    d = np.linspace(0, 1, 21)
    m = [law.map_demand(x) for x in d]
    assert np.all(np.diff([x.mdot_bl_kgps for x in m]) >= 0)
    assert np.all(np.diff([x.t_evap_sp_c for x in m]) <= 0)
    assert m[0].t_evap_sp_c == 10.0 and m[0].mdot_bl_kgps == 0.05


def test_bumpless_handover_and_anti_windup():
    law = AccLaw()
    law.step(40.0, 5.0)  # pull-down
    c = law.step(27.5, 5.0)  # error 1.5 K < exit threshold: PI takes over at demand ~1
    assert c.mode == "pi" and c.demand > 0.95
    # long overcooling: the demand must reach 0 and come back within a few steps once warm
    for _ in range(200):
        c = law.step(20.0, 5.0)
    assert c.demand == 0.0
    steps = 0
    while law.step(27.0, 5.0).demand <= 0.0:
        steps += 1
        assert steps < 10  # back-calculation keeps the integrator from winding up


def test_sensor_fault_holds_last_command():
    law = AccLaw()
    a = law.step(30.0, 5.0)
    b = law.step(math.nan, 5.0)
    assert b.mode == "sensor_fault"
    assert (b.mdot_bl_kgps, b.t_evap_sp_c) == (a.mdot_bl_kgps, a.t_evap_sp_c)
    with pytest.raises(ValueError, match="dt_s"):
        law.step(30.0, 0.0)


def test_settings_validation_names_field():
    with pytest.raises(ValueError, match="kp_per_k"):
        AccSettings(kp_per_k=0.0).validate()
    with pytest.raises(ValueError, match="pulldown_exit_k"):
        AccSettings(pulldown_exit_k=5.0, pulldown_enter_k=4.0).validate()


def test_allowance_ramps_the_setpoint_over_the_relaxed_bound():
    law = AccLaw(AccSettings(allowance_k_per_pmv=2.0))
    assert law.step(27.0, 5.0, pmv_ub=3.0).setpoint_c == pytest.approx(26.0 + 2.0 * 2.5)
    assert law.step(27.0, 5.0, pmv_ub=1.5).setpoint_c == pytest.approx(28.0)
    assert law.step(27.0, 5.0, pmv_ub=0.5).setpoint_c == 26.0        # in the band: no allowance
    assert law.step(27.0, 5.0).setpoint_c == 26.0                    # no bound given
    plain = AccLaw()
    assert plain.step(27.0, 5.0, pmv_ub=3.0).setpoint_c == 26.0       # off by default


def test_sun_and_ambient_compensation():
    s = AccSettings(sun_gain_k_per_kwm2=1.5, ambient_gain_k_per_k=0.1, sun_blower_gain_kgps_per_kwm2=0.03,
                    sun_filter_tau_s=20.0)
    law = AccLaw(s)
    c = law.step(20.0, 5.0, t_amb_c=35.0, solar_wm2=800.0)           # cabin cold: demand 0, blower at its floor
    assert c.setpoint_c == pytest.approx(26.0 - 1.5 * 0.8 - 0.1 * 10.0)
    assert c.mdot_bl_kgps == pytest.approx(0.05 + 0.03 * 0.8)
    # first-order filter: a step from 800 to 0 W/m2 decays with exp(-dt/tau) per step
    c = law.step(20.0, 5.0, t_amb_c=35.0, solar_wm2=0.0)
    sf = 800.0 * math.exp(-5.0 / 20.0)
    assert c.setpoint_c == pytest.approx(26.0 - 1.5 * sf / 1000 - 1.0)
    # a missing reading keeps the filter and compensates nothing from that sensor
    c = law.step(20.0, 5.0, t_amb_c=None, solar_wm2=math.nan)
    assert c.setpoint_c == pytest.approx(26.0 - 1.5 * sf / 1000)
    # the blower floor never exceeds the maximum flow
    big = AccLaw(AccSettings(sun_blower_gain_kgps_per_kwm2=1.0))
    assert big.step(20.0, 5.0, solar_wm2=1000.0).mdot_bl_kgps == pytest.approx(0.17)
    assert not AccSettings().compensated and s.compensated


@pytest.mark.parametrize("field, value", [("allowance_k_per_pmv", -1.0), ("sun_filter_tau_s", 0.0),
                                          ("sun_blower_gain_kgps_per_kwm2", -0.1), ("sun_gain_k_per_kwm2", math.nan)])
def test_bad_compensation_settings(field, value):
    with pytest.raises(ValueError, match=field):
        AccSettings(**{field: value}).validate()
