"""Cabin + A/C plant: API contract, bad input, pull-down physics, speed sensitivity, convergence, determinism."""

import dataclasses
import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ceco_core.contracts import AcInput
from ceco_core.psychro import humidity_ratio, relative_humidity
from ceco_plant_sim.plant import (
    CabinPlant,
    PlantOutputs,
    PlantState,
    steady_cycle_at_load,
)
from ceco_plant_sim.plant_params import PlantParams
from ceco_v2x_preview.scenario import Environment, load_scenario

REPO = Path(__file__).resolve().parents[2]
FULL = AcInput(mdot_bl_kgps=0.17, t_evap_sp_c=3.0)


def _env(t_amb_c=35.0, solar_wm2=850.0, speed_mps=10.0, rh=0.4):
    return SimpleNamespace(t_amb_c=t_amb_c, solar_wm2=solar_wm2, speed_mps=speed_mps, rh=rh)


@pytest.fixture(scope="module")
def sc03():
    """SC03 conditions after a one-hour hot soak (cabin air 57, interior 62, shell 60 degC)."""
    return load_scenario("sc03_hotsoak")


def _sc03_env(sc, t_s):
    """SC03 for its 600 s; after that the SC03 speed trace repeats with the weather held at its end values."""
    if t_s < sc.duration_s:
        return sc.env_at(t_s)
    end = sc.env_at(sc.duration_s)
    return Environment(end.t_amb_c, end.solar_wm2, sc.speed_mps(t_s % sc.duration_s), end.rh)


def _plant(sc, params=None):
    p = params or PlantParams()
    return CabinPlant(p, PlantState.from_initial(sc.initial, p, sc.env_at(0.0)))


def _pulldown(sc, n_s, params=None, dt_s=1.0):
    plant = _plant(sc, params)
    outs = []
    for k in range(int(round(n_s / dt_s))):
        outs.append(plant.step(FULL, _sc03_env(sc, k * dt_s), dt_s))
    return outs


@pytest.fixture(scope="module")
def pulldown_1800(sc03):
    return _pulldown(sc03, 1800.0)


# ------------------------------------------------------------------ API / validation
def test_acinput_bounds_and_nan():
    AcInput(0.05, 3.0)
    AcInput(0.17, 10.0)
    for kw, field in (
        ({"mdot_bl_kgps": 0.04, "t_evap_sp_c": 5.0}, "mdot_bl_kgps"),
        ({"mdot_bl_kgps": 0.18, "t_evap_sp_c": 5.0}, "mdot_bl_kgps"),
        ({"mdot_bl_kgps": float("nan"), "t_evap_sp_c": 5.0}, "mdot_bl_kgps"),
        ({"mdot_bl_kgps": 0.1, "t_evap_sp_c": 2.9}, "t_evap_sp_c"),
        ({"mdot_bl_kgps": 0.1, "t_evap_sp_c": 10.5}, "t_evap_sp_c"),
        ({"mdot_bl_kgps": 0.1, "t_evap_sp_c": float("nan")}, "t_evap_sp_c"),
    ):
        with pytest.raises(ValueError, match=field):
            AcInput(**kw)
    with pytest.raises(dataclasses.FrozenInstanceError):
        FULL.mdot_bl_kgps = 0.1


def test_params_validate_names_field():
    assert PlantParams().validate() == PlantParams()
    for field, bad in (
        ("c_int_jpk", -1.0),
        ("recirc_fraction", 1.5),
        ("cabin_volume_m3", float("nan")),
        ("eta_blower", 0.0),
        ("comp_speed_min_rpm", 9000.0),
        ("refrigerant", ""),
        ("substep_s", 5.0),
        ("n_occupants", 1.5),
    ):
        with pytest.raises(ValueError, match=field):
            dataclasses.replace(PlantParams(), **{field: bad}).validate()


def test_bad_environment_dt_and_command(sc03):
    plant = _plant(sc03)
    with pytest.raises(ValueError, match="env.t_amb_c"):
        plant.step(FULL, _env(t_amb_c=float("nan")), 1.0)
    with pytest.raises(ValueError, match="env.solar_wm2"):
        plant.step(FULL, _env(solar_wm2=-5.0), 1.0)
    with pytest.raises(ValueError, match="env.rh"):
        plant.step(FULL, _env(rh=40.0), 1.0)  # percent instead of a fraction
    with pytest.raises(ValueError, match="env.speed_mps"):
        plant.step(FULL, SimpleNamespace(t_amb_c=35.0, solar_wm2=850.0, rh=0.4), 1.0)
    for dt in (-1.0, 0.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="dt_s"):
            plant.step(FULL, _env(), dt)
    with pytest.raises(ValueError, match="command"):
        plant.step((0.17, 3.0), _env(), 1.0)
    with pytest.raises(RuntimeError):
        plant.outputs()
    # nothing was advanced by the rejected calls
    assert plant.t_s == 0.0
    assert plant.state == PlantState.from_initial(sc03.initial, PlantParams(), sc03.env_at(0.0))


def test_initial_state_from_mapping_and_scenario(sc03):
    p = PlantParams()
    s = PlantState.from_initial({"t_cab_c": 57.0, "t_int_c": 65.0, "t_shell_c": 60.0, "rh_cab": 0.13}, p, _env())
    assert s.t_glass_c == 60.0 and s.t_evap_c == 57.0 and s.comp_pi_integral_rpm == 0.0
    assert s.t_duct_c == s.t_evap_c  # the case and ducts soak with the HVAC module
    assert relative_humidity(57.0, s.w_cab_kgkg) == pytest.approx(0.13, rel=1e-9)
    s2 = PlantState.from_initial(sc03.initial, p, sc03.env_at(0.0))
    assert s2.t_cab_c == sc03.initial.t_cab_c and s2.t_int_c == sc03.initial.t_int_c
    with pytest.raises(ValueError, match="initial.rh_cab"):
        PlantState.from_initial({"t_cab_c": 57.0, "t_int_c": 65.0, "t_shell_c": 60.0}, p, _env())
    with pytest.raises(ValueError, match="initial.rh_cab"):
        PlantState.from_initial({"t_cab_c": 57.0, "t_int_c": 65.0, "t_shell_c": 60.0, "rh_cab": 1.2}, p, _env())
    with pytest.raises(ValueError, match="t_int_c"):
        PlantState(57.0, float("nan"), 60.0, 60.0, 57.0, 57.0, 0.01).validate()
    with pytest.raises(ValueError, match="t_duct_c"):
        PlantState(57.0, 60.0, 60.0, 60.0, 57.0, float("inf"), 0.01).validate()


def test_humidity_ratio_reference():
    # ASHRAE Fundamentals 2017 ch. 1 table 2: W_s = 0.036605 kg/kg at 35 degC, 101.325 kPa
    assert humidity_ratio(35.0, 1.0) == pytest.approx(0.036605, rel=2e-3)
    assert humidity_ratio(35.0, 0.4) == pytest.approx(0.01413, rel=5e-3)


# ------------------------------------------------------------------ SC03 hot-soak pull-down
def test_pulldown_time_power_cop(pulldown_1800):
    outs = pulldown_1800
    t_cab = np.array([o.t_cab_c for o in outs])
    t_s = np.arange(1, len(outs) + 1, dtype=float)  # end-of-step times
    t25 = t_s[np.argmax(t_cab <= 25.0)]
    assert np.any(t_cab <= 25.0)
    # measured 670 s (11.2 min); published hot-soak pull-downs: 10-30 min to ~25 degC (docs/plant.md)
    assert 8 * 60 <= t25 <= 20 * 60, t25
    # the first seconds blow the soaked HVAC module's hot air in (t_cab rises ~0.1 K), then a monotonic pull-down
    assert t_cab[:3].max() - t_cab[0] < 0.5
    assert np.all(np.diff(t_cab[5:600]) < 0.0)
    assert 16.0 < t_cab[-1] < 22.0
    p_ac = np.array([o.p_comp_w + o.p_blower_w for o in outs])
    assert 1000.0 < p_ac.mean() < 4000.0
    assert p_ac.max() < 4000.0
    # instantaneous COP after the first minute: measured 1.72 (idle, hot interior) .. 3.18 (cruise)
    assert all(1.6 < o.cop < 3.5 for o in outs[60:])
    cop_mean = sum(o.q_evap_ref_w for o in outs) / sum(o.p_comp_w for o in outs)
    assert 2.2 < cop_mean < 2.7, cop_mean  # measured 2.43
    # blower at 0.17 kg/s: fan law 311 W + 15 W fixed losses
    assert outs[0].p_blower_w == pytest.approx(326.0, abs=1.0)


def test_pulldown_ac_behaviour(pulldown_1800):
    outs = pulldown_1800
    p = PlantParams()
    assert outs[0].capacity_limited and outs[0].mop_active
    # hot start: the inverter power limit binds below the maximum speed
    assert outs[0].p_comp_w == pytest.approx(p.p_comp_max_w, rel=2e-3)
    assert outs[0].comp_speed_rpm < p.comp_speed_max_rpm
    assert all(o.p_comp_w <= p.p_comp_max_w * 1.001 for o in outs)
    late = outs[900:]
    # the ECU's PI holds the wall at the set-point; SC03 speed steps move the condenser: measured +-0.43 K
    assert all(abs(o.t_evap_c - 3.0) < 0.6 for o in late)
    assert all(4.0 < o.t_vent_c < 8.0 for o in late)  # max-A/C vent air
    assert all(o.t_evap_sat_c < o.t_evap_c < o.t_evap_out_c <= o.t_vent_c for o in late)
    assert all(40.0 < o.t_cond_c < 65.0 for o in outs[60:])
    assert all(o.q_latent_w > 300.0 for o in late)  # 40 % RH fresh-air share is dehumidified
    assert all(0.0 < o.rh_cab < 0.6 for o in outs)
    # quasi-steady: air-side heat = refrigerant heat when the wall temperature is settled
    assert outs[-1].q_evap_w == pytest.approx(outs[-1].q_evap_ref_w, rel=0.01)


def test_step_energy_lies_between_the_instantaneous_powers(sc03):
    # a half-load command after the pull-down: the compressor PI ramps, so the power changes within a step
    plant = _plant(sc03)
    env = _sc03_env(sc03, 0.0)
    half = AcInput(mdot_bl_kgps=0.1, t_evap_sp_c=7.0)
    for _ in range(300):
        plant.step(FULL, env, 1.0)
    changed = 0
    for _ in range(60):
        p0 = plant.snapshot(half, env).p_comp_w
        o = plant.step(half, env, 1.0)
        p1 = plant.snapshot(half, env).p_comp_w
        lo, hi = min(p0, p1), max(p0, p1)
        assert lo - 1e-6 * hi - 1e-9 <= o.e_comp_j / 1.0 <= hi + 1e-6 * hi + 1e-9, (p0, o.e_comp_j, p1)
        changed += abs(p1 - p0) > 1.0
    assert changed >= 10  # the bound was exercised on steps whose power really changed


def test_vent_air_not_supersaturated(pulldown_1800):
    o = pulldown_1800[-1]
    p = PlantParams()
    w_mix = p.recirc_fraction * o.w_cab_kgkg + (1 - p.recirc_fraction) * humidity_ratio(35.0, 0.4)
    w_sat_vent = humidity_ratio(o.t_vent_c, 1.0)
    assert w_mix > w_sat_vent * 0.9  # the coil condenses ...
    # ... and the humidity state stays physical: cabin w below saturation at cabin temperature
    assert o.w_cab_kgkg < humidity_ratio(o.t_cab_c, 1.0)


# ------------------------------------------------------------------ speed sensitivity
def test_cop_rises_with_vehicle_speed_at_fixed_load():
    p = PlantParams()
    speeds = [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0]
    res = [steady_cycle_at_load(p, 3000.0, 5.0, 35.0, v) for v in speeds]
    cop = [s.q_evap_ref_w / s.p_comp_w for _, s in res]
    pw = [s.p_comp_w for _, s in res]
    tc = [s.t_cond_c for _, s in res]
    assert all(b > a for a, b in zip(cop, cop[1:]))
    assert all(b < a for a, b in zip(pw, pw[1:]))
    assert all(b < a for a, b in zip(tc, tc[1:]))
    assert all(abs(s.q_evap_ref_w - 3000.0) < 1.0 for _, s in res)
    # measured: COP 3.21 at idle -> 3.88 at 25 m/s (+21 %), condensing 45.9 -> 40.3 degC
    assert 2.5 < cop[0] < 3.6 and 3.4 < cop[-1] < 4.5
    assert cop[5] / cop[0] > 1.12


def test_dynamic_plant_more_efficient_at_speed(sc03):
    ref = _plant(sc03)
    for _ in range(300):
        ref.step(FULL, _env(speed_mps=0.0), 1.0)
    state = ref.state
    res = {}
    for v in (0.0, 25.0):
        plant = CabinPlant(PlantParams(), state)
        outs = [plant.step(AcInput(0.12, 5.0), _env(speed_mps=v), 1.0) for _ in range(120)]
        res[v] = sum(o.q_evap_ref_w for o in outs) / sum(o.p_comp_w for o in outs)
    assert res[25.0] > 1.1 * res[0.0]


# ------------------------------------------------------------------ integration quality
def _traj(outs):
    return np.array([[o.t_cab_c, o.t_int_c, o.t_evap_c, o.t_vent_c, o.w_cab_kgkg * 1000.0] for o in outs])


def test_substep_convergence_sc03(sc03):
    """Halving the sub-step (0.5 s -> 0.25 s) changes the 600 s SC03 pull-down by < 0.01 K (air), 0.05 K (wall)."""
    a = _pulldown(sc03, 600.0, PlantParams())
    b = _pulldown(sc03, 600.0, dataclasses.replace(PlantParams(), substep_s=0.25))
    d = np.abs(_traj(a) - _traj(b)).max(axis=0)
    # measured: 0.0025 K cabin, 0.011 K wall
    assert d[0] < 0.01 and d[1] < 0.01 and d[2] < 0.05 and d[3] < 0.05 and d[4] < 0.01
    ea = sum(o.e_comp_j for o in a)
    eb = sum(o.e_comp_j for o in b)
    assert ea == pytest.approx(eb, rel=2e-3)


def test_control_period_independence(sc03):
    """dt_s = 1 and dt_s = 5 with the same held command and env give the same result."""
    env = _env(speed_mps=12.0)
    p1 = _plant(sc03)
    p5 = _plant(sc03)
    cmds = [AcInput(0.17, 3.0), AcInput(0.08, 8.0), AcInput(0.12, 5.0)]
    e1 = e5 = 0.0
    for k in range(120):
        cmd = cmds[(k // 20) % 3]
        for _ in range(5):
            o1 = p1.step(cmd, env, 1.0)
            e1 += o1.e_comp_j
        o5 = p5.step(cmd, env, 5.0)
        e5 += o5.e_comp_j
        assert o5.t_cab_c == pytest.approx(o1.t_cab_c, abs=1e-9)
        assert o5.t_evap_c == pytest.approx(o1.t_evap_c, abs=1e-9)
    s1, s5 = p1.state.as_tuple(), p5.state.as_tuple()
    assert max(abs(a - b) for a, b in zip(s1, s5)) < 1e-9
    assert e1 == pytest.approx(e5, rel=1e-9)
    assert p1.t_s == p5.t_s == 600.0


def test_deterministic_bit_identical(sc03):
    a = _pulldown(sc03, 300.0)
    b = _pulldown(sc03, 300.0)
    assert a == b  # frozen dataclasses: field-by-field exact equality


def test_outputs_contract(pulldown_1800):
    names = {f.name for f in dataclasses.fields(PlantOutputs)}
    for n in (
        "t_cab_c",
        "t_int_c",
        "t_shell_c",
        "t_evap_c",
        "t_vent_c",
        "t_evap_sat_c",
        "t_cond_c",
        "rh_cab",
        "p_comp_w",
        "p_blower_w",
        "p_cond_fan_w",
        "e_comp_j",
        "e_blower_j",
        "q_evap_w",
        "q_latent_w",
        "cop",
        "comp_speed_rpm",
        "capacity_limited",
        "mdot_ref_kgps",
    ):
        assert n in names
    o = pulldown_1800[10]
    assert all(math.isfinite(getattr(o, n)) for n in names if not isinstance(getattr(o, n), bool))


def test_every_parameter_documented():
    text = (REPO / "docs" / "plant.md").read_text()
    rows = {m.group(1) for m in re.finditer(r"^\|\s*`(\w+)`\s*\|", text, re.M)}
    missing = [f.name for f in dataclasses.fields(PlantParams) if f.name not in rows]
    assert not missing, f"parameters missing from the docs/plant.md table: {missing}"


def test_snapshot_does_not_advance(sc03):
    a = _plant(sc03)
    b = _plant(sc03)
    env = sc03.env_at(0.0)
    snap = a.snapshot(FULL, env)
    assert snap.t_cab_c == sc03.initial.t_cab_c and snap.e_comp_j == 0.0 and a.t_s == 0.0
    # hot soaked module: the vent air starts near the cabin temperature, blower heat and duct included
    assert sc03.initial.t_cab_c - 5.0 < snap.t_vent_c < sc03.initial.t_cab_c + 5.0
    assert snap.p_comp_w == pytest.approx(PlantParams().p_comp_max_w, rel=1e-3)  # hot start at the limit
    assert a.step(FULL, env, 1.0) == b.step(FULL, env, 1.0)  # bit-identical with and without the snapshot
    with pytest.raises(ValueError, match="env.rh"):
        a.snapshot(FULL, _env(rh=float("nan")))


def test_moisture_balance_conserves_water(sc03):
    """inflow - outflow - condensate = storage change of the cabin air's water, over a whole run (the
    integration's bookkeeping; the flows themselves: the dry-coil steady-state test below)."""
    plant = _plant(sc03)
    m_air = plant.params.rho_air_kgm3 * plant.params.cabin_volume_m3  # dry-air mass of the cabin [kg]
    w0 = plant.state.w_cab_kgkg
    water_in = water_out = condensate = 0.0
    # pull-down, then a low-flow warm-coil phase (condensation stops and restarts), with the SC03 speed trace
    for k in range(900):
        cmd = FULL if k < 450 else AcInput(mdot_bl_kgps=0.06, t_evap_sp_c=10.0)
        out = plant.step(cmd, _sc03_env(sc03, float(k)), 1.0)
        water_in += out.m_water_in_kg
        water_out += out.m_water_out_kg
        condensate += out.m_condensate_kg
    storage = m_air * (plant.state.w_cab_kgkg - w0)
    scale = max(water_in, water_out, condensate)
    assert condensate > 0.1 and water_in > 0.1  # real flows: 0.21 kg condensed, 0.36 kg in, 0.16 kg out
    assert abs(water_in - water_out - condensate - storage) <= 1e-6 * scale
    # the outputs report the same cabin humidity the state holds
    assert out.w_cab_kgkg == plant.state.w_cab_kgkg


def _cold_saturated_run(t_c, rh, n_s, p=None):
    """Parked-at-ambient cabin at ``t_c`` [degC] and ``rh`` (ambient alike, night, 26 m/s), blower 0.05 kg/s at
    80 % recirculation, compressor off (set-point above the cabin): the occupant's vapour saturates the air.
    Returns (params, plant, the cabin's water content at the start [kg/kg], the step outputs)."""
    p = p or PlantParams()
    env = _env(t_amb_c=t_c, solar_wm2=0.0, speed_mps=26.0, rh=rh)
    init = {"t_cab_c": t_c, "t_int_c": t_c, "t_shell_c": t_c, "rh_cab": rh}
    plant = CabinPlant(p, PlantState.from_initial(init, p, env))
    w0 = plant.state.w_cab_kgkg
    u = AcInput(mdot_bl_kgps=0.05, t_evap_sp_c=10.0)
    return p, plant, w0, [plant.step(u, env, 1.0) for _ in range(n_s)]


@pytest.mark.parametrize(("t_c", "rh", "n_s"), [(-40.0, 1.0, 120), (0.0, 0.9, 300)])
def test_cabin_air_is_never_supersaturated(t_c, rh, n_s):
    """Water beyond saturation at the cabin air temperature is fog (condensed): rh_cab stops at 1 (it rose to
    3.8 and 1.10 when only the coil condensed) while the water content goes on rising; below it nothing changes."""
    p, plant, _, outs = _cold_saturated_run(t_c, rh, n_s)
    rhs = np.array([o.rh_cab for o in outs])
    raw = np.array([relative_humidity(o.t_cab_c, o.w_cab_kgkg, p.p_atm_pa) for o in outs])  # of the water content
    assert rhs.max() <= 1.0
    assert raw[-1] > 1.0 + 1e-3 and rhs[-1] == pytest.approx(1.0, abs=1e-15)  # held at saturation, fog beyond it
    below = raw < 1.0  # unsaturated steps (the 0 degC run's first ~100 s): rh is the humidity ratio's, unchanged
    assert below.any() == (rh < 1.0)
    np.testing.assert_array_equal(rhs[below], raw[below])
    np.testing.assert_allclose(rhs[~below], 1.0, rtol=0, atol=1e-15)


def test_fog_deposits_and_the_water_balance_holds():
    """in - out - condensate (coil + fog deposited on the surfaces) = storage change, with fog present; the fog's
    deposition is a part of the condensate of its own (24 % here: with tau_fog 1e9 s, nearly no deposition, the
    condensate falls from 10.7 to 8.2 g; the coil catches the fog that passes it with the recirculated air)."""
    p, plant, w0, outs = _cold_saturated_run(-40.0, 1.0, 600)
    m_air = p.rho_air_kgm3 * p.cabin_volume_m3
    water_in = sum(o.m_water_in_kg for o in outs)
    water_out = sum(o.m_water_out_kg for o in outs)
    condensate = sum(o.m_condensate_kg for o in outs)
    storage = m_air * (plant.state.w_cab_kgkg - w0)
    assert abs(water_in - water_out - condensate - storage) <= 1e-9 * water_in
    # the fog settles where the occupant's vapour it holds is deposited (tau_fog) and exfiltrated
    excess = plant.state.w_cab_kgkg - humidity_ratio(plant.state.t_cab_c, 1.0, p.p_atm_pa)
    gen = p.n_occupants * p.occ_latent_w / p.h_fg_jpkg
    assert 0.0 < excess * m_air / p.fog_removal_tau_s < gen
    kept = dataclasses.replace(p, fog_removal_tau_s=1e9)
    *_, outs_kept = _cold_saturated_run(-40.0, 1.0, 600, kept)
    assert sum(o.m_condensate_kg for o in outs_kept) < 0.85 * condensate


def test_dry_coil_steady_humidity_is_the_fresh_air_and_occupant_balance(sc03):
    """An independent check of the moisture terms (the conservation test above holds for any flow
    formula): with the coil above the dew point nothing condenses, and the cabin settles where the
    occupants' moisture is carried away by the fresh air, W_cab = W_amb + n L_occ / (h_fg m_fresh),
    m_fresh = (1 - r) mdot + m_inf (W of the ambient air: ceco_core.psychro.humidity_ratio)."""
    from ceco_core import psychro

    p = PlantParams()
    plant = _plant(sc03, p)
    env = _env(t_amb_c=30.0, solar_wm2=0.0, speed_mps=0.0, rh=0.15)  # dew point ~1 degC, coil >= 10 degC
    u = AcInput(mdot_bl_kgps=0.1, t_evap_sp_c=10.0)
    for _ in range(6000):
        out = plant.step(u, env, 1.0)
    assert out.m_condensate_kg == 0.0
    w_amb = float(psychro.humidity_ratio(env.t_amb_c, env.rh, p.p_atm_pa))
    fresh = (1.0 - p.recirc_fraction) * u.mdot_bl_kgps + p.infiltration_0_kgps
    w_expect = w_amb + p.n_occupants * p.occ_latent_w / (p.h_fg_jpkg * fresh)
    assert w_expect > w_amb * 1.05  # the occupants' share is visible
    assert plant.state.w_cab_kgkg == pytest.approx(w_expect, rel=1e-4)


def test_duct_mass_delays_the_vent_air(sc03):
    """The HVAC case and ducts (7 kJ/K, soaked at cabin temperature) warm the first cold air."""
    outs = _pulldown(sc03, 120.0)
    light = _pulldown(sc03, 120.0, params=dataclasses.replace(PlantParams(), c_duct_jpk=700.0))
    t_vent = np.array([o.t_vent_c for o in outs])
    t_vent_light = np.array([o.t_vent_c for o in light])
    # at 60 s the vent air is measurably warmer with the real mass (sc03_hotsoak: 17.3 vs 12.2 degC)
    assert t_vent[59] - t_vent_light[59] > 2.0
    # the duct wall cools towards the vent air and stays above it
    assert outs[0].t_duct_c > outs[-1].t_duct_c > outs[-1].t_vent_c
