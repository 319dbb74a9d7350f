"""The smooth refrigerant-cycle table: its samples are the solver's, its splines stay close to it off the grid."""

import dataclasses
import json
import shutil

import numpy as np
import pytest

from ceco_plant_sim.plant_model import PlantModel
from ceco_plant_sim.plant_params import PlantParams
from ceco_plant_sim.smooth_cycle import (
    SHIPPED_SMOOTH_TABLE,
    TABLE_OUTPUTS,
    SmoothCycleGrid,
    StaleSmoothTableError,
    _power_limit_speed,
    _solver,
    build_smooth_cycle_table,
    check_smooth_cycle_file,
    load_smooth_cycle_file,
    smooth_cycle_table,
)

COARSE = SmoothCycleGrid(
    speed_rpm=(700.0, 8700.0, 5), t_wall_c=(0.0, 66.0, 7), t_amb_c=(20.0, 45.0, 5), vehicle_speed_mps=(0.0, 45.0, 4)
)


@pytest.fixture(scope="module")
def tab():
    return load_smooth_cycle_file()


@pytest.fixture(scope="module")
def solve():
    return _solver(PlantParams())


def test_shipped_table_is_the_solvers_sampling(tab):
    """200 random grid points and power-limit speeds equal a fresh sampling bit for bit (the tool checks all)."""
    prov = check_smooth_cycle_file(SHIPPED_SMOOTH_TABLE, sample=200, seed=7)
    assert prov["command"] == "python tools/make_smooth_cycle_table.py"
    assert prov["outputs"] == list(TABLE_OUTPUTS)
    assert tab.source.startswith("shipped file smooth_cycle_R1234yf.npz")
    assert smooth_cycle_table() is smooth_cycle_table(PlantParams())  # cached, from the file
    assert smooth_cycle_table().source == tab.source


def test_changed_or_foreign_file_is_stale(tmp_path, tab):
    bad = tmp_path / "t.npz"
    shutil.copy(SHIPPED_SMOOTH_TABLE, bad)
    with np.load(bad) as z:
        members = {k: z[k] for k in z.files}
    members["p_comp_w"] = members["p_comp_w"].copy()
    members["p_comp_w"][3, 5, 2, 1] = np.nextafter(members["p_comp_w"][3, 5, 2, 1], 0.0)  # one ulp
    np.savez(bad, **members)
    with pytest.raises(StaleSmoothTableError, match=r"p_comp_w at grid point \(3, 5, 2, 1\)"):
        check_smooth_cycle_file(str(bad), points=[(3, 5, 2, 1)])
    prov = json.loads(str(members["provenance"]))
    prov["format"] = 99
    members["provenance"] = np.array(json.dumps(prov))
    np.savez(bad, **members)
    with pytest.raises(StaleSmoothTableError, match="format 99"):
        load_smooth_cycle_file(str(bad))
    with pytest.raises(StaleSmoothTableError, match="p_comp_max_w = 3500.0, the plant has 3000.0"):
        tab.check_params(dataclasses.replace(PlantParams(), p_comp_max_w=3000.0))
    tab.check_params(dataclasses.replace(PlantParams(), c_int_jpk=80000.0))  # not a cycle parameter


def test_splines_interpolate_the_samples(tab):
    for ix in [(0, 0, 0, 0), (4, 17, 8, 3), (10, 33, 12, 6), (6, 2, 11, 5)]:
        got = np.asarray(tab.cycle(*(a[i] for a, i in zip(tab.axes, ix, strict=True)))).ravel()
        want = np.array([tab.values[k][ix] for k in TABLE_OUTPUTS])
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
        lim = float(tab.n_lim(*(a[i] for a, i in zip(tab.axes[1:], ix[1:], strict=True))))
        assert lim == pytest.approx(tab.n_lim_rpm[ix[1:]], rel=1e-12)


def test_splines_against_the_solver_off_the_grid(tab, solve):
    """Random points of the box (speed N_min..N_max): the spline's error against the solver.

    Measured on 3000 points (tools/make_smooth_cycle_table.py --errors): capacity p95 0.22 % / max 0.96 %,
    compressor power p95 0.48 % / max 2.8 % (28 W), both largest beside the MOP and head-pressure kinks.
    """
    p = PlantParams()
    rng = np.random.default_rng(3)
    box = tab.box()
    rel_q, rel_p, abs_p = [], [], []
    for _ in range(300):
        x = [rng.uniform(p.comp_speed_min_rpm, p.comp_speed_max_rpm)] + [rng.uniform(lo, hi) for lo, hi in box[1:]]
        s = solve(*x)
        q, pc, t_e, mdot = np.asarray(tab.cycle(*x)).ravel()
        rel_q.append(abs(q / s.q_evap_ref_w - 1))
        rel_p.append(abs(pc / s.p_comp_w - 1))
        abs_p.append(abs(pc - s.p_comp_w))
        assert abs(t_e - s.t_evap_sat_c) < 0.35 and abs(mdot / s.mdot_ref_kgps - 1) < 0.03
    assert np.percentile(rel_q, 95) < 4e-3 and max(rel_q) < 0.015
    assert np.percentile(rel_p, 95) < 8e-3 and max(rel_p) < 0.04 and max(abs_p) < 40.0
    # the power-limit speed where it can bind (within 500 rpm of N_max or below)
    errs = []
    while len(errs) < 25:
        x = [rng.uniform(lo, hi) for lo, hi in box[1:]]
        want = _power_limit_speed(solve, p, *x)
        if want <= p.comp_speed_max_rpm + 500.0:
            errs.append(abs(float(tab.n_lim(*x)) - want))
    assert max(errs) < 30.0  # rpm (measured: p95 5, max 17)


def test_margin_says_when_the_box_is_left(tab):
    inside = float(tab.margin(4000.0, 10.0, 35.0, 600.0))
    assert 0.0 < inside <= 0.5
    assert float(tab.margin(4000.0, 70.0, 35.0, 600.0)) < 0.0  # a soak hotter than the grid
    assert float(tab.margin(4000.0, 10.0, 50.0, 600.0)) < 0.0
    # outside, the splines are clamped to the box, not extrapolated to 0
    q_edge = float(tab.cycle(4000.0, 66.0, 35.0, 600.0)[0])
    assert float(tab.cycle(4000.0, 70.0, 35.0, 600.0)[0]) == q_edge > 1000.0


def test_a_table_built_for_other_parameters_follows_them():
    """A lower inverter limit: a table built at run time (coarse grid) lowers the smooth model's power-limit speed."""
    p = dataclasses.replace(PlantParams(), p_comp_max_w=3000.0)
    low = build_smooth_cycle_table(p, COARSE)
    low.check_params(p)
    ref = build_smooth_cycle_table(PlantParams(), COARSE)
    assert np.array_equal(low.values["p_comp_w"], ref.values["p_comp_w"])  # the cycle itself is the same
    assert np.all(low.n_lim_rpm < ref.n_lim_rpm)
    solve = _solver(p)
    j, k, m = 5, 3, 1
    n = low.n_lim_rpm[j, k, m]
    assert solve(n, low.axes[1][j], low.axes[2][k], low.axes[3][m]).p_comp_w == pytest.approx(3000.0, rel=1e-9)
    model = PlantModel.smooth(p, table=low)
    x = [43.0, 46.0, 48.0, 48.0, 43.0, 43.0, 0.0135, 0.0, 0.8, 6.5e-4]
    energy = model.energy.named(model.step(x, [0.17, 3.0], [35.0, 850.0, 0.0, 0.4])[1])
    assert energy["e_comp_j"] == pytest.approx(3000.0, rel=5e-3)  # at the limit in the hot start
    with pytest.raises(StaleSmoothTableError, match="p_comp_max_w"):
        PlantModel.smooth(PlantParams(), table=low)


def test_sx_graphs_hold_one_call_with_the_splines_value_and_jacobian(tab):
    """In SX graphs the table is y(x*) + J(x*) (x - x*): the spline's value and Jacobian, one call per use."""
    import casadi

    x = casadi.SX.sym("x", 4)
    xm = casadi.MX.sym("x", 4)
    y_sx = tab.cycle(*casadi.vertsplit(x))
    y_mx = tab.cycle.function(*casadi.vertsplit(xm))
    f_sx = casadi.Function("f_sx", [x], [y_sx, casadi.jacobian(y_sx, x)])
    f_mx = casadi.Function("f_mx", [xm], [y_mx, casadi.jacobian(y_mx, xm)])
    rng = np.random.default_rng(3)
    box = tab.box()
    for _ in range(20):
        pt = [rng.uniform(lo, hi) for lo, hi in box]
        v_sx, j_sx = (np.asarray(a) for a in f_sx(pt))
        v_mx, j_mx = (np.asarray(a) for a in f_mx(pt))
        assert np.all(np.isfinite(j_sx))
        np.testing.assert_array_equal(v_sx, v_mx)
        np.testing.assert_allclose(j_sx, j_mx, rtol=1e-12, atol=1e-12 * np.max(np.abs(j_mx)))
        assert np.max(np.abs(j_mx)) > 0.0
    calls = [f_sx.instruction_id(k) for k in range(f_sx.n_instructions())].count(casadi.OP_CALL)
    assert calls == 1 + 4  # the value-and-Jacobian call, then one (cheap) forward call per direction
    # numeric arguments call the table Function itself
    assert float(tab.cycle(4000.0, 20.0, 35.0, 600.0)[0]) == float(tab.cycle.function(4000.0, 20.0, 35.0, 600.0)[0])
