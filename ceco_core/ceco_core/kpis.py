"""The benchmark's key performance indicators of one run (issue 10; docs/metrics.md, "Benchmark KPIs").

:func:`compute_kpis`: energy of every A/C consumer, BOPTEST-style thermal discomfort in PMV h
outside the fixed ISO 7730 category B band, I_PMV plain and clipped to the seven-point scale, draught
and fog from the comfort model's series, actuator travel, peak compressor power, the computational
time ratio and fallbacks. Built on the statistics of :mod:`ceco_core.metrics` (one definition each);
``ceco_plant_sim.metrics`` re-exports both modules. Pure numpy; no ROS import.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ceco_core.air_quality import AirQualityLimits
from ceco_core.contracts import MDOT_BL_MAX_KGPS, MDOT_BL_MIN_KGPS, T_EVAP_SP_MAX_C, T_EVAP_SP_MIN_C
from ceco_core.metrics import (
    COMFORT_HOLD_S,
    J_PER_KWH,
    PMV_SCALE_LIMIT,
    UNIFORM_RTOL,
    as_series,
    draught_stats,
    fog_margin_stats,
    i_pmv_clipped,
    iso7730_invalid_pct,
    time_to_comfort,
)

__all__ = [
    "KPI_KEYS",
    "BAND_PHASE_KEYS",
    "COMFORT_BAND_PMV",
    "ACTUATOR_RANGES",
    "compute_kpis",
    "discomfort_pmvh",
    "DISCOMFORT_CEILING_KEYS",
    "discomfort_ceiling",
    "pmv_band_distance",
    "band_phase",
    "edge_arrival_index",
    "actuator_travel",
    "air_quality_kpis",
    "AIR_QUALITY_KEYS",
    "AIR_LIMIT_KEYS",
    "air_limit_entries",
    "air_limits_of",
    "run_air_quality",
    "breaks_air_quality",
]


COMFORT_BAND_PMV = (-0.5, 0.5)
"""ISO 7730:2005 category B comfort band of PMV [-]: the fixed band of the discomfort KPI."""

ACTUATOR_RANGES = {
    "mdot_bl_kgps": MDOT_BL_MAX_KGPS - MDOT_BL_MIN_KGPS,
    "t_evap_sp_c": T_EVAP_SP_MAX_C - T_EVAP_SP_MIN_C,
}
"""Full range of each A/C input (0.05-0.17 kg/s, 3-10 degC): actuator travel is counted in strokes."""

KPI_KEYS = (
    "energy_kwh",
    "energy_comp_kwh",
    "energy_blower_kwh",
    "energy_fan_kwh",
    "energy_paper_kwh",
    "discomfort_pmvh",
    "discomfort_band_pmvh",
    "band_start_s",
    "i_pmv",
    "i_pmv_clipped",
    "otc_violation_pct",
    "time_to_comfort_s",
    "pmv_mean_band",
    "pmv_above_band_s",
    "energy_band_kwh",
    "t_evap_sp_mean_band_c",
    "mdot_bl_mean_band_kgps",
    "draught_pct",
    "draught_mean_pct",
    "draught_max_pct",
    "fog_margin_min_k",
    "fog_risk_pct",
    "fog_below_bound_s",
    "co2_max_ppm",
    "co2_exposure_ppmh",
    "co2_above_limit_pct",
    "air_quality_met",
    "iso7730_invalid_pct",
    "actuator_travel",
    "travel_mdot_kgps",
    "travel_t_evap_sp_k",
    "peak_comp_kw",
    "time_ratio_mean",
    "time_ratio_max",
    "fallback_steps",
    "duration_s",
)
"""Keys of the ``kpis`` dict of :func:`compute_kpis`, in order."""

BAND_PHASE_KEYS = (
    "band_start_s",
    "discomfort_band_pmvh",
    "pmv_mean_band",
    "pmv_above_band_s",
    "energy_band_kwh",
    "t_evap_sp_mean_band_c",
    "mdot_bl_mean_band_kgps",
)
"""The KPIs of the band phase (:func:`band_phase`): None, with a note, when the band never applies."""


def pmv_band_distance(pmv, band=COMFORT_BAND_PMV, limit: float = PMV_SCALE_LIMIT) -> np.ndarray:
    """Distance of PMV outside the band [-].

    ``max(0, clip(PMV) - hi, lo - clip(PMV))`` with PMV clipped to ``[-limit, limit]``.
    """
    lo, hi = float(band[0]), float(band[1])
    y = np.clip(np.asarray(pmv, dtype=float), -limit, limit)
    return np.maximum(0.0, np.maximum(y - hi, lo - y))


def band_phase(pmv_lb, pmv_ub, band=COMFORT_BAND_PMV) -> np.ndarray:
    """Mask of the band phase: "from the moment the comfort band applies".

    True from the first sample at which the scenario's bounds lie inside the band
    (``lb >= lo`` and ``ub <= hi``, 1e-9 tolerance) to the end; all False if that never
    happens.
    """
    lb, ub = np.asarray(pmv_lb, dtype=float), np.asarray(pmv_ub, dtype=float)
    inside = (lb >= band[0] - 1e-9) & (ub <= band[1] + 1e-9)
    mask = np.zeros(inside.shape, dtype=bool)
    if inside.any():
        mask[int(np.argmax(inside)) :] = True
    return mask


def edge_arrival_index(pmv, zone, band=COMFORT_BAND_PMV) -> int | None:
    """Index of the first sample of the band phase at which the PMV is at or below the band's upper edge, or None.

    ``zone`` is :func:`band_phase`'s mask. At that sample the pull-down has come to the edge: ``pmv_above_band_s``
    counts the samples above the edge from there on (the pull-down's tail before it is no crossing), and the oracle
    that holds the edge (``ceco_controller.oracle``, ``OracleSettings.hold_edge_from_s``) is held from there.
    """
    y, z = np.asarray(pmv, dtype=float), np.asarray(zone, dtype=bool)
    idx = np.flatnonzero(z & (y <= band[1]))
    return int(idx[0]) if idx.size else None


def actuator_travel(mdot_bl_kgps, t_evap_sp_c, ranges: Mapping[str, float] = ACTUATOR_RANGES) -> tuple:
    """BOPTEST's actuator travel of the two held A/C inputs.

    Returns ``(travel, travel_mdot, travel_sp)``: ``travel_x = sum_i |x_{i+1} - x_i|`` (the
    integral of |dx/dt| of a held step signal) in the input's unit [kg/s, K], and ``travel``
    the mean over the two inputs of ``travel_x / range_x`` [full-range strokes].
    """
    m = np.asarray(mdot_bl_kgps, dtype=float)
    s = np.asarray(t_evap_sp_c, dtype=float)
    tm = float(np.sum(np.abs(np.diff(m))))
    tsp = float(np.sum(np.abs(np.diff(s))))
    return 0.5 * (tm / ranges["mdot_bl_kgps"] + tsp / ranges["t_evap_sp_c"]), tm, tsp


def _column(columns: Mapping, key: str, n: int, notes: dict, why: str):
    if key not in columns or columns[key] is None:
        notes[why] = f"run has no {key} column"
        return None
    return as_series(key, columns[key], n)


def _unrecorded(series) -> bool:
    """True for a series that was not recorded: None, empty or all NaN (read from a bag of an older format)."""
    if series is None:
        return True
    a = np.asarray(series, dtype=float)
    return a.size == 0 or bool(np.all(np.isnan(a)))


def air_quality_kpis(co2_cab_ppm, fog_margin_k, dt_s: float, limits: AirQualityLimits) -> tuple[dict, dict]:
    """The air-quality KPIs of uniform samples ``dt_s`` [s] apart (docs/metrics.md, "Air quality").

    ``co2_max_ppm`` [ppm]; ``co2_exposure_ppmh``, the time integral of the CO2 above ``limits.co2_limit_ppm``
    [ppm h]; ``co2_above_limit_pct``, the share of samples above it [%]; ``fog_below_bound_s``, the time with the
    fog margin below ``limits.fog_margin_min_k`` [s]; ``air_quality_met`` 1.0 when the run never passes either
    limit, else 0.0. Either series may be None (not recorded) or all NaN (a run of before issue 21): its KPIs are
    then None with a note, and ``air_quality_met`` is judged on the other alone (None when neither exists).
    Returns ``(kpis, notes)``.
    """
    k: dict = {key: None for key in ("co2_max_ppm", "co2_exposure_ppmh", "co2_above_limit_pct")}
    k["fog_below_bound_s"] = k["air_quality_met"] = None
    notes: dict = {}
    met = []
    if _unrecorded(co2_cab_ppm):
        for key in ("co2_max_ppm", "co2_exposure_ppmh", "co2_above_limit_pct"):
            notes[key] = "run has no cabin CO2 series (not recorded)"
    else:
        c = as_series("co2_cab_ppm", co2_cab_ppm, None)
        over = np.maximum(c - limits.co2_limit_ppm, 0.0)
        k["co2_max_ppm"] = float(np.max(c))
        k["co2_exposure_ppmh"] = float(np.sum(over) * dt_s / 3600.0)
        k["co2_above_limit_pct"] = 100.0 * float(np.count_nonzero(over > 0.0)) / c.size
        met.append(not np.any(over > 0.0))
    if _unrecorded(fog_margin_k):
        notes["fog_below_bound_s"] = "run has no fog margin series"
    else:
        f = as_series("fog_margin_k", fog_margin_k, None)
        below = f < limits.fog_margin_min_k
        k["fog_below_bound_s"] = float(np.count_nonzero(below)) * dt_s
        met.append(not np.any(below))
    if met:
        k["air_quality_met"] = 1.0 if all(met) else 0.0
    else:
        notes["air_quality_met"] = "run has neither a CO2 nor a fog margin series"
    return k, notes


AIR_QUALITY_KEYS = ("co2_max_ppm", "co2_exposure_ppmh", "co2_above_limit_pct", "fog_below_bound_s", "air_quality_met")
"""The air-quality KPIs of :func:`air_quality_kpis`, in order; a run's ``metrics.json`` has them too
(:func:`run_air_quality`)."""

AIR_LIMIT_KEYS = ("co2_limit_ppm", "fog_margin_bound_k")
"""Where a run's ``metrics.json`` records the limits its air quality was scored against [ppm, K]
(``AirQualityLimits.co2_limit_ppm`` and ``.fog_margin_min_k``; the latter renamed: ``fog_margin_min_k`` is the
run's smallest fog margin)."""


def air_limit_entries(limits: AirQualityLimits) -> dict:
    """``limits`` as the entries :data:`AIR_LIMIT_KEYS` of a ``metrics.json``."""
    return {"co2_limit_ppm": float(limits.co2_limit_ppm), "fog_margin_bound_k": float(limits.fog_margin_min_k)}


def air_limits_of(metrics: Mapping) -> AirQualityLimits | None:
    """The limits a ``metrics.json`` records (:data:`AIR_LIMIT_KEYS`); None when it records none (an older run)."""
    if any(metrics.get(k) is None for k in AIR_LIMIT_KEYS):
        return None
    return AirQualityLimits(metrics["co2_limit_ppm"], metrics["fog_margin_bound_k"]).validate()


def run_air_quality(columns: Mapping, limits: AirQualityLimits) -> dict:
    """A run's air quality as its ``metrics.json`` holds it: :data:`AIR_LIMIT_KEYS` and :data:`AIR_QUALITY_KEYS`.

    :func:`air_quality_kpis` over the ``co2_cab_ppm`` and ``fog_margin_k`` columns (either may be absent or all
    NaN: not recorded) at the spacing of ``t_s``; a KPI that is not defined is NaN (``null`` in the file).
    """
    t = as_series("t_s", columns["t_s"], None)
    if t.size < 2:
        raise ValueError(f"t_s: need at least 2 samples, got {t.size}")
    k, _ = air_quality_kpis(columns.get("co2_cab_ppm"), columns.get("fog_margin_k"), float(t[1] - t[0]), limits)
    return {**air_limit_entries(limits), **{key: math.nan if k[key] is None else k[key] for key in AIR_QUALITY_KEYS}}


def breaks_air_quality(kpis: Mapping) -> bool:
    """True when a run passed its CO2 limit or fog bound (``air_quality_met`` 0): the rule of every verb.

    Such a run is never on a front nor matched: a saving bought with stale air or a fogged windshield is no saving
    (docs/metrics.md, "Air quality"). Unknown (None or NaN: not recorded) is not a break.
    """
    return kpis.get("air_quality_met") == 0.0


def discomfort_pmvh(band_distance, dt_s: float) -> float:
    """Thermal discomfort [PMV h], the time integral of ``band_distance``.

    ``band_distance``: :func:`pmv_band_distance` per sample, uniform samples ``dt_s`` [s] apart
    (as BOPTEST integrates its K h).
    """
    return float(np.sum(band_distance) * dt_s / 3600.0)


DISCOMFORT_CEILING_KEYS = ("discomfort_pmvh", "discomfort_band_pmvh", "i_pmv_clipped")
"""The discomfort KPIs with a ceiling (:func:`discomfort_ceiling`): PMV enters them clipped to +-3."""


def discomfort_ceiling(
    kpis: Mapping, key: str = "discomfort_pmvh", band=COMFORT_BAND_PMV, limit: float = PMV_SCALE_LIMIT
) -> float | None:
    """The most the discomfort KPI ``key`` can be in a run: PMV at the +-``limit`` clip for the whole span.

    ``discomfort_pmvh`` [PMV h]: ``duration_s * max(limit - hi, lo + limit) / 3600`` (2.5 PMV for the
    category B band); ``discomfort_band_pmvh``: the same over the band phase (``duration_s - band_start_s``);
    ``i_pmv_clipped`` [s]: ``limit^2 * duration_s``. A run at its ceiling has saturated the metric: every run
    with PMV at or beyond the clip the whole time scores the same, so its value says nothing about its comfort
    (docs/benchmark.md, "Matched comfort"). ``kpis``: the run's :func:`compute_kpis` dict (``duration_s`` [s],
    ``band_start_s`` [s]). None when ``key`` has no ceiling (not in :data:`DISCOMFORT_CEILING_KEYS`) or a KPI
    it needs is None.
    """
    duration = kpis.get("duration_s")
    if key not in DISCOMFORT_CEILING_KEYS or duration is None:
        return None
    if key == "i_pmv_clipped":
        return float(limit * limit * duration)
    if key == "discomfort_band_pmvh":
        start = kpis.get("band_start_s")
        if start is None:
            return None
        duration = duration - start
    most = max(limit - float(band[1]), float(band[0]) + limit)
    return float(duration * most / 3600.0)


def compute_kpis(
    columns: Mapping,
    *,
    step_time_s=None,
    control_period_s: float | None = None,
    fallback_steps: int | None = None,
    band=COMFORT_BAND_PMV,
    air_limits: AirQualityLimits | None = None,
) -> tuple[dict, dict]:
    """The benchmark KPIs of one run (docs/metrics.md, "Benchmark KPIs").

    Args:
        columns: the run's ``timeseries.csv`` columns (1-D arrays): needed ``t_s``,
            ``p_comp_w``, ``p_blower_w``, ``pmv``, ``pmv_lb``, ``pmv_ub``,
            ``mdot_bl_kgps``, ``t_evap_sp_c``; used when present ``p_cond_fan_w``,
            ``dr_pct``, ``fog_margin_k``, ``iso7730_valid``.
        step_time_s: wall time of each whole control step [s] (in-process: the
            controller's compute call; over DDS: command receipt minus state receipt);
            None: the time ratios are null.
        control_period_s: Ts [s] for the time ratios.
        fallback_steps: control steps whose command came from a fallback; None: null.
        band: the fixed comfort band (ISO 7730 category B).
        air_limits: the scenario's CO2 limit and fog bound (default :class:`AirQualityLimits`) for the
            air-quality KPIs (:func:`air_quality_kpis`; from ``co2_cab_ppm`` and ``fog_margin_k`` when present).

    Returns:
        ``(kpis, notes)``: ``kpis`` maps every key of :data:`KPI_KEYS` to a float or
        None; ``notes`` maps each None KPI to the reason.
    """
    t = as_series("t_s", columns["t_s"], None)
    n = t.size
    if n < 2:
        raise ValueError(f"t_s: need at least 2 samples, got {n}")
    dt = float(t[1] - t[0])
    if dt <= 0.0 or np.any(np.abs(np.diff(t) - dt) > UNIFORM_RTOL * dt):
        raise ValueError("t_s: must be increasing and uniformly spaced")
    notes: dict = {}
    p_comp = as_series("p_comp_w", columns["p_comp_w"], n)
    p_bl = as_series("p_blower_w", columns["p_blower_w"], n)
    p_fan = _column(columns, "p_cond_fan_w", n, notes, "energy_fan_kwh")
    y = as_series("pmv", columns["pmv"], n)
    lb = as_series("pmv_lb", columns["pmv_lb"], n)
    ub = as_series("pmv_ub", columns["pmv_ub"], n)
    k: dict = {key: None for key in KPI_KEYS}
    k["duration_s"] = n * dt
    e_comp, e_bl = float(np.sum(p_comp) * dt), float(np.sum(p_bl) * dt)
    e_fan = float(np.sum(p_fan) * dt) if p_fan is not None else 0.0
    if p_fan is None:
        notes["energy_fan_kwh"] += " (energy_kwh counts compressor and blower only)"
    else:
        k["energy_fan_kwh"] = e_fan / J_PER_KWH
    k["energy_comp_kwh"] = e_comp / J_PER_KWH
    k["energy_blower_kwh"] = e_bl / J_PER_KWH
    k["energy_paper_kwh"] = (e_comp + e_bl) / J_PER_KWH
    k["energy_kwh"] = (e_comp + e_bl + e_fan) / J_PER_KWH
    dist = pmv_band_distance(y, band)
    k["discomfort_pmvh"] = discomfort_pmvh(dist, dt)
    zone = band_phase(lb, ub, band)
    m = as_series("mdot_bl_kgps", columns["mdot_bl_kgps"], n)
    s = as_series("t_evap_sp_c", columns["t_evap_sp_c"], n)
    if zone.any():
        k["band_start_s"] = float(t[int(np.argmax(zone))] - t[0])
        k["discomfort_band_pmvh"] = discomfort_pmvh(dist[zone], dt)
        k["pmv_mean_band"] = float(np.mean(y[zone]))
        arrival = edge_arrival_index(y, zone, band)  # the pull-down's tail, still above the edge, is no crossing
        if arrival is not None:
            k["pmv_above_band_s"] = float(np.count_nonzero(y[arrival:] > band[1]) * dt)
        else:
            notes["pmv_above_band_s"] = "the PMV never came to the band's upper edge or below in the band phase"
        p_all = p_comp + p_bl + (p_fan if p_fan is not None else 0.0)  # the consumers energy_kwh counts
        k["energy_band_kwh"] = float(np.sum(p_all[zone]) * dt) / J_PER_KWH
        k["t_evap_sp_mean_band_c"] = float(np.mean(s[zone]))
        k["mdot_bl_mean_band_kgps"] = float(np.mean(m[zone]))
    else:
        for key in BAND_PHASE_KEYS:
            notes[key] = "the scenario's bounds never lie inside the comfort band in this run"
    k["i_pmv"] = float(np.sum(y * y) * dt)
    k["i_pmv_clipped"] = i_pmv_clipped(y, dt)
    k["otc_violation_pct"] = 100.0 * float(np.count_nonzero((y > ub) | (y < lb))) / n
    ttc = time_to_comfort(t, dt, y, band[0], band[1], COMFORT_HOLD_S)
    k["time_to_comfort_s"] = None if math.isnan(ttc) else ttc
    if math.isnan(ttc):
        notes["time_to_comfort_s"] = f"PMV never stayed inside the band for {COMFORT_HOLD_S:g} s"
    dr = _column(columns, "dr_pct", n, notes, "draught_pct")
    if dr is None:
        notes["draught_mean_pct"] = notes["draught_max_pct"] = notes["draught_pct"]
    else:
        dstat = draught_stats(dr)
        k["draught_pct"], k["draught_mean_pct"], k["draught_max_pct"] = (
            dstat["dr_above_pct"],
            dstat["dr_mean_pct"],
            dstat["dr_max_pct"],
        )
    fog = _column(columns, "fog_margin_k", n, notes, "fog_margin_min_k")
    if fog is None:
        notes["fog_risk_pct"] = notes["fog_margin_min_k"]
    else:
        fstat = fog_margin_stats(fog)
        k["fog_margin_min_k"], k["fog_risk_pct"] = fstat["fog_margin_min_k"], fstat["fog_risk_pct"]
    aq, aq_notes = air_quality_kpis(columns.get("co2_cab_ppm"), fog, dt, (air_limits or AirQualityLimits()).validate())
    k.update(aq)
    notes.update(aq_notes)
    valid = _column(columns, "iso7730_valid", n, notes, "iso7730_invalid_pct")
    if valid is not None:
        k["iso7730_invalid_pct"] = iso7730_invalid_pct(valid)
    k["actuator_travel"], k["travel_mdot_kgps"], k["travel_t_evap_sp_k"] = actuator_travel(m, s)
    k["peak_comp_kw"] = float(np.max(p_comp)) / 1000.0
    if step_time_s is None or control_period_s is None:
        notes["time_ratio_mean"] = notes["time_ratio_max"] = "no per-step wall times recorded for this run"
    else:
        st = np.asarray(step_time_s, dtype=float)
        st = st[np.isfinite(st)]
        if st.size == 0:
            notes["time_ratio_mean"] = notes["time_ratio_max"] = "no control step was timed"
        else:
            if not (math.isfinite(control_period_s) and control_period_s > 0):
                raise ValueError(f"control_period_s: must be finite and > 0, got {control_period_s!r}")
            r = st / float(control_period_s)
            k["time_ratio_mean"], k["time_ratio_max"] = float(np.mean(r)), float(np.max(r))
    if fallback_steps is None:
        notes["fallback_steps"] = "fallbacks not recorded for this run"
    else:
        k["fallback_steps"] = float(fallback_steps)
    return k, notes
