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


def test_demand_of_inverts_the_map_and_projects_off_map_commands():
    law = AccLaw()
    for d in (0.0, 0.1, 0.3, 0.45, 0.5, 0.8, 1.0):
        c = law.map_demand(d)
        assert law.demand_of(c.mdot_bl_kgps, c.t_evap_sp_c) == pytest.approx(d, abs=1e-12)
    # (0.05 kg/s, 3 degC) is off the map: the nearest map point in normalised units is at d = 0.5 - ...
    d = law.demand_of(0.05, 3.0)
    c = law.map_demand(d)
    assert 0.3 < d < 0.5 and c.mdot_bl_kgps > 0.05 and c.t_evap_sp_c > 3.0
    # ... and it is the nearest: a brute-force search over the map in the same normalised units
    st = law.settings

    def dist(dd, m, sp):
        cc = law.map_demand(dd)
        dm = (cc.mdot_bl_kgps - m) / (st.mdot_bl_max_kgps - st.mdot_bl_min_kgps)
        ds = (cc.t_evap_sp_c - sp) / (st.t_evap_sp_max_c - st.t_evap_sp_min_c)
        return dm * dm + ds * ds

    grid = np.linspace(0.0, 1.0, 20001)
    for m, sp in ((0.05, 3.0), (0.17, 10.0), (0.11, 4.0), (0.06, 9.5)):
        d_star = grid[int(np.argmin([dist(x, m, sp) for x in grid]))]
        got = law.demand_of(m, sp)
        assert dist(got, m, sp) <= dist(d_star, m, sp) + 1e-12 and abs(got - d_star) <= 1e-4, (m, sp)


def test_take_over_after_tracking_is_bumpless_and_then_the_law_rules():
    """While another controller is in charge the law tracks its command; at take-over its first
    output equals the last applied command, and the difference to its own output decays with
    handover_tau_s (30 s: e^-1 after 30 s)."""
    law = AccLaw()
    for _ in range(10):  # a CECO-like command: low blower, evaporator at 7 degC, cabin 27.5 degC
        law.track(0.05, 7.0, 27.5)
    c0 = law.step(27.5, 5.0)
    assert (c0.mdot_bl_kgps, c0.t_evap_sp_c) == pytest.approx((0.05, 7.0), abs=1e-12)
    # the law's own output from here: PI preset to the tracked demand (its map point of (0.05, 7))
    d_tracked = law.demand_of(0.05, 7.0)
    assert law.map_demand(d_tracked).t_evap_sp_c == pytest.approx(7.0)
    assert not np.any(law._offset)  # a command on the law's map leaves no offset to decay
    # from here the PI integrates: dd = Ts kp / Ti e = 5 * 0.25 / 120 * 1.5 per step, i.e. the set-point
    # falls by dd * 7 K / 0.5 = 0.21875 K per step
    outs = [law.step(27.5, 5.0) for _ in range(3)]
    np.testing.assert_allclose([c.t_evap_sp_c for c in outs], 7.0 - 0.21875 * np.arange(1, 4), atol=1e-12)
    # a command off the map (3 degC at minimum flow): the offset decays as exp(-t / 30 s)
    law2 = AccLaw()
    law2.track(0.05, 3.0, 26.0)
    first = law2.step(26.0, 5.0)
    assert (first.mdot_bl_kgps, first.t_evap_sp_c) == pytest.approx((0.05, 3.0), abs=1e-12)
    off0 = law2._offset.copy()
    for _ in range(6):
        law2.step(26.0, 5.0)
    np.testing.assert_allclose(law2._offset, off0 * math.exp(-30.0 / 30.0), rtol=1e-9)
    # a hot cabin at take-over: pull-down mode, entered without a jump
    law3 = AccLaw()
    law3.track(0.1, 6.0, 35.0)
    c = law3.step(35.0, 5.0)
    assert c.mode == "pulldown" and (c.mdot_bl_kgps, c.t_evap_sp_c) == pytest.approx((0.1, 6.0))
    later = [law3.step(35.0, 5.0) for _ in range(40)]
    assert later[-1].mdot_bl_kgps == pytest.approx(0.17, abs=1e-3)
    assert later[-1].t_evap_sp_c == pytest.approx(3.0, abs=0.02)


def test_a_sensor_fault_at_take_over_holds_the_applied_command():
    law = AccLaw()
    law.track(0.08, 5.0, 26.5)
    for _ in range(3):
        c = law.step(math.nan, 5.0)
        assert c.mode == "sensor_fault" and (c.mdot_bl_kgps, c.t_evap_sp_c) == pytest.approx((0.08, 5.0))


def test_allowance_ramps_the_setpoint_over_the_relaxed_bound():
    law = AccLaw(AccSettings(allowance_k_per_pmv=2.0))
    assert law.step(27.0, 5.0, pmv_ub=3.0).setpoint_c == pytest.approx(26.0 + 2.0 * 2.5)
    assert law.step(27.0, 5.0, pmv_ub=1.5).setpoint_c == pytest.approx(28.0)
    assert law.step(27.0, 5.0, pmv_ub=0.5).setpoint_c == 26.0  # in the band: no allowance
    assert law.step(27.0, 5.0).setpoint_c == 26.0  # no bound given
    plain = AccLaw()
    assert plain.step(27.0, 5.0, pmv_ub=3.0).setpoint_c == 26.0  # off by default


def test_sun_and_ambient_compensation():
    s = AccSettings(
        sun_gain_k_per_kwm2=1.5, ambient_gain_k_per_k=0.1, sun_blower_gain_kgps_per_kwm2=0.03, sun_filter_tau_s=20.0
    )
    law = AccLaw(s)
    c = law.step(20.0, 5.0, t_amb_c=35.0, solar_wm2=800.0)  # cabin cold: demand 0, blower at its floor
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


@pytest.mark.parametrize(
    "field, value",
    [
        ("allowance_k_per_pmv", -1.0),
        ("sun_filter_tau_s", 0.0),
        ("sun_blower_gain_kgps_per_kwm2", -0.1),
        ("sun_gain_k_per_kwm2", math.nan),
    ],
)
def test_bad_compensation_settings(field, value):
    with pytest.raises(ValueError, match=field):
        AccSettings(**{field: value}).validate()


def test_pmv_feedback_mode_regulates_the_pmv():
    law = AccLaw(AccSettings(feedback="pmv", setpoint_pmv=0.2, kp_per_pmv=0.8, ti_s=60.0))
    c = law.step(30.0, 5.0, pmv=2.0)  # error 1.8 > 1.2: pull-down, whatever the temperature
    assert c.mode == "pulldown" and c.setpoint_pmv == 0.2 and math.isnan(c.setpoint_c)
    c = law.step(30.0, 5.0, pmv=0.7)  # error 0.5 < 0.6: the PI takes over bumplessly at d = 1
    assert c.mode == "pi" and c.demand == pytest.approx(1.0)
    # then the integrator: demand = kp e + I, I += dt (kp / Ti e + (d - v)/Tt), here unsaturated
    law2 = AccLaw(AccSettings(feedback="pmv", setpoint_pmv=0.2, kp_per_pmv=0.8, ti_s=60.0))
    d1 = law2.step(25.0, 5.0, pmv=0.5).demand  # I = 0: 0.8 * 0.3
    d2 = law2.step(25.0, 5.0, pmv=0.5).demand  # I = 5 * 0.8 / 60 * 0.3
    assert d1 == pytest.approx(0.24) and d2 == pytest.approx(0.24 + 5.0 * 0.8 / 60.0 * 0.3)
    # the temperature is ignored in this mode, a missing PMV is a sensor fault that holds the command
    assert law2.step(math.nan, 5.0, pmv=0.5).mode == "pi"
    held = law2.step(25.0, 5.0, pmv=math.nan)
    assert held.mode == "sensor_fault" and held.demand == pytest.approx(law2.step(25.0, 5.0, pmv=None).demand)
    # the allowance in PMV units: the set-point follows the relaxed bound
    a = AccLaw(AccSettings(feedback="pmv", setpoint_pmv=0.0, allowance_pmv_per_pmv=0.5))
    assert a.step(25.0, 5.0, pmv=0.1, pmv_ub=2.5).setpoint_pmv == pytest.approx(1.0)
    assert a.step(25.0, 5.0, pmv=0.1, pmv_ub=0.5).setpoint_pmv == 0.0
    # a temperature law leaves the PMV set-point NaN and ignores pmv
    t = AccLaw()
    c = t.step(27.0, 5.0, pmv=5.0)
    assert c.mode == "pi" and c.setpoint_c == 26.0 and math.isnan(c.setpoint_pmv)


def test_pmv_feedback_tracks_for_a_bumpless_take_over():
    law = AccLaw(AccSettings(feedback="pmv", setpoint_pmv=0.0, kp_per_pmv=0.8))
    law.track(0.08, 5.0, None, pmv=0.25)
    d_a = law.demand_of(0.08, 5.0)
    c = law.step(30.0, 5.0, pmv=0.25)
    # integrator preset so that kp e + I = d_a at the take-over: the PI's first demand is the applied one
    assert c.demand == pytest.approx(d_a, abs=1e-12) and 0.0 < d_a < 1.0
    assert (c.mdot_bl_kgps, c.t_evap_sp_c) == pytest.approx((0.08, 5.0))  # the applied command, then decays


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"feedback": "comfort"}, "feedback"),
        ({"feedback": "pmv", "sun_gain_k_per_kwm2": 1.0}, "compensation"),
        ({"kp_per_pmv": 0.0}, "kp_per_pmv"),
        ({"pulldown_exit_pmv": 1.5}, "pulldown_exit_pmv"),
        ({"setpoint_pmv": 4.0}, "setpoint_pmv"),
        ({"allowance_pmv_per_pmv": -0.1}, "allowance_pmv_per_pmv"),
    ],
)
def test_bad_pmv_feedback_settings(kw, field):
    with pytest.raises(ValueError, match=field):
        AccSettings(**kw).validate()


def test_feedback_pmv_is_the_scored_comfort_model_on_the_observation():
    from ceco_core import psychro
    from ceco_core.acc_law import feedback_pmv
    from ceco_core.cabin_comfort import ComfortParams, evaluate_cabin_comfort

    p = ComfortParams()
    kw = dict(t_cab_c=26.0, t_vent_c=12.0, t_int_c=31.0, t_shell_c=35.0, t_glass_c=38.0, rh_cab=0.35)
    y = feedback_pmv(**kw, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p)
    ref = evaluate_cabin_comfort(**kw, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p)
    assert y == pytest.approx(float(ref.pmv), abs=1e-12)  # the plant's scored PMV, same inputs
    assert float(ref.pa_pa) == pytest.approx(float(psychro.vapour_pressure_pa(26.0, 0.35)))
    # hotter surfaces, higher PMV; a missing or impossible input gives NaN (the law holds)
    assert feedback_pmv(**{**kw, "t_int_c": 40.0}, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p) > y
    for bad in ({"rh_cab": math.nan}, {"rh_cab": 1.5}, {"t_glass_c": None}, {"t_vent_c": "x"}):
        assert math.isnan(feedback_pmv(**{**kw, **bad}, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p))
    # a vapour pressure given in place of the humidity: rh_cab is not read, the PMV is the one at that pressure
    pa = float(psychro.vapour_pressure_pa(26.0, 0.35))
    for rh in (math.nan, 0.35, 0.9):
        got = feedback_pmv(**{**kw, "rh_cab": rh}, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p, pa_pa=pa)
        assert got == pytest.approx(y, abs=1e-12)
    at_1700 = feedback_pmv(**{**kw, "rh_cab": math.nan}, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p, pa_pa=1700.0)
    assert at_1700 > y  # 1700 Pa is more humid than 35 % at 26 degC (1180 Pa): a warmer sensation
    for bad_pa in (math.nan, -1.0, math.inf):
        assert math.isnan(feedback_pmv(**kw, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p, pa_pa=bad_pa))
    # a mean radiant temperature given (the caller's cabin_mrt_c of the same surfaces): the same PMV to the bit; a
    # different one is what the PMV is computed with
    from ceco_core.cabin_comfort import cabin_mrt_c

    t_mr = float(cabin_mrt_c(t_cab_c=26.0, t_int_c=31.0, t_shell_c=35.0, t_glass_c=38.0, params=p))
    assert feedback_pmv(**kw, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p, t_mr_c=t_mr) == y
    assert feedback_pmv(**kw, mdot_bl_kgps=0.09, solar_wm2=700.0, params=p, t_mr_c=t_mr + 3.0) > y + 0.1
