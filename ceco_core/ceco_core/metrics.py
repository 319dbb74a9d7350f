"""Metrics of a closed-loop run: energy, comfort, constraint violation.

Equations, units and the reasoning behind each choice: ``docs/metrics.md``.
The paper's three metrics (Wang et al., DSCC 2019, Sec. 4):

* ``E_tot = integral_0^T (P_comp + P_bl + P_fan) dt``               [J]
  (the paper's E_tot counts P_comp + P_bl only; ceco counts every electrical
  consumer of the A/C, the condenser fan too, in every output: :data:`ENERGY_PARTS`)
* ``I_PMV = integral_0^T PMV^2 dt``                                 [s]
* ``OTC violation = T_viol / T * 100 %``, where T_viol is the time with
  PMV > PMV_UB or PMV < PMV_LB                                      [%]

Sampling convention (the run directory's, docs/architecture.md): sample i
stands for the interval ``[t_i, t_i + dt)`` with ``dt = t_1 - t_0``, so every
integral is the rectangle sum ``sum_i x_i * dt`` and ``T = n * dt``. Powers
are the interval means, so the energy sums are exact; PMV is a sample at
``t_i`` held over its interval.

The benchmark KPIs (issue 10, ``ceco benchmark``) are in :mod:`ceco_core.kpis`, built on the
statistics defined here.

Pure numpy; no ROS import.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ceco_core.air_quality import AirQualityLimits

__all__ = [
    "J_PER_KWH",
    "ENERGY_PARTS",
    "METRIC_KEYS",
    "PMV_SCALE_LIMIT",
    "DRAUGHT_LIMIT_PCT",
    "DR_CATEGORY_LIMITS_PCT",
    "compute_metrics",
    "RUN_METRIC_COLUMNS",
    "run_metrics",
    "relative_change_pct",
    "i_pmv_clipped",
    "iso7730_invalid_pct",
    "draught_stats",
    "fog_margin_stats",
    "COMFORT_SERIES_METRIC_KEYS",
    "comfort_series_metrics",
]

J_PER_KWH = 3.6e6
"""Joules in one kilowatt-hour (exact)."""

ENERGY_PARTS = "compressor + blower + condenser fan"
"""What ``E_tot`` counts, in every ceco output (console, CSV, JSON, figures, docs): every electrical
consumer of the A/C. The paper's E_tot leaves the condenser fan out (it is part of its P_aux);
``E_comp_J``, ``E_blower_J`` and ``E_fan_J`` give the parts."""

COMFORT_HOLD_S = 60.0
"""Default time PMV must stay in the comfort zone for comfort to count as reached [s]."""

METRIC_KEYS = (
    "E_tot_J",
    "E_tot_kWh",
    "E_comp_J",
    "E_blower_J",
    "E_fan_J",
    "P_mean_w",
    "I_pmv",
    "otc_violation_pct",
    "otc_violation_s",
    "otc_above_ub_s",
    "otc_below_lb_s",
    "time_to_comfort_s",
    "pmv_mean",
    "pmv_max",
    "pmv_min",
    "duration_s",
)
"""Keys of the dict returned by :func:`compute_metrics`, in order."""

UNIFORM_RTOL = 1e-6
"""Relative tolerance on the spacing of the time samples."""


def as_series(name: str, x, n: int | None) -> np.ndarray:
    """``x`` as a 1-D float series (a scalar broadcast to ``n``); ValueError naming ``name`` otherwise.

    The series must be 1-D, ``n`` long (when ``n`` is given) and finite.
    """
    a = np.asarray(x, dtype=float)
    if n is not None and a.ndim == 0:
        a = np.full(n, float(a))
    if a.ndim != 1:
        raise ValueError(f"{name}: must be 1-D, got shape {a.shape}")
    if n is not None and a.size != n:
        raise ValueError(f"{name}: length {a.size} differs from t_s length {n}")
    if not np.all(np.isfinite(a)):
        i = int(np.flatnonzero(~np.isfinite(a))[0])
        raise ValueError(f"{name}: NaN or infinite value at index {i}")
    return a


def compute_metrics(
    t_s,
    p_comp_w,
    p_blower_w,
    pmv,
    pmv_lb,
    pmv_ub,
    *,
    comfort_ub: float = 0.5,
    comfort_lb: float = -0.5,
    p_fan_w,
    comfort_hold_s: float = COMFORT_HOLD_S,
) -> dict:
    """Energy and comfort metrics of one run (see module docstring).

    Args:
        t_s: sample times [s], uniformly spaced, at least 2 samples.
        p_comp_w: compressor electrical power, mean over each interval [W].
        p_blower_w: blower electrical power, mean over each interval [W].
        pmv: PMV at each sample [-].
        pmv_lb: the scenario's lower PMV bound at each sample (array or
            scalar) [-]; used for the OTC violation.
        pmv_ub: the scenario's upper PMV bound at each sample (array or
            scalar) [-]; used for the OTC violation.
        comfort_ub: upper edge of the comfort zone used for time to comfort
            (ISO 7730 category B: +0.5) [-].
        comfort_lb: lower edge of that comfort zone (category B: -0.5) [-].
        p_fan_w: condenser fan electrical power, mean over each interval [W]
            (the plant's ``p_cond_fan_w``); required, so that ``E_tot_J``
            counts the same parts in every output (:data:`ENERGY_PARTS`).
        comfort_hold_s: time PMV must stay in the zone to count [s].

    Returns:
        dict with the keys :data:`METRIC_KEYS` (floats). ``time_to_comfort_s``
        is the time since ``t_s[0]`` of the first sample from which PMV stays
        inside ``[comfort_lb, comfort_ub]`` for ``comfort_hold_s``; NaN if that
        never happens within the run (including when PMV enters the zone less
        than ``comfort_hold_s`` before the end).

    Raises:
        ValueError naming the argument: NaN, length mismatch, non-uniform or
        non-increasing time, fewer than 2 samples, comfort_lb > comfort_ub.
    """
    t = as_series("t_s", t_s, None)
    n = t.size
    if n < 2:
        raise ValueError(f"t_s: need at least 2 samples, got {n}")
    steps = np.diff(t)
    dt = float(steps[0])
    if dt <= 0.0:
        raise ValueError(f"t_s: must be increasing, first step {dt}")
    if np.any(np.abs(steps - dt) > UNIFORM_RTOL * dt):
        i = int(np.flatnonzero(np.abs(steps - dt) > UNIFORM_RTOL * dt)[0])
        raise ValueError(f"t_s: must be uniformly spaced (step {dt} s), step {i} is {float(steps[i])} s")
    p_comp = as_series("p_comp_w", p_comp_w, n)
    p_bl = as_series("p_blower_w", p_blower_w, n)
    p_fan = as_series("p_fan_w", p_fan_w, n)
    y = as_series("pmv", pmv, n)
    lb = as_series("pmv_lb", pmv_lb, n)
    ub = as_series("pmv_ub", pmv_ub, n)
    for name, v in (("comfort_lb", comfort_lb), ("comfort_ub", comfort_ub), ("comfort_hold_s", comfort_hold_s)):
        if not math.isfinite(v):
            raise ValueError(f"{name}: must be finite, got {v}")
    if comfort_lb > comfort_ub:
        raise ValueError(f"comfort_lb: {comfort_lb} exceeds comfort_ub {comfort_ub}")
    if comfort_hold_s < 0.0:
        raise ValueError(f"comfort_hold_s: must be >= 0, got {comfort_hold_s}")

    duration_s = n * dt
    e_comp = float(np.sum(p_comp) * dt)
    e_bl = float(np.sum(p_bl) * dt)
    e_fan = float(np.sum(p_fan) * dt)
    e_tot = e_comp + e_bl + e_fan
    above = y > ub
    below = y < lb
    viol_s = float(np.count_nonzero(above | below) * dt)

    return {
        "E_tot_J": e_tot,
        "E_tot_kWh": e_tot / J_PER_KWH,
        "E_comp_J": e_comp,
        "E_blower_J": e_bl,
        "E_fan_J": e_fan,
        "P_mean_w": e_tot / duration_s,
        "I_pmv": float(np.sum(y * y) * dt),
        "otc_violation_pct": 100.0 * viol_s / duration_s,
        "otc_violation_s": viol_s,
        "otc_above_ub_s": float(np.count_nonzero(above) * dt),
        "otc_below_lb_s": float(np.count_nonzero(below) * dt),
        "time_to_comfort_s": time_to_comfort(t, dt, y, comfort_lb, comfort_ub, comfort_hold_s),
        "pmv_mean": float(np.mean(y)),
        "pmv_max": float(np.max(y)),
        "pmv_min": float(np.min(y)),
        "duration_s": duration_s,
    }


RUN_METRIC_COLUMNS = ("t_s", "p_comp_w", "p_blower_w", "p_cond_fan_w", "pmv", "pmv_lb", "pmv_ub")
"""The ``timeseries.csv`` columns :func:`run_metrics` reads."""


def run_metrics(columns: Mapping, air_limits: AirQualityLimits | None = None) -> dict:
    """:func:`compute_metrics` over a run's ``timeseries.csv`` columns (:data:`RUN_METRIC_COLUMNS`).

    With ``air_limits`` (the scenario's ``AirQualityLimits``: ``scenario.air_quality.limits``) also the run's air
    quality scored against them (``ceco_core.kpis.run_air_quality``: the limits and the air-quality KPIs, from the
    ``co2_cab_ppm`` and ``fog_margin_k`` columns when present). Every writer of ``metrics.json`` (``ceco sim``,
    ``ceco run``) and ``ceco report``'s check call this one function.

    ValueError naming the missing columns (a run directory older than the condenser fan column
    cannot give ``E_tot`` by :data:`ENERGY_PARTS`).
    """
    missing = [c for c in RUN_METRIC_COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"time series: missing columns {missing}")
    t, comp, bl, fan, y, lb, ub = (np.asarray(columns[c], dtype=float) for c in RUN_METRIC_COLUMNS)
    out = compute_metrics(t, comp, bl, y, lb, ub, p_fan_w=fan)
    if air_limits is not None:
        from ceco_core.kpis import run_air_quality  # (here: ceco_core.kpis is built on this module)

        out.update(run_air_quality(columns, air_limits))
    return out


def time_to_comfort(t, dt, y, lo, hi, hold_s) -> float:
    """First time [s from t[0]] after which PMV ``y`` stays inside ``[lo, hi]`` for ``hold_s`` [s]; NaN if never."""
    # Samples needed to cover hold_s: intervals [t_i, t_i + dt) of samples
    # i..i+m-1 cover [t_i, t_i + m*dt).
    m = max(1, int(math.ceil(hold_s / dt - 1e-9)))
    inside = (y >= lo) & (y <= hi)
    if inside.size < m:
        return math.nan
    # run[i] = number of consecutive in-zone samples starting at i.
    run = np.zeros(inside.size + 1, dtype=int)
    for i in range(inside.size - 1, -1, -1):
        run[i] = run[i + 1] + 1 if inside[i] else 0
    ok = np.flatnonzero(run[:-1] >= m)
    return float(t[ok[0]] - t[0]) if ok.size else math.nan


def relative_change_pct(value: float, baseline: float) -> float:
    """``100 * (value - baseline) / |baseline|`` [%].

    Returns 0.0 when both are 0 and NaN when only the baseline is 0 (a
    relative change from nothing is undefined) or either is NaN.
    """
    value, baseline = float(value), float(baseline)
    if math.isnan(value) or math.isnan(baseline):
        return math.nan
    if baseline == 0.0:
        return 0.0 if value == 0.0 else math.nan
    return 100.0 * (value - baseline) / abs(baseline)


# --------------------------------------------------------------------------------------------------
# comfort-series metrics (issue 9): pure functions of the timeseries columns pmv, dr_pct,
# fog_margin_k, iso7730_valid (ceco_core.rundir.COMFORT_COLUMNS); docs/metrics.md

PMV_SCALE_LIMIT = 3.0
"""End of ISO 7730's seven-point thermal sensation scale (+3 hot, -3 cold) [-]: PMV is clipped to +-3
in ``i_pmv_clipped`` and the ``discomfort_*`` KPIs (beyond it PMV is no vote)."""

DR_CATEGORY_LIMITS_PCT = {"A": 10.0, "B": 20.0, "C": 30.0}
"""ISO 7730:2005 Annex A, Table A.1: draught rating limits of the categories [%]."""

DRAUGHT_LIMIT_PCT = DR_CATEGORY_LIMITS_PCT["B"]
"""The category B limit of the draught rating DR [%] (the metrics' threshold)."""


def i_pmv_clipped(pmv, dt_s: float, limit: float = PMV_SCALE_LIMIT) -> float:
    """``sum_i clip(PMV_i, -limit, limit)^2 dt`` [s]: the paper's I_PMV with PMV held on the 7-point scale.

    Beyond +-3 a PMV is no longer a vote (and outside ISO 7730's validity): a hot-soaked cabin's PMV of
    5-7 would otherwise dominate the integral.
    """
    y = np.clip(as_series("pmv", pmv, None), -limit, limit)
    return float(np.sum(y * y) * dt_s)


def iso7730_invalid_pct(valid) -> float:
    """Share of samples whose PMV inputs or PMV lie outside ISO 7730 Clause 4 ranges [%] (``valid`` 1/0)."""
    v = as_series("iso7730_valid", valid, None)
    return float(100.0 * np.count_nonzero(v < 0.5) / v.size) if v.size else math.nan


def draught_stats(dr_pct, limit_pct: float = DRAUGHT_LIMIT_PCT) -> dict:
    """Draught rating statistics ``dr_mean_pct``, ``dr_max_pct``, ``dr_above_pct`` [%].

    ``dr_above_pct`` is the share of samples with DR above ``limit_pct`` (ISO 7730 category B: 20 %).
    """
    d = as_series("dr_pct", dr_pct, None)
    if not d.size:
        return {"dr_mean_pct": math.nan, "dr_max_pct": math.nan, "dr_above_pct": math.nan}
    return {
        "dr_mean_pct": float(np.mean(d)),
        "dr_max_pct": float(np.max(d)),
        "dr_above_pct": float(100.0 * np.count_nonzero(d > limit_pct) / d.size),
    }


def fog_margin_stats(fog_margin_k) -> dict:
    """Windscreen fog margin (glass minus dew point) statistics ``fog_margin_min_k``, ``fog_margin_mean_k`` [K].

    ``fog_risk_pct`` is the share of samples with a margin below 0 (condensation on the glass) [%].
    """
    f = as_series("fog_margin_k", fog_margin_k, None)
    if not f.size:
        return {"fog_margin_min_k": math.nan, "fog_margin_mean_k": math.nan, "fog_risk_pct": math.nan}
    return {
        "fog_margin_min_k": float(np.min(f)),
        "fog_margin_mean_k": float(np.mean(f)),
        "fog_risk_pct": float(100.0 * np.count_nonzero(f < 0.0) / f.size),
    }


COMFORT_SERIES_METRIC_KEYS = (
    "I_pmv_clipped",
    "iso7730_invalid_pct",
    "dr_mean_pct",
    "dr_max_pct",
    "dr_above_pct",
    "fog_margin_min_k",
    "fog_margin_mean_k",
    "fog_risk_pct",
    "rh_cab_mean",
    "pa_mean_pa",
)
"""Keys of :func:`comfort_series_metrics` (each also with the suffix ``_zone``)."""


def comfort_series_metrics(columns: Mapping, dt_s: float, zone=None) -> dict:
    """The comfort-series metrics of a run, whole run and (``zone``: boolean mask) the comfort-zone phase.

    ``columns`` holds ``pmv, dr_pct, fog_margin_k, iso7730_valid, rh_cab, pa_pa`` (timeseries.csv);
    returns :data:`COMFORT_SERIES_METRIC_KEYS` and the same keys suffixed ``_zone`` (NaN without a zone).
    """
    n = np.asarray(columns["pmv"]).size
    masks = {
        "": np.ones(n, dtype=bool),
        "_zone": np.zeros(n, dtype=bool) if zone is None else np.asarray(zone, dtype=bool),
    }
    out = {}
    for suffix, m in masks.items():
        if not m.any():
            out.update({k + suffix: math.nan for k in COMFORT_SERIES_METRIC_KEYS})
            continue
        col = {
            k: np.asarray(columns[k], dtype=float)[m]
            for k in ("pmv", "dr_pct", "fog_margin_k", "iso7730_valid", "rh_cab", "pa_pa")
        }
        vals = {
            "I_pmv_clipped": i_pmv_clipped(col["pmv"], dt_s),
            "iso7730_invalid_pct": iso7730_invalid_pct(col["iso7730_valid"]),
            **draught_stats(col["dr_pct"]),
            **fog_margin_stats(col["fog_margin_k"]),
            "rh_cab_mean": float(np.mean(col["rh_cab"])),
            "pa_mean_pa": float(np.mean(col["pa_pa"])),
        }
        out.update({k + suffix: vals[k] for k in COMFORT_SERIES_METRIC_KEYS})
    return out
