"""Refrigerant cycle of the plant: CoolProp tables, the quasi-steady cycle solve, its balances."""

import math

import CoolProp.CoolProp as CP
import numpy as np
import pytest

from ceco_core.units import c_to_k
from ceco_plant_sim.plant import _compressor_model, condenser_eps_c_wpk
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.refrigerant import (
    CompressorModel,
    build_cycle_tables,
    direct_cycle_properties,
    solve_cycle,
)

FLUID = "R1234yf"


@pytest.fixture(scope="module")
def tab():
    p = PlantParams()
    return build_cycle_tables(p.refrigerant, p.superheat_k, p.subcool_k)


@pytest.fixture(scope="module")
def comp():
    return _compressor_model(PlantParams())


def test_coolprop_has_r1234yf():
    # R-1234yf is the default refrigerant (no R-134a fallback needed with CoolProp 8)
    assert CP.PropsSI("Tcrit", FLUID) == pytest.approx(c_to_k(94.7), abs=0.1)
    # saturation pressure at 0 degC: 316 kPa (Richter et al. 2011 EOS, as in CoolProp)
    assert CP.PropsSI("P", "T", c_to_k(0.0), "Q", 1, FLUID) == pytest.approx(3.16e5, rel=0.01)


def test_table_error_against_direct_coolprop(tab):
    """Table error over the operating envelope (T_e -10..20 degC, T_c 25..75 degC), 200 seeded points."""
    rng = np.random.default_rng(1234)
    worst = {}
    for _ in range(200):
        te = float(rng.uniform(-10.0, 20.0))
        tc = float(rng.uniform(25.0, 75.0))
        ref = direct_cycle_properties(FLUID, tab.superheat_k, tab.subcool_k, te, tc)
        got = {
            "p_evap_pa": tab.p_evap_pa(te),
            "rho_suc_kgm3": tab.rho_suc_kgm3(te),
            "h_suc_jpkg": tab.h_suc_jpkg(te),
            "p_cond_pa": tab.p_cond_pa(tc),
            "h_liq_jpkg": tab.h_liq_jpkg(tc),
            "dh_is_jpkg": tab.dh_is_jpkg(te, tc),
            "dh_evap_jpkg": tab.h_suc_jpkg(te) - tab.h_liq_jpkg(tc),
        }
        ref["dh_evap_jpkg"] = ref["h_suc_jpkg"] - ref["h_liq_jpkg"]
        for k, v in got.items():
            worst[k] = max(worst.get(k, 0.0), abs(v - ref[k]) / abs(ref[k]))
    # measured: 3e-5 (pressures, density), 1e-6 (enthalpies), 4e-4 (isentropic work, 2.5 K grid)
    for k in ("p_evap_pa", "rho_suc_kgm3", "p_cond_pa"):
        assert worst[k] < 1e-4, (k, worst[k])
    for k in ("h_suc_jpkg", "h_liq_jpkg", "dh_evap_jpkg"):
        assert worst[k] < 1e-5, (k, worst[k])
    assert worst["dh_is_jpkg"] < 1e-3, worst["dh_is_jpkg"]


def _solve(tab, comp, n_rpm, t_wall=5.0, speed=0.0, guess=None):
    p = PlantParams()
    return solve_cycle(tab, comp, n_rpm, t_wall, p.ua_evap_ref_wpk, 35.0, condenser_eps_c_wpk(p, speed),
                       p.te_mop_c, guess=guess, tol_k=1e-8, max_iter=30)


def test_cycle_balances(tab, comp):
    p = PlantParams()
    epsc = condenser_eps_c_wpk(p, 0.0)
    for n in (1000.0, 3000.0, 6000.0, 8600.0):
        s = _solve(tab, comp, n)
        assert not s.mop_active
        # evaporator: refrigerant heat = wall-to-refrigerant conduction
        assert s.q_evap_ref_w == pytest.approx(p.ua_evap_ref_wpk * (5.0 - s.t_evap_sat_c), rel=1e-6)
        # condenser: rejected heat = capacity + shaft work = eps C (T_c - T_amb)
        assert s.q_cond_w == pytest.approx(s.q_evap_ref_w + s.w_shaft_w, rel=1e-12)
        assert s.q_cond_w == pytest.approx(epsc * (s.t_cond_c - 35.0), rel=1e-6)
        assert s.p_comp_w == pytest.approx(s.w_shaft_w / p.eta_motor_inverter)
        assert s.iterations <= 10


def test_cycle_matches_direct_coolprop_at_solution(tab, comp):
    """COP and capacity recomputed with direct CoolProp calls at the solved (T_e, T_c): < 0.2 % apart."""
    p = PlantParams()
    s = _solve(tab, comp, 5000.0)
    d = direct_cycle_properties(FLUID, p.superheat_k, p.subcool_k, s.t_evap_sat_c, s.t_cond_c)
    pr = d["p_cond_pa"] / d["p_evap_pa"]
    mdot = d["rho_suc_kgm3"] * p.displacement_m3 * 5000.0 / 60.0 * comp.eta_vol(pr)
    q = mdot * (d["h_suc_jpkg"] - d["h_liq_jpkg"])
    w = mdot * d["dh_is_jpkg"] / comp.eta_is(pr) / p.eta_motor_inverter
    assert s.q_evap_ref_w == pytest.approx(q, rel=2e-3)
    assert s.q_evap_ref_w / s.p_comp_w == pytest.approx(q / w, rel=2e-3)


def test_capacity_grows_with_speed_and_evaporating_temperature_falls(tab, comp):
    sols = [_solve(tab, comp, n) for n in (1000.0, 2000.0, 4000.0, 8600.0)]
    q = [s.q_evap_ref_w for s in sols]
    te = [s.t_evap_sat_c for s in sols]
    assert all(b > a for a, b in zip(q, q[1:]))
    assert all(b < a for a, b in zip(te, te[1:]))
    # max capacity at a 5 degC wall, 35 degC idle: 5-7 kW (mid-size car A/C)
    assert 5000.0 < q[-1] < 7000.0


def test_condensing_temperature_falls_with_vehicle_speed(tab, comp):
    s0 = _solve(tab, comp, 5000.0, speed=0.0)
    s25 = _solve(tab, comp, 5000.0, speed=25.0)
    assert s25.t_cond_c < s0.t_cond_c - 5.0
    assert s25.q_evap_ref_w / s25.p_comp_w > 1.1 * s0.q_evap_ref_w / s0.p_comp_w


def test_mop_caps_evaporating_temperature(tab, comp):
    p = PlantParams()
    s = _solve(tab, comp, 8600.0, t_wall=55.0)
    assert s.mop_active
    assert s.t_evap_sat_c == p.te_mop_c
    # compressor-limited: the refrigerant absorbs less than the wall could give
    assert s.q_evap_ref_w < p.ua_evap_ref_wpk * (55.0 - p.te_mop_c)


def test_compressor_off(tab, comp):
    s = _solve(tab, comp, 0.0, t_wall=20.0)
    assert s.mdot_ref_kgps == 0.0 and s.p_comp_w == 0.0 and s.q_evap_ref_w == 0.0
    assert s.t_evap_sat_c == 20.0


def test_warm_and_cold_start_agree(tab, comp):
    cold = _solve(tab, comp, 4000.0)
    warm = _solve(tab, comp, 4000.0, guess=(cold.t_evap_sat_c + 0.3, cold.t_cond_c - 0.5))
    assert warm.t_evap_sat_c == pytest.approx(cold.t_evap_sat_c, abs=1e-6)
    assert warm.t_cond_c == pytest.approx(cold.t_cond_c, abs=1e-6)
    assert warm.iterations < cold.iterations


def test_efficiency_maps():
    c = CompressorModel(33e-6, 0.95, 0.025, 0.70, 0.01, 3.0, 0.9)
    assert c.eta_vol(3.0) == pytest.approx(0.90)
    assert c.eta_is(3.0) == pytest.approx(0.70)
    assert c.eta_is(6.0) == pytest.approx(0.61)
    assert c.eta_vol(0.5) == pytest.approx(0.95)  # pr < 1 treated as 1
    assert c.eta_vol(100.0) == 0.3 and c.eta_is(100.0) == 0.3


def test_unknown_fluid_rejected():
    with pytest.raises(ValueError, match="fluid"):
        build_cycle_tables("NotAFluid123")


def test_nonconvergence_raises(tab, comp):
    with pytest.raises(RuntimeError, match="did not converge"):
        solve_cycle(tab, comp, 4000.0, 5.0, 1500.0, 35.0, 400.0, 12.0, max_iter=1, tol_k=1e-12)
    assert math.isfinite(_solve(tab, comp, 4000.0).t_cond_c)


def test_head_pressure_control_at_low_ambient(tab, comp):
    """Cold condenser air: the pressure ratio is held at pr_min instead of falling below 1."""
    p = PlantParams()
    epsc = condenser_eps_c_wpk(p, 10.0)
    free = solve_cycle(tab, comp, 3000.0, 8.0, p.ua_evap_ref_wpk, 2.0, epsc, p.te_mop_c, tol_k=1e-8)
    held = solve_cycle(tab, comp, 3000.0, 8.0, p.ua_evap_ref_wpk, 2.0, epsc, p.te_mop_c, tol_k=1e-8,
                       pr_min=p.pr_min)
    assert free.pressure_ratio < p.pr_min and not free.head_pressure_control
    assert held.head_pressure_control and held.pressure_ratio == pytest.approx(p.pr_min, rel=1e-6)
    assert held.t_cond_c > held.t_evap_sat_c + 10.0
    assert held.p_comp_w > 0.0 and 3.0 < held.q_evap_ref_w / held.p_comp_w < 10.0
    # the evaporator balance still holds
    assert held.q_evap_ref_w == pytest.approx(p.ua_evap_ref_wpk * (8.0 - held.t_evap_sat_c), rel=1e-6)
    # at 35 degC it is inactive
    assert not _solve(tab, comp, 3000.0).head_pressure_control
