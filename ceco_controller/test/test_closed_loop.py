"""Closed loop on the real plant, scenarios and comfort: bounds, run directory, determinism, faults."""

import csv
import json
import math

import numpy as np
import pytest

from ceco_controller import closed_loop as cl
from ceco_core.contracts import DIAGNOSTICS_COLUMNS, STRATEGIES
from ceco_v2x_preview.preview import parse_quality

SHORT = cl.SimSettings(duration_s=60.0, progress=False)


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_strategy_respects_actuator_bounds(strategy):
    """The whole of SC03 (the first minute sits on the bounds' corner; ceco-pmv, ceco and ceco-ioch leave it from
    330, 390 and 455 s)."""
    res = cl.simulate("sc03", strategy, cl.SimSettings(progress=False))
    ts = res.timeseries
    assert ts["t_s"].size == 600 and len(res.diagnostics) == 120
    assert np.all((ts["mdot_bl_kgps"] >= 0.05) & (ts["mdot_bl_kgps"] <= 0.17))
    assert np.all((ts["t_evap_sp_c"] >= 3.0) & (ts["t_evap_sp_c"] <= 10.0))
    # the command is held over each control period, both of its parts
    for c in ("mdot_bl_kgps", "t_evap_sp_c"):
        assert np.all(np.diff(ts[c].reshape(120, 5), axis=1) == 0), c
    if strategy != "baseline":  # the NMPC commands inside the range, not only at its corner
        assert len(np.unique(ts["t_evap_sp_c"])) > 1 and len(np.unique(ts["mdot_bl_kgps"])) > 2
    assert np.all(np.isfinite(ts["pmv"])) and res.metrics["E_tot_J"] > 0


def test_run_directory_format_and_determinism(tmp_path):
    a = cl.simulate("sc03", "ceco-ioch", SHORT)
    b = cl.simulate("sc03", "ceco-ioch", SHORT)
    for c in cl.TIMESERIES_COLUMNS:
        np.testing.assert_array_equal(a.timeseries[c], b.timeseries[c])
    # the controller's numbers too: every diagnostics field but the wall times, and the predicted PMV
    timed = ("solve_time_ms", "step_time_ms")
    rows = lambda r: [{k: v for k, v in row.items() if k not in timed} for row in r.diagnostics]  # noqa: E731
    assert len(a.diagnostics) == 12 and repr(rows(a)) == repr(rows(b))
    for x, y in zip(a.diag_objects, b.diag_objects):
        np.testing.assert_array_equal(x.pred_pmv, y.pred_pmv)
    d = cl.write_run(a, tmp_path / "run")
    with open(d / "timeseries.csv") as fh:
        header = next(csv.reader(fh))
    assert tuple(header[:20]) == cl.TIMESERIES_COLUMNS[:20]
    with open(d / "diagnostics.csv") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == DIAGNOSTICS_COLUMNS + ("pmv_pred", "t_cab_pred_c", "step_time_ms")
    # every control step's wall time is recorded (a positive finite number; its size is not tested)
    assert all(0.0 < float(dict(zip(rows[0], r))["step_time_ms"]) < math.inf for r in rows[1:])
    # predicted PMV and T_cab over the grid points 0..Np of every successful solve
    checked = 0
    for row in rows[1:]:
        r = dict(zip(rows[0], row))
        if r["success"] == "1":
            pmv = [float(v) for v in r["pmv_pred"].split(";")]
            tcab = [float(v) for v in r["t_cab_pred_c"].split(";")]
            assert len(pmv) == len(tcab) == 7 and 20.0 < tcab[0] < 70.0 and abs(float(r["pmv_pred_1"]) - pmv[1]) < 1e-4
            checked += 1
    assert checked == len(rows) - 1 == 12  # every one of the 12 solves succeeded and was checked
    m = json.loads((d / "metrics.json").read_text())
    for key in (
        "E_tot_J",
        "I_pmv",
        "otc_violation_pct",
        "scenario",
        "strategy",
        "control_period_s",
        "horizon_steps",
        "seed",
        "preview_quality",
    ):
        assert key in m
    assert m["strategy"] == "ceco-ioch" and m["horizon_steps"] == 6


@pytest.mark.parametrize("strategy", ["ceco", "ceco-e", "ceco-c", "ceco-ioch"])
def test_missing_preview_span_does_not_crash(strategy):
    q = parse_quality("missing:10-40,policy=drop")
    res = cl.simulate("sc03", strategy, cl.SimSettings(duration_s=60.0, progress=False, preview_quality=q))
    th = [d.trusted_horizon for d in res.diag_objects]
    assert 0 in th and 7 in th  # degraded inside the span, full horizon outside
    assert all(d.fallback != "baseline" or d.k == 0 for d in res.diag_objects)


def test_ceco_inside_pmv_bounds_after_pulldown():
    """SC03: ceco keeps the plant's PMV inside the bounds once the pull-down allows it (tolerance 0.02 PMV).

    SC03 starts after the regulation's 10-minute soak; the scenario's upper bound
    relaxes the pull-down (3.0 at 30 s, linearly to +0.5 at 300 s). With the
    occupant's environment in the scored PMV (docs/comfort.md: T_mr of the
    sun-heated surfaces, body-average air speed) and the HVAC case/duct mass, the
    cabin cannot follow that ramp: until t = 319 s every CECO strategy holds the
    coldest command the actuator bounds allow (0.17 kg/s, 3 degC; measured) and PMV
    is still above the bound (0.63 at 300 s). From 330 s on the bounds hold.
    Tolerance 0.02 PMV: the plant/model mismatch the robust back-off (0.1 PMV) has
    to absorb, with a margin.
    """
    res = cl.simulate("sc03", "ceco", cl.SimSettings(progress=False))
    ts = res.timeseries
    # after the first control period (t < 5 s: the vent air is the soaked 43 degC HVAC air, so the NMPC
    # starts at low flow), every violation of the upper bound happens at full cooling
    over = (ts["pmv"] > ts["pmv_ub"] + 0.02) & (ts["t_s"] >= 5.0)
    assert np.all(ts["mdot_bl_kgps"][over] >= 0.17 - 1e-3) and np.all(ts["t_evap_sp_c"][over] <= 3.0 + 1e-3)
    after = ts["t_s"] >= 330.0
    assert after.sum() > 250
    assert np.all(ts["pmv"][after] <= ts["pmv_ub"][after] + 0.02)
    assert np.all(ts["pmv"][after] >= ts["pmv_lb"][after] - 0.02)
    assert np.max(ts["pmv_ub"][after]) <= 0.5 + 1e-9  # the bound really is the comfort zone there
    assert res.metrics["n_fallback_baseline"] == 0
