"""Benchmark KPIs (ceco_core.kpis.compute_kpis) on hand-made series.

Each expected value is worked out by hand from a few samples, so a wrong clip,
band, sampling rule or unit conversion fails.
"""

import numpy as np
import pytest

from ceco_core import kpis as mt


def _series(pmv, ub=None, dt=10.0, **extra):
    n = len(pmv)
    cols = {
        "t_s": dt * np.arange(n),
        "p_comp_w": np.full(n, 1000.0),
        "p_blower_w": np.full(n, 100.0),
        "p_cond_fan_w": np.full(n, 50.0),
        "pmv": np.asarray(pmv, float),
        "pmv_lb": np.full(n, -0.5),
        "pmv_ub": np.full(n, 0.5) if ub is None else np.asarray(ub, float),
        "mdot_bl_kgps": np.full(n, 0.1),
        "t_evap_sp_c": np.full(n, 5.0),
    }
    cols.update(extra)
    return cols


PMV = [4.0, 1.5, 0.5, 0.0, -0.7, -4.0]
UB = [3.0, 3.0, 2.0, 0.5, 0.5, 0.5]


def test_energy_counts_every_consumer():
    k, notes = mt.compute_kpis(_series([0.0] * 360, dt=10.0))
    # 3600 s at 1000 + 100 + 50 W
    assert k["energy_comp_kwh"] == pytest.approx(1.0)
    assert k["energy_blower_kwh"] == pytest.approx(0.1)
    assert k["energy_fan_kwh"] == pytest.approx(0.05)
    assert k["energy_kwh"] == pytest.approx(1.15)
    assert k["energy_paper_kwh"] == pytest.approx(1.1)
    assert k["peak_comp_kw"] == 1.0 and k["duration_s"] == 3600.0
    no_fan = _series([0.0] * 360)
    del no_fan["p_cond_fan_w"]
    k2, n2 = mt.compute_kpis(no_fan)
    assert k2["energy_kwh"] == pytest.approx(1.1) and k2["energy_fan_kwh"] is None
    assert "p_cond_fan_w" in n2["energy_fan_kwh"]


def test_discomfort_clips_pmv_and_integrates_the_distance_outside_the_band():
    k, _ = mt.compute_kpis(_series(PMV, UB))
    # clipped [3, 1.5, .5, 0, -.7, -3] -> distances [2.5, 1, 0, 0, .2, 2.5], 10 s each
    assert k["discomfort_pmvh"] == pytest.approx(6.2 * 10 / 3600)
    assert k["i_pmv"] == pytest.approx((16 + 2.25 + 0.25 + 0 + 0.49 + 16) * 10)
    assert k["i_pmv_clipped"] == pytest.approx((9 + 2.25 + 0.25 + 0 + 0.49 + 9) * 10)
    # the band applies from the first sample whose bounds lie inside it (t = 30 s)
    assert k["band_start_s"] == 30.0
    assert k["discomfort_band_pmvh"] == pytest.approx((0 + 0.2 + 2.5) * 10 / 3600)
    assert k["pmv_mean_band"] == pytest.approx((0.0 - 0.7 - 4.0) / 3)
    # the paper's OTC violation uses the scenario's bounds: 4 > 3, -0.7 and -4 < -0.5
    assert k["otc_violation_pct"] == pytest.approx(100 * 3 / 6)
    assert mt.pmv_band_distance([0.5, 0.6, -3.5]).tolist() == pytest.approx([0.0, 0.1, 2.5])


def test_the_band_phase_splits_the_energy_and_reads_the_pmv_and_the_actuators_there():
    # PMV 0.6 and 0.7 cross the band's +0.5 edge inside the band phase (from t = 30 s) after it came to 0.4 there;
    # 0.8 and 1.5 lie before the band phase, 0.9 at its start is the pull-down's tail, not a crossing
    pmv = [0.8, 1.5, 0.5, 0.9, 0.4, 0.6, 0.7, 0.2]
    UB = [3.0, 3.0, 2.0, 0.5, 0.5, 0.5, 0.5, 0.5]
    comp = np.array([3000.0, 3000.0, 1000.0, 1000.0, 800.0, 600.0, 400.0, 200.0])
    k, _ = mt.compute_kpis(
        _series(
            pmv,
            UB,
            p_comp_w=comp,
            mdot_bl_kgps=np.array([0.17, 0.17, 0.10, 0.10, 0.08, 0.06, 0.12, 0.08]),
            t_evap_sp_c=np.array([3.0, 3.0, 4.0, 4.0, 6.0, 8.0, 10.0, 8.0]),
        )
    )
    assert k["band_start_s"] == 30.0
    assert k["pmv_above_band_s"] == 20.0  # 0.6 and 0.7, 10 s each
    # the pull-down comes to the edge at the first band-phase sample at or below +0.5 (0.4 at index 4; the 0.5 at
    # index 2 lies before the band phase)
    assert mt.edge_arrival_index(pmv, mt.band_phase([-0.5] * 8, UB)) == 4
    assert mt.edge_arrival_index([0.9, 0.5, 0.7], [False, True, True]) == 1
    assert mt.edge_arrival_index([0.9, 0.6, 0.7], [True, True, True]) is None
    # (1000 + 800 + 600 + 400 + 200) W of compressor + 5 x (100 + 50) W, 10 s each
    assert k["energy_band_kwh"] == pytest.approx((3000.0 + 750.0) * 10 / 3.6e6)
    assert k["energy_kwh"] == pytest.approx((comp.sum() + 8 * 150.0) * 10 / 3.6e6)
    assert k["t_evap_sp_mean_band_c"] == pytest.approx(7.2)
    assert k["mdot_bl_mean_band_kgps"] == pytest.approx(0.44 / 5)
    no_fan = _series(pmv, UB, p_comp_w=comp)
    del no_fan["p_cond_fan_w"]
    assert mt.compute_kpis(no_fan)[0]["energy_band_kwh"] == pytest.approx((3000.0 + 500.0) * 10 / 3.6e6)
    # never at or below +0.5 in the band phase: no crossing to count, said why
    k, notes = mt.compute_kpis(_series([0.8, 1.5, 0.9, 0.9, 0.7, 0.6, 0.6, 0.6], UB))
    assert k["pmv_above_band_s"] is None and "never came to the band's upper edge" in notes["pmv_above_band_s"]
    assert k["pmv_mean_band"] == pytest.approx(0.68)


def test_no_band_phase_gives_null_with_a_reason():
    k, notes = mt.compute_kpis(_series(PMV, [3.0] * 6))
    assert set(mt.BAND_PHASE_KEYS) < set(mt.KPI_KEYS)
    for key in mt.BAND_PHASE_KEYS:
        assert k[key] is None and "never lie inside" in notes[key]
    assert k["discomfort_pmvh"] > 0


def test_actuator_travel_counts_the_jumps_in_strokes():
    s = _series(
        [0.0] * 4, mdot_bl_kgps=np.array([0.05, 0.17, 0.17, 0.11]), t_evap_sp_c=np.array([3.0, 3.0, 10.0, 10.0])
    )
    k, _ = mt.compute_kpis(s)
    assert k["travel_mdot_kgps"] == pytest.approx(0.18)
    assert k["travel_t_evap_sp_k"] == pytest.approx(7.0)
    assert k["actuator_travel"] == pytest.approx(0.5 * (0.18 / 0.12 + 7.0 / 7.0))


def test_time_ratio_and_fallbacks():
    k, notes = mt.compute_kpis(
        _series([0.0] * 4), step_time_s=[0.01, 0.05, np.nan], control_period_s=5.0, fallback_steps=2
    )
    assert k["time_ratio_mean"] == pytest.approx(0.006) and k["time_ratio_max"] == pytest.approx(0.01)
    assert k["fallback_steps"] == 2.0
    k2, n2 = mt.compute_kpis(_series([0.0] * 4))
    assert k2["time_ratio_mean"] is None and k2["fallback_steps"] is None
    assert "wall times" in n2["time_ratio_max"] and "fallback" in n2["fallback_steps"]


def test_draught_fog_and_validity_from_the_comfort_columns():
    s = _series(
        [0.0] * 5,
        dr_pct=np.array([10.0, 25.0, 20.0, 35.0, 0.0]),
        fog_margin_k=np.array([5.0, 2.0, -0.5, 1.0, 3.0]),
        iso7730_valid=np.array([1.0, 1, 0, 1, 1]),
    )
    k, notes = mt.compute_kpis(s)
    assert k["draught_pct"] == pytest.approx(40.0)  # 25 and 35 > 20 (20 itself is not)
    assert k["draught_mean_pct"] == pytest.approx(18.0) and k["draught_max_pct"] == 35.0
    assert k["fog_margin_min_k"] == -0.5 and k["fog_risk_pct"] == pytest.approx(20.0)
    assert k["iso7730_invalid_pct"] == pytest.approx(20.0)
    assert not {"draught_pct", "fog_margin_min_k", "iso7730_invalid_pct"} & set(notes)


def test_missing_comfort_columns_are_said_clearly():
    k, notes = mt.compute_kpis(_series([0.0] * 5))
    for key, col in (
        ("draught_pct", "dr_pct"),
        ("draught_max_pct", "dr_pct"),
        ("fog_margin_min_k", "fog_margin_k"),
        ("fog_risk_pct", "fog_margin_k"),
        ("iso7730_invalid_pct", "iso7730_valid"),
    ):
        assert k[key] is None and notes[key] == f"run has no {col} column", key
    assert set(k) == set(mt.KPI_KEYS)
    assert all(v is not None for key, v in k.items() if key not in notes)


@pytest.mark.parametrize("col", ["pmv", "p_comp_w", "mdot_bl_kgps"])
def test_bad_series_name_the_column(col):
    s = _series([0.0] * 4)
    s[col] = np.array([0.0, np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match=col):
        mt.compute_kpis(s)
    with pytest.raises(ValueError, match="uniformly"):
        mt.compute_kpis(_series([0.0] * 4) | {"t_s": np.array([0.0, 1.0, 3.0, 4.0])})


def test_air_quality_kpis_on_a_hand_made_series():
    """10 s samples: CO2 1400, 1600, 1800, 1500, 1000 ppm against 1500: exposure (100 + 300) ppm x 10 s = 1.111 ppm h,
    max 1800, 2 of 5 samples above (the limit itself is not above); fog margins 5, 2.5, 4, 3, 1 K against 3 K:
    two samples below, 20 s; the run breaks the limits."""
    from ceco_core.air_quality import AirQualityLimits

    s = _series(
        [0.0] * 5,
        co2_cab_ppm=np.array([1400.0, 1600.0, 1800.0, 1500.0, 1000.0]),
        fog_margin_k=np.array([5.0, 2.5, 4.0, 3.0, 1.0]),
    )
    k, notes = mt.compute_kpis(s)
    assert k["co2_exposure_ppmh"] == pytest.approx(400.0 * 10.0 / 3600.0, rel=1e-12)
    assert k["co2_max_ppm"] == 1800.0 and k["co2_above_limit_pct"] == pytest.approx(40.0)
    assert k["fog_below_bound_s"] == 20.0 and k["air_quality_met"] == 0.0
    assert not {"co2_max_ppm", "fog_below_bound_s", "air_quality_met"} & set(notes)
    # a 2000 ppm limit and a 0.5 K fog bound: the same run meets both
    k2, _ = mt.compute_kpis(s, air_limits=AirQualityLimits(co2_limit_ppm=2000.0, fog_margin_min_k=0.5))
    assert k2["co2_exposure_ppmh"] == 0.0 and k2["co2_above_limit_pct"] == 0.0
    assert k2["fog_below_bound_s"] == 0.0 and k2["air_quality_met"] == 1.0


def test_air_quality_kpis_of_a_run_without_co2_are_unknown_never_zero():
    """A run recorded before issue 21 (no CO2 column, or a column of NaN read from an old bag): the CO2 KPIs are
    None with a note; air_quality_met is judged on the fog margin alone."""
    for co2 in (None, np.full(5, np.nan)):
        extra = {"fog_margin_k": np.full(5, 6.0)}
        if co2 is not None:
            extra["co2_cab_ppm"] = co2
        k, notes = mt.compute_kpis(_series([0.0] * 5, **extra))
        assert k["co2_max_ppm"] is None and k["co2_exposure_ppmh"] is None and "CO2" in notes["co2_max_ppm"]
        assert k["air_quality_met"] == 1.0 and k["fog_below_bound_s"] == 0.0
    with pytest.raises(ValueError, match="co2_cab_ppm"):
        mt.compute_kpis(_series([0.0] * 3, co2_cab_ppm=np.array([500.0, np.nan, 600.0])))
