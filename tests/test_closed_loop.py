"""Closed loop on the real plant, scenarios and comfort: bounds, run directory, determinism, faults."""
import csv
import json

import numpy as np
import pytest

from ceco_controller import closed_loop as cl
from ceco_controller.interface import DIAGNOSTICS_COLUMNS
from ceco_controller.strategies import STRATEGIES
from ceco_v2x_preview.preview import parse_quality

SHORT = cl.SimSettings(duration_s=60.0, progress=False)


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_every_strategy_respects_actuator_bounds(strategy):
    res = cl.simulate("sc03", strategy, SHORT)
    ts = res.timeseries
    assert ts["t_s"].size == 60 and len(res.diagnostics) == 12
    assert np.all((ts["mdot_bl_kgps"] >= 0.05) & (ts["mdot_bl_kgps"] <= 0.17))
    assert np.all((ts["t_evap_sp_c"] >= 3.0) & (ts["t_evap_sp_c"] <= 10.0))
    # the command is held over each control period
    assert np.all(np.diff(ts["mdot_bl_kgps"].reshape(12, 5), axis=1) == 0)
    assert np.all(np.isfinite(ts["pmv"])) and res.metrics["E_tot_J"] > 0


def test_run_directory_format_and_determinism(tmp_path):
    a = cl.simulate("sc03", "ceco-ioch", SHORT)
    b = cl.simulate("sc03", "ceco-ioch", SHORT)
    for c in cl.TIMESERIES_COLUMNS:
        np.testing.assert_array_equal(a.timeseries[c], b.timeseries[c])
    d = cl.write_run(a, tmp_path / "run")
    with open(d / "timeseries.csv") as fh:
        header = next(csv.reader(fh))
    assert tuple(header[:20]) == cl.TIMESERIES_COLUMNS[:20]
    with open(d / "diagnostics.csv") as fh:
        assert tuple(next(csv.reader(fh))) == DIAGNOSTICS_COLUMNS
    m = json.loads((d / "metrics.json").read_text())
    for key in ("E_tot_J", "I_pmv", "otc_violation_pct", "scenario", "strategy", "control_period_s",
                "horizon_steps", "seed", "preview_quality"):
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
    """ceco keeps PMV inside the comfort zone once the pull-down relaxation ends (tolerance 0.05 PMV).

    Run on sc03_mild: with the current plant the SC03 comfort zone is not reachable
    by any controller within 600 s (max cooling still has PMV > 0.5 at the end;
    docs/results.md), so the claim is tested where the zone is reachable.
    """
    res = cl.simulate("sc03_mild", "ceco", cl.SimSettings(progress=False))
    ts = res.timeseries
    after = ts["t_s"] >= 240.0
    assert np.all(ts["pmv"][after] <= ts["pmv_ub"][after] + 0.05)
    assert np.all(ts["pmv"][after] >= ts["pmv_lb"][after] - 0.05)
    assert res.metrics["n_fallback_baseline"] == 0
