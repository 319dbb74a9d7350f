"""Refrigerant cycle of the plant: CoolProp tables (shipped file and fresh builds), the cycle solve, its balances."""

import json
import logging
import math
import os
import re
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import CoolProp
import CoolProp.CoolProp as CP
import numpy as np
import pytest

from ceco_core.units import c_to_k
from ceco_plant_sim import refrigerant, refrigerant_table_file
from ceco_plant_sim.plant import _compressor_model, condenser_eps_c_wpk
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.refrigerant import (
    DEFAULT_GRID,
    SHIPPED_TABLES,
    CompressorModel,
    StaleTablesError,
    TableGrid,
    build_cycle_tables,
    check_tables_file,
    cycle_tables,
    direct_cycle_properties,
    load_tables_file,
    read_tables_file,
    solve_cycle,
    tables_arrays,
)

FLUID = "R1234yf"


@pytest.fixture(scope="module")
def tab():
    """The tables the plant uses (the shipped file)."""
    p = PlantParams()
    return cycle_tables(p.refrigerant, p.superheat_k, p.subcool_k)


@pytest.fixture(scope="module")
def fresh():
    """A fresh CoolProp build of the same configuration."""
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
    return solve_cycle(
        tab,
        comp,
        n_rpm,
        t_wall,
        p.ua_evap_ref_wpk,
        35.0,
        condenser_eps_c_wpk(p, speed),
        p.te_mop_c,
        guess=guess,
        tol_k=1e-8,
        max_iter=30,
    )


def test_cycle_balances(tab, comp):
    p = PlantParams()
    epsc = condenser_eps_c_wpk(p, 0.0)
    for n in (1000.0, 3000.0, 6000.0, 8600.0):
        s = _solve(tab, comp, n)
        assert not s.mop_active
        # evaporator: refrigerant heat = wall-to-refrigerant conduction
        assert s.q_evap_ref_w == pytest.approx(p.ua_evap_ref_wpk * (5.0 - s.t_evap_sat_c), rel=1e-6)
        # condenser: rejected heat = eps C (T_c - T_amb) = the refrigerant's enthalpy drop from the compressor's
        # discharge to the subcooled liquid, mdot (h_suc + dh_is / eta_is - h_liq), from direct CoolProp calls at the
        # solved temperatures (first law on the loop: capacity + shaft work, each from its own equation)
        assert s.q_cond_w == pytest.approx(epsc * (s.t_cond_c - 35.0), rel=1e-6)
        d = direct_cycle_properties(FLUID, p.superheat_k, p.subcool_k, s.t_evap_sat_c, s.t_cond_c)
        h_dis = d["h_suc_jpkg"] + d["dh_is_jpkg"] / comp.eta_is(d["p_cond_pa"] / d["p_evap_pa"])
        assert s.q_cond_w == pytest.approx(s.mdot_ref_kgps * (h_dis - d["h_liq_jpkg"]), rel=2e-3)
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
    held = solve_cycle(tab, comp, 3000.0, 8.0, p.ua_evap_ref_wpk, 2.0, epsc, p.te_mop_c, tol_k=1e-8, pr_min=p.pr_min)
    assert free.pressure_ratio < p.pr_min and not free.head_pressure_control
    assert held.head_pressure_control and held.pressure_ratio == pytest.approx(p.pr_min, rel=1e-6)
    assert held.t_cond_c > held.t_evap_sat_c + 10.0
    assert held.p_comp_w > 0.0 and 3.0 < held.q_evap_ref_w / held.p_comp_w < 10.0
    # the evaporator balance still holds
    assert held.q_evap_ref_w == pytest.approx(p.ua_evap_ref_wpk * (8.0 - held.t_evap_sat_c), rel=1e-6)
    # at 35 degC it is inactive
    assert not _solve(tab, comp, 3000.0).head_pressure_control


def test_mop_pinned_cycle_does_not_depend_on_the_wall_temperature(tab, comp):
    """Once the MOP pins T_e the cycle is compressor-limited: the wall temperature drops out of it.

    Before the fix the head-pressure flag, judged on the unpinned solution (T_e far above the pin,
    pressure ratio below pr_min), stuck after the pin: from ~32 degC wall at 4000 rpm the cycle
    jumped to T_c 36.5 degC at 35 degC ambient (1.5 K of condenser driving force for 7.7 kW) and
    5933 -> 6804 W of capacity for 1397 -> 1050 W. Never visited by the recorded runs (their hot
    starts run at the power-limit speed, where the ratio stays above pr_min).
    """
    p = PlantParams()
    epsc = condenser_eps_c_wpk(p, 0.0)
    pinned = [
        solve_cycle(tab, comp, 4000.0, t, p.ua_evap_ref_wpk, 35.0, epsc, p.te_mop_c, tol_k=1e-10, pr_min=p.pr_min)
        for t in (20.0, 32.5, 45.0, 65.0)
    ]
    assert all(s.mop_active and not s.head_pressure_control for s in pinned)
    q0, p0 = pinned[0].q_evap_ref_w, pinned[0].p_comp_w
    for s in pinned[1:]:
        assert s.q_evap_ref_w == pytest.approx(q0, rel=1e-9) and s.p_comp_w == pytest.approx(p0, rel=1e-9)
    s = pinned[-1]
    # the condenser balance holds: Q_ref + W_shaft = eps_c C_c (T_c - T_amb)
    assert s.q_cond_w == pytest.approx(epsc * (s.t_cond_c - 35.0), rel=1e-6)
    assert s.t_cond_c > 45.0


# ---------------------------------------------------------------- the shipped table file


def test_plant_uses_the_shipped_file(tab):
    assert tab.source.startswith("shipped file cycle_tables_R1234yf.npz (CoolProp 8.0.0")
    prov, _ = read_tables_file(SHIPPED_TABLES)
    p = PlantParams()
    assert (prov["fluid"], prov["superheat_k"], prov["subcool_k"]) == (p.refrigerant, p.superheat_k, p.subcool_k)
    assert prov["grid"] == asdict(DEFAULT_GRID)
    assert prov["command"] == "python tools/make_refrigerant_tables.py"
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", prov["date_utc"])
    assert prov["coolprop_gitrevision"] == CoolProp.__gitrevision__


def test_shipped_tables_equal_a_fresh_coolprop_build_exactly(tab, fresh):
    """Bit for bit: the same float64 values, hence the same interpolants and the same simulation."""
    got, ref = tables_arrays(tab), tables_arrays(fresh)
    assert set(got) == set(ref) == {"p_evap_pa", "rho_suc_kgm3", "h_suc_jpkg", "p_cond_pa", "h_liq_jpkg", "dh_is_jpkg"}
    for key in ref:
        assert got[key].shape == ref[key].shape and np.array_equal(got[key], ref[key]), key
    assert got["dh_is_jpkg"].shape == (25, 31) and got["p_evap_pa"].shape == (121,)
    assert (tab.te_range_c, tab.tc_range_c) == (fresh.te_range_c, fresh.tc_range_c)
    rng = np.random.default_rng(7)
    for te, tc in rng.uniform([-40.0, 0.0], [40.0, 95.0], size=(50, 2)):  # extrapolation included
        assert tab.h_suc_jpkg.value_slope(te) == fresh.h_suc_jpkg.value_slope(te)
        assert tab.p_cond_pa.value_slope(tc) == fresh.p_cond_pa.value_slope(tc)
        assert tab.dh_is_jpkg.value_grad(te, tc) == fresh.dh_is_jpkg.value_grad(te, tc)
    assert check_tables_file(SHIPPED_TABLES)["coolprop_version"] == CoolProp.__version__


def _rewrite(src, dst, prov_change=None, arrays_change=None):
    prov, arrays = read_tables_file(src)
    prov = dict(prov, **(prov_change or {}))
    arrays = dict(arrays, **(arrays_change or {}))
    with open(dst, "wb") as f:
        np.savez(f, provenance=np.array(json.dumps(prov)), **arrays)
    return dst


def test_stale_coolprop_version_is_detected(tmp_path):
    old = _rewrite(SHIPPED_TABLES, tmp_path / "old.npz", {"coolprop_version": "6.4.1"})
    with pytest.raises(
        StaleTablesError,
        match=r"generated with CoolProp 6\.4\.1, the installed CoolProp is 8\.0\.0; "
        r"regenerate it with `python tools/make_refrigerant_tables\.py`",
    ):
        check_tables_file(str(old))


def test_changed_values_are_detected(tmp_path):
    _, arrays = read_tables_file(SHIPPED_TABLES)
    h = arrays["h_liq_jpkg"].copy()
    h[17] = np.nextafter(h[17], np.inf)  # one ulp at one point
    bad = _rewrite(SHIPPED_TABLES, tmp_path / "ulp.npz", arrays_change={"h_liq_jpkg": h})
    with pytest.raises(
        StaleTablesError,
        match=r"h_liq_jpkg differs from a fresh CoolProp 8\.0\.0 build at 1 of 151 "
        r"points \(largest relative difference 1\.\d+e-16\)",
    ):
        check_tables_file(str(bad))


def test_other_grid_or_format_or_shape_is_detected(tmp_path):
    coarse = TableGrid(step_1d_k=1.0, step_2d_k=5.0)
    refrigerant.write_tables_file(str(tmp_path / "coarse.npz"), grid=coarse, command="test")
    prov, arrays = read_tables_file(str(tmp_path / "coarse.npz"))  # a valid file of another grid
    assert arrays["p_evap_pa"].shape == (61,) and arrays["dh_is_jpkg"].shape == (13, 16)
    with pytest.raises(
        StaleTablesError,
        match=r"grid \{.*'step_1d_k': 1\.0.*\} differs from the plant's "
        r"\{.*'step_1d_k': 0\.5.*\}; regenerate it with `python tools/",
    ):
        load_tables_file(str(tmp_path / "coarse.npz"))
    check_tables_file(str(tmp_path / "coarse.npz"))  # but it is current for its own grid
    lie = _rewrite(tmp_path / "coarse.npz", tmp_path / "lie.npz", {"grid": asdict(DEFAULT_GRID)})
    with pytest.raises(
        StaleTablesError,
        match=r"p_evap_pa is float64 \(61,\), the grid .* needs finite float64 "
        r"\(121,\)",
    ):
        read_tables_file(str(lie))
    fmt = _rewrite(SHIPPED_TABLES, tmp_path / "fmt.npz", {"format": 2})
    with pytest.raises(StaleTablesError, match="format 2, this code reads format 1"):
        read_tables_file(str(fmt))
    with pytest.raises(StaleTablesError, match="unreadable"):
        read_tables_file(str(tmp_path / "missing.npz"))
    nan = _rewrite(SHIPPED_TABLES, tmp_path / "nan.npz", arrays_change={"dh_is_jpkg": np.full((25, 31), np.nan)})
    with pytest.raises(StaleTablesError, match="dh_is_jpkg is float64 \\(25, 31\\), .* needs finite"):
        read_tables_file(str(nan))


def test_stale_shipped_file_falls_back_to_coolprop_with_a_warning(tmp_path, monkeypatch, caplog, fresh):
    old = _rewrite(SHIPPED_TABLES, tmp_path / "fmt.npz", {"format": 0})
    monkeypatch.setattr(refrigerant_table_file, "SHIPPED_TABLES", str(old))
    with caplog.at_level(logging.WARNING, logger="ceco_plant_sim.refrigerant_table_file"):
        t = cycle_tables.__wrapped__("R1234yf", 5.0, 5.0)  # past the cache
    assert "format 0, this code reads format 1" in caplog.text
    assert "building the tables with CoolProp instead" in caplog.text
    assert t.source.startswith("built with CoolProp 8.0.0")
    assert np.array_equal(tables_arrays(t)["dh_is_jpkg"], tables_arrays(fresh)["dh_is_jpkg"])


def test_configuration_not_in_the_file_is_built_with_coolprop(caplog):
    with caplog.at_level(logging.WARNING, logger="ceco_plant_sim.refrigerant_table_file"):
        t = cycle_tables("R1234yf", 8.0, 5.0)
    assert "holds R1234yf with superheat 5.0 K and subcooling 5.0 K, not R1234yf with 8.0 K and 5.0 K" in caplog.text
    assert t.source.startswith("built with CoolProp") and t.superheat_k == 8.0
    ref = direct_cycle_properties(FLUID, 8.0, 5.0, 0.0, 50.0)
    assert t.h_suc_jpkg(0.0) == pytest.approx(ref["h_suc_jpkg"], rel=1e-12)  # a grid point
    with pytest.raises(ValueError, match="fluid: CoolProp does not know 'NotAFluid123'"):
        cycle_tables("NotAFluid123", 5.0, 5.0)


def test_package_data_installs_the_file():
    setup = (Path(refrigerant.__file__).parents[1] / "setup.py").read_text()
    globs = re.search(r"package_data=\{package_name: \[([^]]*)\]", setup)[1]
    rel = os.path.relpath(SHIPPED_TABLES, os.path.dirname(refrigerant.__file__))
    assert rel == os.path.join("data", "cycle_tables_R1234yf.npz")
    assert "'data/*'" in globs


_NO_COOLPROP = """
import sys
sys.modules['CoolProp'] = None            # any `import CoolProp` now raises ImportError
import ceco_plant_sim.refrigerant, ceco_plant_sim.plant, ceco_plant_sim.plant_params, ceco_plant_sim.scenario_plant
import ceco_plant_sim.plant_io, ceco_plant_sim.comfort, ceco_plant_sim.metrics
from ceco_core.contracts import AcInput
from ceco_plant_sim.scenario_plant import ScenarioPlant
from ceco_v2x_preview.scenario import load_scenario
sp = ScenarioPlant(load_scenario('sc03'), 1.0)
for _ in range(20):
    r = sp.step(AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0))
print('T_CAB', repr(float(r.meas['t_cab_c'])), 'P_COMP', repr(float(r.out.p_comp_w)))
print('SOURCE', sp.plant.tables_source)
try:
    ceco_plant_sim.refrigerant.cycle_tables('R1234yf', 7.0, 5.0)
except ImportError as e:
    print('NEEDS', e)
"""


def test_plant_modules_run_without_coolprop():
    """The plant imports, loads its tables and steps with CoolProp unimportable (key-on: no 2.3 s import)."""
    out = subprocess.run(
        [sys.executable, "-c", _NO_COOLPROP],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)),
    )
    assert out.returncode == 0, out.stderr
    assert "SOURCE shipped file cycle_tables_R1234yf.npz" in out.stdout
    assert "NEEDS refrigerant tables: CoolProp is needed to build tables that the shipped file" in out.stdout
    assert "holds R1234yf with superheat 5.0 K" in out.stderr  # the warning before the attempt
    t_cab, p_comp = (float(x) for x in re.search(r"T_CAB (\S+) P_COMP (\S+)", out.stdout).groups())
    assert 30.0 < t_cab < 60.0 and p_comp > 500.0
    # the same 20 s in this process (CoolProp imported here): the same numbers, bit for bit
    from ceco_core.contracts import AcInput
    from ceco_plant_sim.scenario_plant import ScenarioPlant
    from ceco_v2x_preview.scenario import load_scenario

    sp = ScenarioPlant(load_scenario("sc03"), 1.0)
    for _ in range(20):
        r = sp.step(AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0))
    assert (float(r.meas["t_cab_c"]), float(r.out.p_comp_w)) == (t_cab, p_comp)
