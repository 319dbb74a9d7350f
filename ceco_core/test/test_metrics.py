"""Run metrics against analytic cases."""

import math

import numpy as np
import pytest

from ceco_core.metrics import (
    METRIC_KEYS,
    compute_metrics,
    relative_change_pct,
    run_metrics,
)

T = np.arange(600.0)  # 1 s samples, sample i covers [i, i + 1)


def _sc03_ub(t):
    return np.interp(t, [0.0, 60.0, 300.0, 600.0], [3.0, 3.0, 0.5, 0.5])


def test_constant_power():
    """E_tot counts compressor + blower + condenser fan (one definition in every output), parts beside it."""
    m = compute_metrics(T, 2000.0, np.full(600, 150.0), np.zeros(600), -0.5, 0.5, p_fan_w=np.full(600, 100.0))
    assert list(m) == list(METRIC_KEYS)
    assert m["duration_s"] == 600.0
    assert m["E_comp_J"] == 1.2e6 and m["E_blower_J"] == 9.0e4 and m["E_fan_J"] == 6.0e4
    assert m["E_tot_J"] == 1.35e6
    assert m["E_tot_kWh"] == pytest.approx(1.35e6 / 3.6e6, rel=1e-15)
    assert m["P_mean_w"] == 2250.0
    assert m["I_pmv"] == 0.0 and m["otc_violation_pct"] == 0.0
    assert m["time_to_comfort_s"] == 0.0
    with pytest.raises(TypeError, match="p_fan_w"):  # no silent compressor + blower only
        compute_metrics(T, 2000.0, 150.0, np.zeros(600), -0.5, 0.5)  # type: ignore[call-arg]


def test_run_metrics_reads_the_fan_column():
    cols = {"t_s": T, "p_comp_w": np.full(600, 2000.0), "p_blower_w": np.full(600, 150.0)}
    cols.update(p_cond_fan_w=np.full(600, 100.0), pmv=np.zeros(600), pmv_lb=np.full(600, -0.5))
    cols["pmv_ub"] = np.full(600, 0.5)
    assert run_metrics(cols)["E_tot_J"] == 1.35e6
    with pytest.raises(ValueError, match="p_cond_fan_w"):
        run_metrics({k: v for k, v in cols.items() if k != "p_cond_fan_w"})


def test_pmv_step():
    pmv = np.where(T < 100.0, 2.0, 0.2)
    m = compute_metrics(T, 0.0, 0.0, pmv, -0.5, _sc03_ub(T), p_fan_w=0.0)
    assert m["I_pmv"] == pytest.approx(4.0 * 100 + 0.04 * 500)  # PMV^2 * s
    assert m["time_to_comfort_s"] == 100.0
    assert m["pmv_mean"] == pytest.approx((2.0 * 100 + 0.2 * 500) / 600)
    assert (m["pmv_max"], m["pmv_min"]) == (2.0, 0.2)
    assert m["otc_violation_s"] == 0.0  # 2.0 is inside the relaxed bound


def test_violation_of_known_duration():
    pmv = np.full(600, 0.2)
    pmv[320:350] = 1.0  # above ub = 0.5 for 30 s
    pmv[400:412] = -0.8  # below lb = -0.5 for 12 s
    pmv[10:20] = 2.9  # below the relaxed ub = 3: no violation
    m = compute_metrics(T, 0.0, 0.0, pmv, -0.5, _sc03_ub(T), p_fan_w=0.0)
    assert m["otc_violation_s"] == 42.0
    assert m["otc_above_ub_s"] == 30.0 and m["otc_below_lb_s"] == 12.0
    assert m["otc_violation_pct"] == pytest.approx(7.0)
    # Comfort first reached at 20 s, kept 300 s: the later exits don't undo it.
    assert m["time_to_comfort_s"] == 20.0


def test_time_to_comfort_hold_rule_and_sub_second_sampling():
    pmv = np.full(600, 1.0)
    pmv[100:130] = 0.0  # 30 s in the zone: too short
    pmv[140:] = 0.4
    m = compute_metrics(T, 0.0, 0.0, pmv, -0.5, 3.0, p_fan_w=0.0)
    assert m["time_to_comfort_s"] == 140.0
    never = compute_metrics(T, 0.0, 0.0, np.full(600, 0.7), -0.5, 3.0, p_fan_w=0.0)
    assert math.isnan(never["time_to_comfort_s"])
    late = np.full(600, 1.0)
    late[560:] = 0.0  # enters 40 s before the end: not confirmed
    assert math.isnan(compute_metrics(T, 0.0, 0.0, late, -0.5, 3.0, p_fan_w=0.0)["time_to_comfort_s"])
    # dt = 0.5 s, starting at t = 10 s: times are relative to the start.
    t = 10.0 + 0.5 * np.arange(400)
    pmv = np.where(t < 60.0, 1.5, 0.0)
    m = compute_metrics(t, 1000.0, 0.0, pmv, -0.5, 3.0, p_fan_w=0.0)
    assert m["time_to_comfort_s"] == 50.0
    assert m["E_comp_J"] == pytest.approx(1000.0 * 200.0)
    assert m["I_pmv"] == pytest.approx(2.25 * 50.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(pmv=np.r_[np.zeros(599), np.nan]), "pmv: NaN"),
        (dict(p_comp_w=np.zeros(599)), "p_comp_w: length 599"),
        (dict(t_s=np.r_[T[:-1], 700.0]), "t_s: must be uniformly spaced"),
        (dict(t_s=T[::-1].copy()), "t_s: must be increasing"),
        (dict(pmv_ub=np.full(600, np.inf)), "pmv_ub"),
    ],
)
def test_bad_input(kwargs, message):
    args = dict(
        t_s=T, p_comp_w=np.zeros(600), p_blower_w=np.zeros(600), pmv=np.zeros(600), pmv_lb=-0.5, pmv_ub=0.5, p_fan_w=0.0
    )
    args.update(kwargs)
    with pytest.raises(ValueError) as err:
        compute_metrics(**args)
    assert message in str(err.value)
    with pytest.raises(ValueError, match="at least 2"):
        compute_metrics([0.0], [1.0], [1.0], [0.0], -0.5, 0.5, p_fan_w=0.0)


def test_relative_change():
    assert relative_change_pct(84.1, 100.0) == pytest.approx(-15.9)
    assert relative_change_pct(-0.2, -0.1) == pytest.approx(-100.0)
    assert relative_change_pct(0.0, 0.0) == 0.0
    assert math.isnan(relative_change_pct(1.0, 0.0))
    assert math.isnan(relative_change_pct(math.nan, 1.0))
