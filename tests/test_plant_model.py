"""The plant written once: numeric path = the reference trajectories, exact symbolic = numeric, smooth = plant.

tests/data/plant_reference.npz (tools/make_plant_reference.py) holds six closed-loop command sequences
and the plant's replayed series at commit 978d6c4 (the plant code of 8546529, before its equations were
written once).
"""

import dataclasses
import math
import sys
from pathlib import Path

import casadi
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ceco_core.air_quality import KGKG_PER_PPM
from ceco_core.psychro import humidity_ratio
from ceco_plant_sim.compiled_plant import PlantEvaluation
from ceco_plant_sim.plant_equations import (
    NO_GUESS,
    Env,
    Guess,
    Input,
    NewtonCycle,
    PlantEquations,
    State,
    blower_power_w,
)
from ceco_plant_sim.plant_model import PlantModel
from ceco_plant_sim.plant_ops import NUMERIC, SmoothSettings
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.plant_state import PlantState
from ceco_plant_sim.refrigerant import cycle_tables
from ceco_plant_sim.replay import REPLAY_SERIES, replay_commands

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import make_plant_reference as ref  # noqa: E402  (the tool that wrote the reference file)

FULL_RUN = ("sc03_hotsoak", "baseline")
"""Replayed whole (600 s: MOP valve, inverter power limit, pull-down, regulation)."""
PARTIAL_STEPS = 200
"""The other reference runs are compared over their first 200 s (all six were checked whole: docs/plant.md)."""
SMOOTH_RUNS = (("sc03", "baseline"), ("sc03", "ceco"), ("udds", "baseline"), ("udds", "ceco"))
"""The recorded runs the smooth model replays whole (baseline and NMPC, SC03 and UDDS)."""


@pytest.fixture(scope="module")
def reference():
    return ref.load()


@pytest.fixture(scope="module")
def plant_replays(reference):
    """The numeric plant's replay of each recorded run (whole for FULL_RUN and SMOOTH_RUNS, else 200 steps)."""
    prov, arrays = reference
    out = {}
    for note in prov["runs"]:
        run = (note["scenario"], note["strategy"])
        key = ref.run_key(*run)
        n = note["steps"] if run == FULL_RUN or run in SMOOTH_RUNS else PARTIAL_STEPS
        m, t = arrays[f"{key}__mdot_bl_kgps"][:n], arrays[f"{key}__t_evap_sp_c"][:n]
        out[run] = (replay_commands(run[0], m, t, evaluation=PlantEvaluation("python")), m, t)
    return out


@pytest.fixture(scope="module")
def smooth():
    return PlantModel.smooth()


@pytest.fixture(scope="module")
def exact():
    return PlantModel.exact(door_input=True)


# ---------------------------------------------------------------- (a) the numeric path
def test_numeric_plant_equals_the_reference_trajectories(reference, plant_replays):
    """Every recorded series (states, powers, energies, PMV) within 1e-9 of its scale (measured: bit-identical)."""
    prov, arrays = reference
    names = prov["series"]  # recorded before issue 21; the code records the door and CO2 besides
    assert set(names) <= set(REPLAY_SERIES) and len(names) >= 40
    assert {"meas_co2_cab_ppm", "co2_cab_ppm", "recirc_share"} <= set(REPLAY_SERIES) - set(names)
    for run, (rep, m, _) in plant_replays.items():
        key = ref.run_key(*run)
        idx = arrays[f"{key}__sample_index"]
        keep = idx < m.size
        want = arrays[f"{key}__samples"][:, keep]
        got = np.stack([rep.series[k][idx[keep]] for k in names])
        scale = np.maximum(np.max(np.abs(want), axis=1, keepdims=True), 1e-300)
        rel = np.abs(got - want) / scale
        worst = names[int(np.argmax(rel.max(axis=1)))]
        assert rel.max() <= 1e-9, f"{run}: {worst} differs by {rel.max():.3g} of its scale"
        assert int(keep.sum()) >= PARTIAL_STEPS // ref.SAMPLE_EVERY
        if m.size == next(n["steps"] for n in prov["runs"] if (n["scenario"], n["strategy"]) == run):
            e_ref = float(arrays[f"{key}__energy_j"])
            assert abs(rep.energy_j() - e_ref) <= 1e-9 * e_ref
    assert plant_replays[FULL_RUN][0].series["t_s"].size == 600
    s = plant_replays[FULL_RUN][0].series  # the run exercises the switches it is meant to
    assert s["mop_active"].max() == 1.0 and s["capacity_limited"].max() == 1.0 and s["q_latent_w"].max() > 500.0


# ---------------------------------------------------------------- (b) the exact symbolic model
_STATE = st.tuples(
    st.floats(15.0, 60.0),  # t_cab
    st.floats(15.0, 65.0),  # t_int
    st.floats(15.0, 65.0),  # t_shell
    st.floats(15.0, 60.0),  # t_glass
    st.floats(0.5, 60.0),  # t_evap
    st.floats(5.0, 60.0),  # t_duct
    st.floats(0.1, 0.9),  # cabin rh -> w_cab
    st.floats(-2000.0, 9000.0),  # PI integral
    st.floats(0.0, 1.0),  # door position
    st.floats(400.0, 5000.0),  # cabin CO2 [ppm]
)
_CMD = st.tuples(st.floats(0.05, 0.17), st.floats(3.0, 10.0), st.floats(0.0, 1.0))
_ENV = st.tuples(st.floats(20.0, 45.0), st.floats(0.0, 1000.0), st.floats(0.0, 35.0), st.floats(0.1, 0.9))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(state=_STATE, cmd=_CMD, env=_ENV, warm=st.booleans())
def test_exact_model_equals_the_numeric_step_at_random_states(exact, state, cmd, env, warm):
    """One plant step (2 RK4 sub-steps, 8 refrigerant solves or more) of the exact CasADi model = the simulator's.

    Measured: within 4e-16 relative (last-bit differences of numpy's and libm's exp and pow in the
    water saturation pressure), never a different branch.
    """
    p = exact.params
    x = State(*state[:6], humidity_ratio(state[0], state[6], p.p_atm_pa), state[7], state[8], state[9] * KGKG_PER_PPM)
    u, e = Input(*cmd), Env(*env)
    numeric = PlantEquations(p, NewtonCycle(p, cycle_tables()), NUMERIC)
    guess = NO_GUESS
    if warm:  # a warm start from a solve at a nearby speed, as the previous stage leaves it
        guess = numeric.rhs(x, u, 0.0, e, NO_GUESS)[3]
    x1, acc, g1, ok = numeric.step(x, u, e, exact.plant_dt_s, guess)
    y1 = numeric.rhs(x1, u, blower_power_w(p, u.mdot_bl_kgps), e, g1)[2]
    xs, es, ys, gs, oks = exact.step(list(x), list(u), list(e), list(guess))
    assert float(oks) == 1.0 and ok
    for got, want in ((xs, x1), (gs, g1), (ys, y1)):
        got = np.asarray(got, dtype=float).ravel()
        want = np.asarray([float(v) for v in want])
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12), got - want
    energy = exact.energy.named(es)
    assert energy["e_comp_j"] == pytest.approx(acc.p_comp_w, rel=1e-12, abs=1e-9)
    assert energy["e_cond_fan_j"] == pytest.approx(acc.p_cond_fan_w, rel=1e-12, abs=1e-9)
    assert energy["m_condensate_kg"] == pytest.approx(acc.mdot_condensate_kgps, rel=1e-12, abs=1e-15)
    assert energy["m_co2_gen_kg"] == pytest.approx(acc.mdot_co2_gen_kgps, rel=1e-12)


def test_exact_model_replays_the_hot_start_with_its_warm_start(exact, plant_replays):
    """60 s of the one-hour hot soak (MOP pin, power-limit secant, warm start carried from step to step)."""
    rep, m, t = plant_replays[FULL_RUN]
    n = 60
    x0, envs, comfort, pa = exact.scenario_drive(FULL_RUN[0], n)
    door = np.full(n, exact.params.recirc_fraction)  # the door model, its command at the plant's default
    r = exact.replay(x0, np.column_stack([m[:n], t[:n], door]), envs, comfort=comfort, pa_pa=pa)
    assert r["ok"].all()
    compared = [name for name in exact.state.names if name in rep.series]
    assert len(compared) == 8  # every state but the PI integral and CO2 (recorded in ppm: below)
    for name in compared:
        i = exact.state.index(name)
        assert np.allclose(r["x"][1:, i], rep.series[name][:n], rtol=1e-12, atol=1e-12), name
    co2 = r["x"][1:, exact.state.index("co2_cab_kgkg")] / KGKG_PER_PPM
    assert np.allclose(co2, rep.series["co2_cab_ppm"][:n], rtol=1e-12)
    e = r["energy"][:, exact.energy.index("e_comp_j")]
    assert np.allclose(e, rep.series["e_comp_j"][:n], rtol=1e-12)
    assert np.allclose(r["pmv"], rep.series["pmv"][:n], rtol=0.0, atol=1e-12)
    assert rep.series["mop_active"][:n].max() == 1.0 and rep.series["capacity_limited"][:n].mean() > 0.9


def test_exact_model_reports_a_solve_that_does_not_converge():
    """The masked solve's flag: with a 2-evaluation cap the exact model says ok = 0 where the simulator raises."""
    p = dataclasses.replace(PlantParams(), cycle_max_iter=2)
    model = PlantModel.exact(p)
    x = [43.0, 46.0, 48.0, 48.0, 43.0, 43.0, 0.012, 0.0, 0.8, 425.0 * KGKG_PER_PPM]
    *_, ok = model.step(x, [0.17, 3.0], [35.0, 850.0, 0.0, 0.4], [0.0, 0.0, 0.0])
    assert float(ok) == 0.0
    numeric = PlantEquations(p, NewtonCycle(p, cycle_tables()), NUMERIC)
    with pytest.raises(RuntimeError, match="did not converge in 2 iterations"):
        numeric.step(State(*x), Input(0.17, 3.0, 0.8), Env(35.0, 850.0, 0.0, 0.4), 1.0, NO_GUESS)


# ---------------------------------------------------------------- (c) the smooth symbolic model
@pytest.mark.parametrize("run", SMOOTH_RUNS, ids=["/".join(r) for r in SMOOTH_RUNS])
def test_smooth_model_replays_recorded_runs(smooth, plant_replays, run):
    """The issue's tolerances: energy within 0.3 %, scored PMV within 0.01 at every step (measured: 0.008 %, 0.0025)."""
    rep, m, t = plant_replays[run]
    x0, envs, comfort, pa = smooth.scenario_drive(run[0], m.size)
    r = smooth.replay(x0, np.column_stack([m, t]), envs, comfort=comfort, pa_pa=pa)
    e_model = float(np.sum(r["energy"][:, smooth.energy.index("e_total_j")]))
    assert e_model == pytest.approx(rep.energy_j(), rel=3e-3)
    e_comp = float(np.sum(r["energy"][:, smooth.energy.index("e_comp_j")]))
    assert e_comp == pytest.approx(float(np.sum(rep.series["e_comp_j"])), rel=3e-3)
    assert np.max(np.abs(r["pmv"] - rep.series["pmv"])) <= 0.01
    assert np.max(np.abs(r["x"][1:, 0] - rep.series["t_cab_c"])) <= 0.05  # cabin air [K]
    assert r["table_margin"].min() >= 0.0  # never outside the smooth cycle table's box (0: standstill, its edge)
    # the energy split is the plant's: blower exactly (the same fan law), condenser fan with the duty
    assert np.sum(r["energy"][:, smooth.energy.index("e_blower_j")]) == pytest.approx(
        np.sum(rep.series["e_blower_j"]), rel=1e-12
    )


def test_smooth_step_is_differentiable_and_its_jacobian_matches_finite_differences(smooth):
    """d(step)/d(x, u) by CasADi AD against central differences at pull-down, regulation and duty-cycling states."""
    xs = casadi.SX.sym("x", 10)
    us = casadi.SX.sym("u", 2)
    es = casadi.SX.sym("e", 4)
    x1, energy, _ = smooth.step(xs, us, es)
    out = casadi.vertcat(x1, energy[smooth.energy.index("e_total_j")])
    jac = casadi.Function("step_jacobian", [xs, us, es], [casadi.jacobian(out, casadi.vertcat(xs, us)), out])
    env = [35.0, 850.0, 12.0, 0.4]
    states = (
        [43.0, 46.0, 48.0, 48.0, 40.0, 43.0, 0.0135, 0.0, 0.8, 6.5e-4],  # hot start: MOP and power limit
        [25.0, 30.0, 33.0, 32.0, 5.2, 15.0, 0.008, 2500.0, 0.5, 1.5e-3],  # regulation, the door moving
        [23.0, 26.0, 30.0, 30.0, 9.8, 14.0, 0.008, 100.0, 0.8, 2.0e-3],  # low load: duty-cycling below N_min
    )
    for x in states:
        u = [0.1, 5.0] if x[4] < 10.0 else [0.17, 3.0]
        j, _ = jac(x, u, env)
        j = np.asarray(j)
        assert np.all(np.isfinite(j))
        z = np.array(x + u)
        h = np.maximum(np.abs(z) * 1e-6, 1e-7)
        fd = np.empty_like(j)
        for k in range(z.size):
            zp, zm = z.copy(), z.copy()
            zp[k] += h[k]
            zm[k] -= h[k]
            fp = np.asarray(jac(zp[:10], zp[10:], env)[1]).ravel()
            fm = np.asarray(jac(zm[:10], zm[10:], env)[1]).ravel()
            fd[:, k] = (fp - fm) / (2 * h[k])
        scale = np.maximum(np.abs(j), 1e-3 * np.max(np.abs(j), axis=1, keepdims=True))
        assert np.max(np.abs(fd - j) / scale) < 2e-4, np.max(np.abs(fd - j) / scale)  # measured 1e-5 .. 3.4e-5


def test_smoothing_bounds_of_the_plant_pieces():
    """Each smoothed kink and switch of the rhs within its documented bound (SmoothSettings docstrings)."""
    from ceco_plant_sim.plant_ops import SmoothOps

    s = SmoothSettings()
    ops = SmoothOps(s)
    z = casadi.SX.sym("z")
    sn, sd, sw, se, sdoor = (ops.scaled(k) for k in ("speed", "duty", "water", "err", "door"))
    f = casadi.Function(
        "pieces",
        [z],
        [
            sn.fmin(sn.fmax(z, 800.0), 8600.0),  # compressor speed while running [rpm]
            sd.fmin(sd.fmax(z / 800.0, 0.0), 1.0),  # duty
            sw.fmax(z * 1e-5, 0.0),  # condensation excess [kg/kg]
            se.gt(z * 1e-4, 0.0),  # sign of the evaporator error
            sdoor.fmin(sdoor.fmax(z * 1e-4, -0.2), 0.2),  # door speed [1/s] under its rate limit
        ],
    )
    ln2 = math.log(2.0)
    for n in np.linspace(-3000.0, 12000.0, 1501):
        speed, duty, excess, sign, door = (float(v) for v in f(n))
        assert abs(door - min(max(n * 1e-4, -0.2), 0.2)) <= ln2 / s.k_door_s + 1e-12
        assert abs(speed - min(max(n, 800.0), 8600.0)) <= ln2 / s.k_speed_per_rpm + 1e-9
        assert abs(duty - min(max(n / 800.0, 0.0), 1.0)) <= ln2 / s.k_duty + 1e-12
        assert -1e-15 <= excess - max(n * 1e-5, 0.0) <= ln2 / s.k_water_per_kgkg + 1e-15
        err = n * 1e-4
        if err != 0.0:
            assert abs(sign - (err > 0.0)) <= math.exp(-abs(err) / s.w_err_k) + 1e-15
    # the bounds are tight at the kinks: a sharper setting gets closer
    assert abs(float(f(800.0)[0]) - 800.0) > 0.5 * ln2 / s.k_speed_per_rpm


def test_layouts_name_every_slot(smooth, exact):
    assert smooth.state.names == tuple(f.name for f in dataclasses.fields(PlantState))
    assert smooth.step.size1_in(0) == 10 and smooth.step.size1_in(1) == 2 and smooth.step.size1_in(2) == 4
    assert exact.step.n_in() == 4 and smooth.step.n_in() == 3
    assert exact.input.names == ("mdot_bl_kgps", "t_evap_sp_c", "recirc_share") and exact.step.size1_in(1) == 3
    assert smooth.input.names == ("mdot_bl_kgps", "t_evap_sp_c") and not smooth.door_input
    assert exact.aq.names == ("co2_cab_ppm", "fog_margin_k")
    assert smooth.energy.index("e_total_j") == 3
    with pytest.raises(KeyError, match="not one of"):
        smooth.state.index("t_cabin")
    with pytest.raises(ValueError, match="vector of 3 values"):
        smooth.input.named([1.0, 2.0, 3.0])
    assert smooth.input.named([0.1, 5.0]) == {"mdot_bl_kgps": 0.1, "t_evap_sp_c": 5.0}
    assert Guess(*exact.warm.vector({"t_evap_sat_c": 1.0, "t_cond_c": 2.0, "valid": 1.0})).valid == 1.0
