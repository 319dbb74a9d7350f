"""Identification of the control-oriented model from plant data (least squares).

As the paper identified eqs. (1)-(3) and the power models from NREL CoolSim,
this module identifies them from the ceco plant:

1. Excitation: the plant is simulated (1 s steps) over several drive cycles and
   weather conditions with multi-level random steps of both inputs (blower
   flow 0.05-0.17 kg/s, evaporator set-point 3-10 degC, held 15-120 s, aligned
   with the 5 s model step), starting from a hot soak and from a pre-cooled
   cabin. The recorded time series are saved as CSV (run-directory columns +
   ``segment``), so the fit can be re-run from the data alone.
2. The 1 s series are cut into model intervals of ``ts_s`` (5 s): states at the
   interval start and end, interval means of the inputs, vent air, ambient,
   speed and powers (:func:`intervals_from_series`). Any time series with the
   run-directory columns works: a simulator run, or a rosbag2 recording once
   read into arrays (:func:`fit` takes plain arrays).
3. Least squares: eq. (3) (T_ain), eq. (2) (T_evap) and eq. (1) (T_cab) are
   linear in their parameters (``numpy.linalg.lstsq``); the blower model by
   non-negative linear least squares (``scipy.optimize.lsq_linear``); the
   compressor model by bounded nonlinear least squares
   (``scipy.optimize.least_squares``).
   eta_AC(V) is identified separately from the plant's steady refrigerant
   cycle (:func:`eta_ac_points`, :func:`fit_eta_ac`): the COP ratio
   COP(V)/COP(0) at fixed cooling load and evaporator wall temperature, at
   the loads the closed loop runs at (SC03 comfort-zone phase: q_evap
   2.9-3.9 kW, 10th-90th percentile, baseline run), fitted by
   1 + a (1 - exp(-V/v)). Fitting it jointly with the compressor from the
   drive data let speed absorb load and ambient effects (v at its 60 m/s
   bound, +24 % at 20 m/s against the plant's +15-20 %).
4. Fit report: one-step and multi-step (a whole horizon Np) prediction errors on
   a validation drive (US06) that is not used for fitting.
5. The cabin CO2 and water balances (the CO2 estimator's, the door's and the door NLP's humidity model,
   issue 21): cabin air mass and leakage (:func:`fit_co2_balance`), then the occupants' latent heat and
   the coil's bypass factor (:func:`fit_moisture_balance`), linear least squares, from a drive with the
   door, the blower and the set-point moved at random (UDDS, 4 occupants; :func:`generate_co2_excitation`),
   validated by running the fitted balances free over another (HWFET, 2 occupants); written into the same
   file (``co2_*``, ``moist_*`` fields). With ``--from-csv`` they come from ``--co2-csv`` (columns
   :data:`CO2_CSV_COLUMNS`), else they keep their nominal values and the provenance says so.

CLI (also ``ceco identify``)::

    ceco identify --out runs/id          # regenerate data, fit, write runs/id/model_params.yaml
    ceco identify --from-csv data.csv [--validation-csv v.csv] --out runs/id2
    ceco identify --from-csv data.csv --co2-csv c.csv [--co2-validation-csv cv.csv] --out runs/id3
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import sys
from typing import Any

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from ceco_core import cli_flags
from ceco_core.air_quality import RECIRC_SHARE_DEFAULT

from . import model as cm
from .identification_data import (  # noqa: F401 - part of this module's API (__all__)
    CO2_FINE_COLUMNS,
    CO2_SERIES_COLUMNS,
    CO2_TRAIN_DRIVE,
    CO2_VALIDATION_DRIVE,
    DEFAULT_DATA_DIR,
    PACKAGE_DIR,
    SERIES_COLUMNS,
    TRAIN_DRIVES,
    VALIDATION_DRIVES,
    ExcitationSettings,
    generate_co2_excitation,
    generate_excitation,
    read_series_csv,
    write_series_csv,
)

CO2_CSV_COLUMNS = CO2_SERIES_COLUMNS + ("n_occupants", "co2_amb_ppm")
"""Columns of a CO2 identification CSV (``ceco identify --co2-csv``): the fit's series and, on every row, the
drive's occupants and ambient CO2 [ppm] (constant over a file)."""

__all__ = [
    "SERIES_COLUMNS",
    "ExcitationSettings",
    "generate_excitation",
    "intervals_from_series",
    "fit",
    "fit_intervals",
    "eta_ac_points",
    "fit_eta_ac",
    "EtaMapSettings",
    "prediction_errors",
    "Co2BalanceFit",
    "fit_co2_balance",
    "co2_free_run_max_err_ppm",
    "MoistureBalanceFit",
    "fit_moisture_balance",
    "moisture_free_run_max_err_kgkg",
    "CO2_CSV_COLUMNS",
    "read_series_csv",
    "write_series_csv",
    "main",
]

INTERVAL_KEYS = (
    "t_cab0", "t_cab1", "t_evap0", "t_evap1", "t_int0", "t_shell0", "t_evap_mean", "t_cab_mean", "t_ain_mean",
    "mdot", "sp", "t_amb", "speed", "p_comp", "p_bl", "segment",
)  # fmt: skip
"""Keys of the per-interval regression data (:func:`intervals_from_series`): the start and end states of each
control interval, its mean temperatures, inputs, disturbances, powers and its excitation segment."""


@dataclasses.dataclass(frozen=True)
class EtaMapSettings:
    """Steady-cycle points of the plant used to identify eta_AC(V) (:func:`eta_ac_points`)."""

    loads_w: tuple = (2500.0, 3000.0, 3500.0)
    """Cooling loads Q_evap [W]: the closed loop's comfort-zone range on SC03/UDDS (2.1-3.9 kW)."""
    t_amb_c: float = 35.0
    """Ambient [degC] (SC03, UDDS, HWFET, US06)."""
    t_wall_c: float = 5.0
    """Evaporator wall temperature [degC] (baseline 3 degC, CECO 6-7 degC in the zone phase)."""
    speeds_mps: tuple = tuple(np.arange(0.0, 35.01, 2.5).tolist())
    """Vehicle speeds of the map [m/s] (0 to the top of US06)."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if not (len(self.loads_w) >= 1 and all(math.isfinite(q) and q > 0 for q in self.loads_w)):
            raise ValueError("EtaMapSettings.loads_w must be positive loads [W]")
        if not (
            len(self.speeds_mps) >= 3
            and self.speeds_mps[0] == 0.0
            and all(math.isfinite(v) and v >= 0 for v in self.speeds_mps)
        ):
            raise ValueError("EtaMapSettings.speeds_mps must start at 0 and have >= 3 finite speeds >= 0")
        if not math.isfinite(self.t_amb_c) or not math.isfinite(self.t_wall_c) or self.t_wall_c >= self.t_amb_c:
            raise ValueError("EtaMapSettings.t_wall_c must be finite and below t_amb_c")


def eta_ac_points(settings: EtaMapSettings = EtaMapSettings(), plant_params=None) -> dict:
    """COP(V)/COP(0) of the plant's steady cycle at each load and speed.

    ``ceco_plant_sim.plant.steady_cycle_at_load``: the compressor speed that delivers the load at
    the fixed wall temperature; COP = Q_evap / P_comp. Returns ``speeds_mps`` (S,), ``loads_w`` (L,),
    ``cop`` (L, S) and ``ratio`` (L, S).
    """
    from ceco_plant_sim.plant import steady_cycle_at_load
    from ceco_plant_sim.plant_params import PlantParams

    settings.validate()
    pp = plant_params if plant_params is not None else PlantParams()
    v = np.asarray(settings.speeds_mps, float)
    cop = np.empty((len(settings.loads_w), v.size))
    for i, q in enumerate(settings.loads_w):
        for j, vj in enumerate(v):
            _, sol = steady_cycle_at_load(pp, float(q), settings.t_wall_c, settings.t_amb_c, float(vj))
            cop[i, j] = sol.q_evap_ref_w / sol.p_comp_w
    return {"speeds_mps": v, "loads_w": np.asarray(settings.loads_w, float), "cop": cop, "ratio": cop / cop[:, :1]}


def fit_eta_ac(speeds_mps, ratio) -> tuple[float, float, float]:
    """Fit eta_AC(V) = 1 + a (1 - exp(-V/v)) to COP ratios (rows: loads, averaged in the fit).

    Bounded least squares, a in [0, 3], v in [1, 60] m/s. Returns (a, v [m/s], RMS residual [-]).
    """
    v = np.asarray(speeds_mps, float)
    r = np.atleast_2d(np.asarray(ratio, float))
    if r.shape[1] != v.size or not np.all(np.isfinite(r)):
        raise ValueError("fit_eta_ac: ratio must be finite with one column per speed")

    def resid(z):
        return (1.0 + z[0] * (1.0 - np.exp(-v / z[1])) - r).ravel()

    res = least_squares(resid, np.array([0.3, 15.0]), bounds=([0.0, 1.0], [3.0, 60.0]), x_scale=np.array([0.1, 5.0]))
    return float(res.x[0]), float(res.x[1]), float(np.sqrt(np.mean(res.fun**2)))


STEP_REL_TOL = 1e-3
"""How far a sample interval may differ from the series' step and still count as that step [-, relative]
(:func:`sample_step_s`): the rounding of t_s, not a missing sample."""


def sample_step_s(series: dict, source: str | None = None) -> float:
    """The sample step [s] of a series (``t_s``, ``segment``), checked uniform: the same within every segment.

    :func:`intervals_from_series` strides by row, so a row missing (t_s jumping, e.g. 49 -> 60 s in a 1 s series)
    would join two samples 11 s apart as one step. A ValueError names ``source`` (a file: its line, as
    ``read_series_csv`` counts them; None: "series" and the row), the first step that differs from the series'
    step (the median within the segments) by more than :data:`STEP_REL_TOL`, and the fix; also when t_s does not
    increase.
    """
    t = np.asarray(series["t_s"], float)
    seg = np.asarray(series["segment"])
    # (row, the next row of its segment), in the order of the second
    rows = [np.flatnonzero(seg == s) for s in np.unique(seg)]
    pairs = np.concatenate([np.column_stack([r[:-1], r[1:]]) for r in rows])
    if pairs.size == 0:
        raise ValueError(f"{source or 'series'}: need at least 2 samples in a segment")
    pairs = pairs[np.argsort(pairs[:, 1])]
    steps = t[pairs[:, 1]] - t[pairs[:, 0]]
    dt = float(np.median(steps))
    bad = np.flatnonzero(~(np.abs(steps - dt) <= STEP_REL_TOL * dt) if dt > 0 else ~(steps > 0))
    if bad.size:
        i, j = (int(x) for x in pairs[bad[0]])
        where = f"{source}: line {j + 2}" if source is not None else f"series: row {j}"
        if dt > 0:
            what, fix = f"the sample step is {dt:g} s", "split the file at the gap"
        else:
            what, fix = "t_s must increase", "sort the rows by t_s"
        raise ValueError(
            f"{where}: t_s goes from {t[i]:g} to {t[j]:g} s, but {what}: the series must be uniformly sampled "
            f"({fix}, or give each part its own 'segment' value)"
        )
    return dt


def intervals_from_series(series: dict, ts_s: float = 5.0) -> dict:
    """Cut 1 s series (run-directory sampling) into model intervals of ``ts_s``.

    Row i of the series holds the temperatures at ``t_i`` and the inputs and
    power means over ``[t_i, t_i + dt)``. An interval starting at row i covers
    rows i .. i+m-1 (m = ts_s/dt); its end state is row i+m. Intervals whose
    inputs change inside them are dropped; dt must be uniform (:func:`sample_step_s`). Returns arrays per interval:
    ``t_cab0, t_cab1, t_evap0, t_evap1, t_int0, t_shell0, t_evap_mean, t_cab_mean,
    t_ain_mean, mdot, sp, t_amb, speed, p_comp, p_bl, segment``, and ``recirc`` (the door's mean
    recirculated share [-]) when the series has a ``recirc_share`` column (NaN where it is not measured).
    """
    for c in SERIES_COLUMNS:
        if c not in series:
            raise ValueError(f"series: missing column {c!r}")
    t = np.asarray(series["t_s"], float)
    if t.size < 3:
        raise ValueError("series: need at least 3 samples")
    dt = sample_step_s(series)
    m = int(round(ts_s / dt))
    if m < 1 or abs(m * dt - ts_s) > 1e-6:
        raise ValueError(f"ts_s {ts_s} must be a whole multiple of the sample step {dt}")
    door = "recirc_share" in series
    keys = INTERVAL_KEYS + (("recirc",) if door else ())
    out: dict[str, list] = {k: [] for k in keys}
    seg = np.asarray(series["segment"])
    for s in np.unique(seg):
        idx = np.flatnonzero(seg == s)
        g = {c: np.asarray(series[c], float)[idx] for c in SERIES_COLUMNS + (("recirc_share",) if door else ())}
        for i in range(0, idx.size - m, m):
            sl = slice(i, i + m)
            if np.ptp(g["mdot_bl_kgps"][sl]) > 1e-9 or np.ptp(g["t_evap_sp_c"][sl]) > 1e-9:
                continue
            vals = {
                "t_cab0": g["t_cab_c"][i],
                "t_cab1": g["t_cab_c"][i + m],
                "t_evap0": g["t_evap_c"][i],
                "t_evap1": g["t_evap_c"][i + m],
                "t_int0": g["t_int_c"][i],
                "t_shell0": g["t_shell_c"][i],
                "t_evap_mean": np.mean(g["t_evap_c"][i + 1 : i + m + 1]),
                "t_cab_mean": np.mean(g["t_cab_c"][sl]),
                "t_ain_mean": np.mean(g["t_vent_c"][i + 1 : i + m + 1]),
                "mdot": g["mdot_bl_kgps"][i],
                "sp": g["t_evap_sp_c"][i],
                "t_amb": np.mean(g["t_amb_c"][sl]),
                "speed": np.mean(g["speed_mps"][sl]),
                "p_comp": np.mean(g["p_comp_w"][sl]),
                "p_bl": np.mean(g["p_blower_w"][sl]),
                "segment": s,
            }
            if door:
                vals["recirc"] = np.mean(g["recirc_share"][sl])
            for k, v in vals.items():
                out[k].append(float(v))
    res: dict[str, Any] = {k: np.asarray(v) for k, v in out.items()}
    res["ts_s"] = float(ts_s)
    return res


EXCITATION_MIN_REL_STD = 1e-3
"""A regressor whose standard deviation over the intervals is below this share of its RMS [-] does not vary
(:func:`check_identifiable`; the excitation data: 0.06 at least, per drive)."""
COLLINEARITY_COND_MAX = 1e3
"""Largest condition number of a regression's standardised regressors [-] (:func:`check_identifiable`; the
excitation data: 13 at most, per drive; two blower levels for the three blower coefficients: 1e14)."""


def check_identifiable(regressions: dict[str, dict[str, np.ndarray]]) -> None:
    """ValueError unless interval data identify each regression: ``{regression: {regressor: values}}``.

    Each regressor (an intercept is implied) must vary (:data:`EXCITATION_MIN_REL_STD`), and a regression's
    regressors must not vary together (:data:`COLLINEARITY_COND_MAX`). Without it least squares still returns
    numbers (the minimum-norm solution: gains 0, the data's mean in the offset), a model that cannot predict.
    The error names the regressors that do not vary, or the regression whose regressors are collinear.
    """
    flat: list[str] = []
    for regs in regressions.values():
        for name, x in regs.items():
            rms = float(np.sqrt(np.mean(np.square(x))))
            if not float(np.std(x)) > EXCITATION_MIN_REL_STD * rms and name not in flat:
                flat.append(name)
    n = next(iter(next(iter(regressions.values())).values())).size
    if flat:
        raise ValueError(
            f"the training data cannot identify the model: {', '.join(flat)} "
            f"{'does' if len(flat) == 1 else 'do'} not vary over the {n} intervals: fit from data where the blower "
            "flow and the evaporator set-point are stepped (docs/controller.md, section 2)"
        )
    for what, regs in regressions.items():
        x = np.column_stack(list(regs.values()))
        z = (x - x.mean(axis=0)) / x.std(axis=0)
        sv = np.linalg.svd(z, compute_uv=False)
        if not sv[-1] * COLLINEARITY_COND_MAX > sv[0]:
            raise ValueError(
                f"the training data cannot identify {what}: {', '.join(regs)} vary together (condition number "
                f"{sv[0] / sv[-1]:.3g} > {COLLINEARITY_COND_MAX:g}): fit from data where they vary independently "
                "(docs/controller.md, section 2)"
            )


def _lstsq(a, b):
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    return coef


def fit_intervals(
    iv: dict,
    ts_s: float | None = None,
    eta: tuple[float, float] | None = None,
    recirc_share: float = RECIRC_SHARE_DEFAULT,
) -> tuple[cm.ControlModelParams, dict]:
    """Least-squares fit of every model parameter from interval data; returns (params, residual RMS).

    ``eta`` = (a_eta, v_eta [m/s]) fixes eta_AC(V) (identified from the plant's steady cycle,
    :func:`fit_eta_ac`); None fits it jointly with the compressor (the old method, which lets
    speed absorb load and ambient effects).

    The fresh-air share phi of the power model (P1) is not fitted: it is the door's, 1 - r, known in the
    data: ``iv["recirc"]`` per interval where the series measured the door, else ``recirc_share`` [-] (the
    door the data were recorded with; default the plant's 0.8, the excitation's). Fitted freely, phi went to
    its bound 0 (the sensible-only load then lumps the latent part into c0), which made the model blind to
    the fresh air's load growing with the blower flow: it ranked a warmer coil with more air too favourably
    (docs/controller.md, "The fresh-air share"). ``fresh_air_fraction`` is written as the data's mean 1 - r.
    """
    r_default = float(recirc_share)
    if not (math.isfinite(r_default) and 0.0 <= r_default <= 1.0):
        raise ValueError(f"recirc_share must be in [0, 1], got {recirc_share!r}")
    ts_s = float(ts_s if ts_s is not None else iv["ts_s"])
    n = iv["mdot"].size
    if n < 20:
        raise ValueError(f"need at least 20 intervals to fit, got {n}")
    one = np.ones(n)
    r = np.asarray(iv.get("recirc", np.full(n, np.nan)), float)
    phi = 1.0 - np.where(np.isfinite(r) & (r >= 0.0) & (r <= 1.0), r, r_default)
    # the regressors (CSV names: what must vary) of eqs. (3), (2), (1) and the blower
    tc = iv["t_cab0"]
    x3 = {"t_evap_c": iv["t_evap_mean"], "mdot_bl_kgps": iv["mdot"]}
    x2 = {"t_evap_c": iv["t_evap0"], "t_evap_c - t_evap_sp_c": iv["t_evap0"] - iv["sp"]}
    x1 = {
        "t_int_c - t_cab_c": iv["t_int0"] - tc,
        "t_shell_c - t_cab_c": iv["t_shell0"] - tc,
        "(t_vent_c - t_cab_c) mdot_bl_kgps": (iv["t_ain_mean"] - tc) * iv["mdot"],
    }
    xb = {"mdot_bl_kgps": iv["mdot"], "mdot_bl_kgps^3": iv["mdot"] ** 3}
    check_identifiable({"eq. (3) (T_ain)": x3, "eq. (2) (T_evap)": x2, "eq. (1) (T_cab)": x1, "the blower power": xb})
    # eq. (3): T_ain = g6 T_evap + g7 mdot + tau3 (interval means)
    a3 = np.column_stack([*x3.values(), one])
    g6, g7, tau3 = _lstsq(a3, iv["t_ain_mean"])
    # eq. (2): T_evap+ = g4 T_evap + g5 (T_evap - sp) + tau2
    a2 = np.column_stack([*x2.values(), one])
    g4, g5, tau2 = _lstsq(a2, iv["t_evap1"])
    # eq. (1): T_cab+ - T_cab = g1 (T_int - T_cab) + g2 (T_shell - T_cab) + g3 (T_ain - T_cab) mdot + tau1
    a1 = np.column_stack([*x1.values(), one])
    g1, g2, g3, tau1 = _lstsq(a1, iv["t_cab1"] - tc)
    # blower: b0 + b1 mdot + b3 mdot^3, coefficients >= 0
    ab = np.column_stack([one, *xb.values()])
    sb = np.array([1.0, 100.0, 1e4])  # column scaling for conditioning
    rb = lsq_linear(ab * (1.0 / sb), iv["p_bl"], bounds=(0.0, np.inf))
    b0, b1, b3 = rb.x / sb
    # compressor + eta_AC: nonlinear, bounded
    base = cm.ControlModelParams(
        ts_s=ts_s,
        gamma_1=g1,
        gamma_2=g2,
        gamma_3=g3,
        gamma_4=g4,
        gamma_5=g5,
        gamma_6=g6,
        gamma_7=g7,
        tau_1=tau1,
        tau_2=tau2,
        tau_3=tau3,
        blower_b0_w=b0,
        blower_b1_w_per_kgps=b1,
        blower_b3_w_per_kgps3=b3,
    )

    def comp_params(z):
        if eta is not None:
            z = np.concatenate([z[:2], eta, z[2:]])
        return dataclasses.replace(
            base,
            fresh_air_fraction=float(np.mean(phi)),
            comp_c0=z[0],
            comp_c1_per_k=z[1],
            eta_gain=z[2],
            eta_speed_scale_mps=z[3],
            comp_c_wall_jpk=z[4],
        )

    def comp_resid(z):
        p = comp_params(z)
        q = cm.q_evap_w(
            p, iv["t_cab_mean"], iv["t_amb"], iv["t_ain_mean"], iv["mdot"], iv["t_evap0"], iv["t_evap1"], phi
        )
        return (cm.p_comp_w(p, q, iv["t_amb"], iv["t_evap_mean"], iv["speed"]) - iv["p_comp"]) / 1000.0

    z0 = np.array([0.2, 0.01, 0.2, 10.0, 5000.0])
    lo = np.array([1e-3, 0.0, 0.0, 1.0, 0.0])
    hi = np.array([5.0, 0.5, 3.0, 60.0, 1e5])
    xs = np.array([0.1, 0.01, 0.1, 5.0, 1000.0])
    if eta is not None:
        keep = [0, 1, 4]
        z0, lo, hi, xs = z0[keep], lo[keep], hi[keep], xs[keep]
    rc = least_squares(comp_resid, z0, bounds=(lo, hi), x_scale=xs)
    params = comp_params(rc.x)
    params.validate()
    resid = {
        "t_ain_rms_k": float(np.sqrt(np.mean((a3 @ [g6, g7, tau3] - iv["t_ain_mean"]) ** 2))),
        "t_evap_rms_k": float(np.sqrt(np.mean((a2 @ [g4, g5, tau2] - iv["t_evap1"]) ** 2))),
        "t_cab_rms_k": float(np.sqrt(np.mean((a1 @ [g1, g2, g3, tau1] - (iv["t_cab1"] - tc)) ** 2))),
        "p_blower_rms_w": float(np.sqrt(np.mean((ab @ [b0, b1, b3] - iv["p_bl"]) ** 2))),
        "p_comp_rms_w": float(1000.0 * np.sqrt(np.mean(rc.fun**2))),
        "n_intervals": int(n),
    }
    return params, resid


def fit(
    series: dict, ts_s: float = 5.0, eta: tuple[float, float] | None = None, recirc_share: float = RECIRC_SHARE_DEFAULT
) -> tuple[cm.ControlModelParams, dict]:
    """Fit the control model from 1 s time-series arrays (SERIES_COLUMNS; e.g. read from CSV or a rosbag2 bag).

    ``ts_s`` is the model step [s]; ``eta`` and ``recirc_share`` as in :func:`fit_intervals` (a
    ``recirc_share`` column in ``series`` gives the door per interval).
    """
    return fit_intervals(intervals_from_series(series, ts_s), ts_s, eta, recirc_share)


def _joined(iv: dict) -> np.ndarray:
    """Per pair of consecutive intervals (n - 1): True where a prediction window may span them.

    The second continues the first: the same segment, its start state the first's end state.
    """
    seg, t_cab0, t_cab1 = iv["segment"], iv["t_cab0"], iv["t_cab1"]
    return (seg[1:] == seg[:-1]) & np.isclose(t_cab1[:-1], t_cab0[1:])


def longest_horizon_steps(iv: dict) -> int:
    """The longest prediction window [steps] interval data hold: the longest run of joined intervals (0: none)."""
    if iv["mdot"].size == 0:
        return 0
    breaks = np.flatnonzero(~_joined(iv))
    return int(np.max(np.diff(np.concatenate([[-1], breaks, [iv["mdot"].size - 1]]))))


def prediction_errors(p: cm.ControlModelParams, iv: dict, horizon_steps: int = 6) -> dict:
    """One-step and ``horizon_steps``-step open-loop prediction errors on interval data.

    From every interval start k (with Np consecutive intervals in the same
    segment), the model is run with the recorded inputs, ambient and speed,
    with T_int and T_shell held at their values at k (as in the NMPC), and
    T_ain and the powers predicted by the model. Errors: RMS and max |e| of
    T_cab and T_evap after 1 and Np steps, RMS of T_ain and of the powers, and
    the relative error of the predicted A/C energy over the horizon.
    """
    joined = _joined(iv)
    starts = [k for k in range(joined.size - horizon_steps + 2) if np.all(joined[k : k + horizon_steps - 1])]
    e1_cab, eN_cab, e1_ev, eN_ev, e_ain, e_pc, e_pb, e_energy = [], [], [], [], [], [], [], []
    for k in starts:
        sl = slice(k, k + horizon_steps)
        sim = cm.simulate(
            p,
            iv["t_cab0"][k],
            iv["t_evap0"][k],
            iv["mdot"][sl],
            iv["sp"][sl],
            iv["t_int0"][k],
            iv["t_shell0"][k],
            iv["t_amb"][sl],
            iv["speed"][sl],
        )
        e1_cab.append(sim["t_cab_c"][1] - iv["t_cab1"][k])
        eN_cab.append(sim["t_cab_c"][-1] - iv["t_cab1"][k + horizon_steps - 1])
        e1_ev.append(sim["t_evap_c"][1] - iv["t_evap1"][k])
        eN_ev.append(sim["t_evap_c"][-1] - iv["t_evap1"][k + horizon_steps - 1])
        e_ain.extend(sim["t_ain_c"] - iv["t_ain_mean"][sl])
        e_pc.extend(sim["p_comp_w"] - iv["p_comp"][sl])
        e_pb.extend(sim["p_blower_w"] - iv["p_bl"][sl])
        e_true = np.sum(iv["p_comp"][sl] + iv["p_bl"][sl])
        e_energy.append((np.sum(sim["p_comp_w"] + sim["p_blower_w"]) - e_true) / max(e_true, 1.0))

    def rms(x):
        return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float("nan")

    def mx(x):
        return float(np.max(np.abs(x))) if len(x) else float("nan")

    return {
        "horizon_steps": int(horizon_steps),
        "n_windows": len(starts),
        "t_cab_1step_rms_k": rms(e1_cab),
        "t_cab_1step_max_k": mx(e1_cab),
        f"t_cab_{horizon_steps}step_rms_k": rms(eN_cab),
        f"t_cab_{horizon_steps}step_max_k": mx(eN_cab),
        "t_evap_1step_rms_k": rms(e1_ev),
        f"t_evap_{horizon_steps}step_rms_k": rms(eN_ev),
        "t_ain_rms_k": rms(e_ain),
        "p_comp_rms_w": rms(e_pc),
        "p_blower_rms_w": rms(e_pb),
        "horizon_energy_rel_err_rms": rms(e_energy),
        "horizon_energy_rel_err_mean": float(np.mean(e_energy)) if e_energy else float("nan"),
    }


@dataclasses.dataclass(frozen=True)
class Co2BalanceFit:
    """The cabin CO2 balance's parameters identified from a plant run (:func:`fit_co2_balance`)."""

    m_air_kg: float
    """Cabin dry-air mass [kg]."""
    leak_0_kgps: float
    """Leakage at rest [kg/s]."""
    leak_per_mps_kgps: float
    """Leakage growth with speed [kg/s per m/s]."""
    rate_rms_ppm_per_s: float
    """RMS residual of the fitted CO2 rate [ppm/s]."""
    free_run_max_err_ppm: float
    """Largest error of the balance run with the fitted values from the first sample over the whole series, the
    exact step (:func:`ceco_core.co2_door.co2_after_ppm`) with the inputs held per sample [ppm]."""


def fit_co2_balance(series: dict, n_occupants: int, co2_amb_ppm: float, met: float = 1.2) -> Co2BalanceFit:
    """Least-squares cabin air mass and leakage of the CO2 balance from a plant run (issue 21).

    The balance of :mod:`ceco_core.air_quality`, m_air dC/dt = (F + L_0 + L_V V)(C_amb - C) + G, with F = (1 - r)
    mdot_bl the fresh air [kg/s] of the door's actual share r, V the speed [m/s] and G = n g / k the occupants'
    CO2 [ppm kg/s] (``co2_generation_kgps(met)``, taken as known), is linear in (m_air, L_0, L_V):

        F (C_amb - C) + G = m_air dC/dt - L_0 (C_amb - C) - L_V V (C_amb - C)

    with dC/dt the forward difference of consecutive samples, C and the door's share r their midpoints (the door
    travels within a sample: its mean position over the interval, not the one at its start; a 5-s stroke read at
    the start biased the leakage at rest by +22 % on the CO2 excitation) and the blower flow and speed those of
    the interval's start (held commands, 1 s apart) (``numpy.linalg.lstsq``).
    ``series``: arrays ``t_s`` [s], ``co2_cab_ppm`` (the cabin's CO2: a lab analyser on a test car, the plant's
    value here), ``recirc_share`` [-] (the door's actual position), ``mdot_bl_kgps``, ``speed_mps``. The door must
    move and the speed vary in
    the data, or L_0, L_V and the fresh air are not told apart (a ValueError says so).
    """
    from ceco_core.air_quality import KGKG_PER_PPM, co2_generation_kgps

    t, c, r, m, v = (
        np.asarray(series[k], float) for k in ("t_s", "co2_cab_ppm", "recirc_share", "mdot_bl_kgps", "speed_mps")
    )
    if not (t.size == c.size == r.size == m.size == v.size) or t.size < 60:
        raise ValueError(f"fit_co2_balance: need equal-length series of at least 60 samples, got {t.size}")
    if not np.all(np.isfinite(np.stack([t, c, r, m, v]))) or not np.all(np.diff(t) > 0):
        raise ValueError("fit_co2_balance: the series must be finite with increasing time")
    if np.ptp(r) < 0.05 or np.ptp(v) < 1.0:
        raise ValueError(
            f"fit_co2_balance: the door (range {np.ptp(r):.3f}) and the speed (range {np.ptp(v):.2f} m/s) must vary"
        )
    g = int(n_occupants) * co2_generation_kgps(met) / KGKG_PER_PPM
    dt = np.diff(t)
    cm_ = 0.5 * (c[1:] + c[:-1])
    d_amb = co2_amb_ppm - cm_
    fresh = (1.0 - 0.5 * (r[1:] + r[:-1])) * m[:-1]
    a = np.column_stack([np.diff(c) / dt, -d_amb, -v[:-1] * d_amb])
    b = fresh * d_amb + g
    m_air, l0, lv = (float(z) for z in np.linalg.lstsq(a, b, rcond=None)[0])
    rate = (b + l0 * d_amb + lv * v[:-1] * d_amb) / m_air - np.diff(c) / dt
    err = co2_free_run_max_err_ppm(series, n_occupants, co2_amb_ppm, m_air, l0, lv, met)
    return Co2BalanceFit(float(m_air), float(l0), float(lv), float(np.sqrt(np.mean(rate**2))), err)


def co2_free_run_max_err_ppm(
    series: dict,
    n_occupants: int,
    co2_amb_ppm: float,
    m_air_kg: float,
    leak_0_kgps: float,
    leak_per_mps_kgps: float,
    met: float = 1.2,
) -> float:
    """Largest error [ppm] of the CO2 balance with these values run free from the series' first sample.

    The exact step :func:`ceco_core.co2_door.co2_after_ppm`, the inputs as :func:`fit_co2_balance` takes them.
    """
    from ceco_core.air_quality import KGKG_PER_PPM, co2_generation_kgps
    from ceco_core.co2_door import co2_after_ppm

    t, c, r, m, v = (
        np.asarray(series[k], float) for k in ("t_s", "co2_cab_ppm", "recirc_share", "mdot_bl_kgps", "speed_mps")
    )
    g = int(n_occupants) * co2_generation_kgps(met) / KGKG_PER_PPM
    fresh = (1.0 - 0.5 * (r[1:] + r[:-1])) * m[:-1]
    x, err = float(c[0]), 0.0
    for k in range(t.size - 1):
        leak = leak_0_kgps + leak_per_mps_kgps * float(v[k])
        x = co2_after_ppm(x, co2_amb_ppm, float(fresh[k]), leak, g, m_air_kg, float(t[k + 1] - t[k]))
        err = max(err, abs(x - float(c[k + 1])))
    return float(err)


@dataclasses.dataclass(frozen=True)
class MoistureBalanceFit:
    """The cabin water balance's parameters identified from a plant run (:func:`fit_moisture_balance`)."""

    occ_latent_w: float
    """Latent heat of one occupant [W] (their moisture times h_fg)."""
    bypass_factor: float
    """Evaporator bypass factor of the condensation [-] (a constant: the plant's varies with the flow)."""
    rate_rms_kgkg_per_s: float
    """RMS residual of the fitted humidity-ratio rate [kg/kg per s]."""
    free_run_max_err_kgkg: float
    """Largest error of the balance run with the fitted values from the first sample over the whole series
    [kg/kg] (:func:`moisture_free_run_max_err_kgkg`)."""


def _moisture_terms(series: dict, m_air_kg: float, leak_0_kgps: float, leak_per_mps_kgps: float):
    """Per-interval terms of the water balance [SI]: dW/dt, W, W_amb, F, r, mdot, W_sw (midpoints as for CO2)."""
    from ceco_core import psychro
    from ceco_core.air_quality import leakage_kgps

    t, w, r, m, v, tev, tamb, rh = (
        np.asarray(series[k], float)
        for k in ("t_s", "w_cab_kgkg", "recirc_share", "mdot_bl_kgps", "speed_mps", "t_evap_c", "t_amb_c", "rh_amb")
    )
    if not (t.size == w.size == r.size == m.size == v.size == tev.size == tamb.size == rh.size) or t.size < 60:
        raise ValueError(f"fit_moisture_balance: need equal-length series of at least 60 samples, got {t.size}")
    if not np.all(np.isfinite(np.stack([t, w, r, m, v, tev, tamb, rh]))) or not np.all(np.diff(t) > 0):
        raise ValueError("fit_moisture_balance: the series must be finite with increasing time")
    dt = np.diff(t)
    mid = lambda a: 0.5 * (a[1:] + a[:-1])  # noqa: E731 - the interval's mean of a sampled series
    rm = mid(r)
    w_amb = psychro.humidity_ratio(tamb[:-1], rh[:-1])
    w_sw = psychro.humidity_ratio(mid(tev), 1.0)
    fresh = (1.0 - rm) * m[:-1] + leakage_kgps(leak_0_kgps, leak_per_mps_kgps, v[:-1])
    return dict(dw=np.diff(w) / dt, w=mid(w), w0=w, w_amb=w_amb, fresh=fresh, r=rm, m=m[:-1], w_sw=w_sw, dt=dt)


def fit_moisture_balance(
    series: dict, n_occupants: int, m_air_kg: float, leak_0_kgps: float, leak_per_mps_kgps: float
) -> MoistureBalanceFit:
    """Least-squares occupants' latent heat and coil bypass factor of the cabin water balance (issue 21).

    The balance of ``ceco_core.air_quality`` (``cabin_water_flows_kgps``, ``coil_outlet_humidity_ratio``), with the
    air mass and leakage of the CO2 fit (:func:`fit_co2_balance`) taken as known, is linear in the occupants'
    moisture G and the coil's contact share 1 - BF:

        m_air dW/dt - F (W_amb - W) = G - (1 - BF) mdot max(W_mix - W_sw(T_wall), 0)

    (F = (1 - r) mdot + L_0 + L_V V; W, r and T_wall at the interval's midpoints; ``numpy.linalg.lstsq``).
    ``series``: :data:`CO2_SERIES_COLUMNS` (a cabin humidity sensor, the evaporator wall temperature, the
    ambient's). G = n q_l / h_fg gives q_l per occupant. The coil must condense over a range of flows and
    wall temperatures, else G and BF are not told apart (a ValueError says so).
    """
    from ceco_core import psychro

    d = _moisture_terms(series, m_air_kg, leak_0_kgps, leak_per_mps_kgps)
    w_mix = d["r"] * d["w"] + (1.0 - d["r"]) * d["w_amb"]
    cond = d["m"] * np.maximum(w_mix - d["w_sw"], 0.0)
    if np.ptp(cond) < 1e-5 or np.count_nonzero(cond) < 30:
        raise ValueError("fit_moisture_balance: the coil must condense, at varying rates, in the data")
    y = m_air_kg * d["dw"] - d["fresh"] * (d["w_amb"] - d["w"])
    a = np.column_stack([np.ones_like(cond), -cond])
    (g, contact), *_ = np.linalg.lstsq(a, y, rcond=None)
    rate = (g - contact * cond - y) / m_air_kg
    q_l = float(g) * psychro.H_FG_JPKG / int(n_occupants)
    bf = 1.0 - float(contact)
    err = moisture_free_run_max_err_kgkg(series, n_occupants, m_air_kg, leak_0_kgps, leak_per_mps_kgps, q_l, bf)
    return MoistureBalanceFit(q_l, bf, float(np.sqrt(np.mean(rate**2))), err)


def moisture_free_run_max_err_kgkg(
    series: dict,
    n_occupants: int,
    m_air_kg: float,
    leak_0_kgps: float,
    leak_per_mps_kgps: float,
    occ_latent_w: float,
    bypass_factor: float,
) -> float:
    """Largest error [kg/kg] of the water balance with these values run free from the series' first sample.

    Explicit Euler over each sample, the shared coil and balance functions with the exact max.
    """
    from ceco_core import psychro
    from ceco_core.air_quality import cabin_water_flows_kgps, coil_outlet_humidity_ratio

    d = _moisture_terms(series, m_air_kg, leak_0_kgps, leak_per_mps_kgps)
    gen = int(n_occupants) * occ_latent_w / psychro.H_FG_JPKG
    x, err = float(d["w0"][0]), 0.0
    for k in range(d["dt"].size):
        r, w_amb = float(d["r"][k]), float(d["w_amb"][k])
        w_mix = r * x + (1.0 - r) * w_amb
        w_out = coil_outlet_humidity_ratio(w_mix, float(d["w_sw"][k]), bypass_factor, max)
        f = cabin_water_flows_kgps(x, w_amb, w_mix, w_out, float(d["fresh"][k]), float(d["m"][k]), gen)
        x += float(d["dt"][k]) * (f.into - f.out - f.condensate) / m_air_kg
        err = max(err, abs(x - float(d["w0"][k + 1])))
    return float(err)


def round_floats(d: dict) -> dict:
    """A fit-report mapping with its floats rounded to 6 decimals (for the parameter file)."""
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in d.items()}


def print_fit(params: dict, report: dict, width: int = 24) -> None:
    """Print the identified parameters (without their provenance) and the fit report."""
    for k, v in params.items():
        if k != "provenance":
            print(f"  {k:{width}s} {v: .6g}")
    for name, rep in report.items():
        print(name)
        for k, v in rep.items():
            print(f"  {k:32s} {v}")


OUTPUT_FILES = ("model_params.yaml", "train.csv", "validation.csv")
"""What ``ceco identify`` writes into its ``--out`` run directory."""


def output_paths(out: str | None) -> tuple[pathlib.Path, pathlib.Path]:
    """(data directory, parameter file) of ``ceco identify --out``: a run directory, never the package's files.

    ``out`` None: a new ``runs/identify-<UTC time>``. SystemExit(2) with one line when the directory
    already holds one of :data:`OUTPUT_FILES` (nothing is written over: not the tracked
    ``config/model_params.yaml`` nor the committed excitation data).
    """
    import datetime

    d = pathlib.Path(out or f"runs/identify-{datetime.datetime.now(datetime.UTC):%Y%m%d-%H%M%S}")
    exists = [d / f for f in OUTPUT_FILES if (d / f).exists()]
    if exists:
        print(f"ceco identify: error: {exists[0]} exists: choose a new --out directory", file=sys.stderr)
        raise SystemExit(2)
    d.mkdir(parents=True, exist_ok=True)
    return d, d / "model_params.yaml"


TS_DEFAULT_S = 5.0
"""``ceco identify``'s model step without ``--control-period-s`` [s] (the controller's Ts)."""
NP_DEFAULT = 6
"""``ceco identify``'s multi-step prediction error horizon without ``--horizon-steps`` [steps] (the NMPC's Np)."""


def build_parser() -> cli_flags.Parser:
    """The parser of ``ceco identify``."""
    ap = cli_flags.Parser(prog="ceco identify", description="Identify the control-oriented model.")
    ap.add_argument(
        "--from-csv",
        nargs="*",
        default=None,
        help="fit from these 1 s series CSVs (SERIES_COLUMNS) instead of simulating the plant",
    )
    ap.add_argument("--validation-csv", default=None, help="validation series CSV (default: simulate US06)")
    ap.add_argument(
        "--out",
        default=None,
        help="run directory to write model_params.yaml and the generated train/validation CSVs into; it must not "
        "hold them already (default: a new runs/identify-<UTC time>)",
    )
    ap.add_argument(
        "--co2-csv",
        default=None,
        help="fit the cabin CO2 balance from this 1 s CSV (CO2_CSV_COLUMNS) instead of simulating the plant",
    )
    ap.add_argument(
        "--co2-validation-csv", default=None, help="validation CSV of the CO2 balance (default: simulate HWFET)"
    )
    ap.add_argument(
        "--recirc-share",
        type=float,
        default=RECIRC_SHARE_DEFAULT,
        help="the door's recirculated share [0..1] in the training data where it has no recirc_share column: the "
        f"power model's fresh-air share is 1 - it (default: {RECIRC_SHARE_DEFAULT}, the plant's door, which the "
        "simulated excitation holds)",
    )
    ap.add_argument("--seed", type=int, default=1, help="excitation seed (default: 1)")
    cli_flags.add_control_period(ap, default_text=f"{TS_DEFAULT_S:g} s: the model's step", deprecated=("--ts",))
    cli_flags.add_horizon(
        ap, default_text=f"{NP_DEFAULT}: the horizon of the multi-step prediction error", deprecated=("--horizon",)
    )
    return ap


def main(argv=None) -> int:
    """CLI: (re)generate the excitation data, fit, validate, write the parameter file into a run directory."""
    ap = build_parser()
    args = ap.parse_args(argv)
    args.ts = args.control_period_s if args.control_period_s is not None else TS_DEFAULT_S
    args.horizon = args.horizon_steps if args.horizon_steps is not None else NP_DEFAULT
    try:
        return _identify(args, argv)
    except (ValueError, OSError) as exc:  # a missing or malformed CSV: one line, no traceback
        print(f"ceco identify: error: {exc}", file=sys.stderr)
        return 2


def _co2_series_from_csv(path) -> dict:
    """A CO2 identification CSV (:data:`CO2_CSV_COLUMNS`) as the series :func:`fit_co2_balance` takes."""
    s: dict[str, Any] = read_series_csv(path, CO2_CSV_COLUMNS)
    for k in ("n_occupants", "co2_amb_ppm"):
        if s[k].size == 0 or np.ptp(s[k]) != 0.0:
            raise ValueError(f"{path}: column {k!r} must hold one value on every row")
    s["n_occupants"], s["co2_amb_ppm"] = int(s["n_occupants"][0]), float(s["co2_amb_ppm"][0])
    if not 1 <= s["n_occupants"] <= 5:
        raise ValueError(f"{path}: n_occupants must be 1..5, got {s['n_occupants']}")
    return s


def _identify_co2(args, data_dir: pathlib.Path, exc: ExcitationSettings) -> tuple[dict, dict, str]:
    """The CO2 balance's part of ``ceco identify``: (ControlModelParams fields, fit report, provenance text).

    Training and validation series from the CSVs given, else simulated (and written into the run directory);
    with ``--from-csv`` and no ``--co2-csv`` the nominal values are kept (empty fields) and the text says so.
    """
    if args.co2_csv is None and args.from_csv:
        print("ceco identify: no --co2-csv: the CO2 balance keeps its nominal values", file=sys.stderr)
        return {}, {"method": "not identified (no CO2 data): nominal values"}, "not identified (nominal values)"
    srcs = []
    sets = []
    for csv_arg, drive, name in (
        (args.co2_csv, CO2_TRAIN_DRIVE, "co2_train.csv"),
        (args.co2_validation_csv, CO2_VALIDATION_DRIVE, "co2_validation.csv"),
    ):
        if csv_arg:
            sets.append(_co2_series_from_csv(csv_arg))
            srcs.append(csv_arg)
            continue
        series = generate_co2_excitation(drive, exc)
        n = len(series["t_s"])
        table = dict(
            series, n_occupants=np.full(n, series["n_occupants"]), co2_amb_ppm=np.full(n, series["co2_amb_ppm"])
        )
        sha = write_series_csv(table, data_dir / name, CO2_CSV_COLUMNS, CO2_FINE_COLUMNS)
        sets.append(series)
        srcs.append(f"{name} (sha256 {sha[:16]}; {drive[0]}, {drive[1]} occupants)")
    train, valid = sets
    fit = fit_co2_balance(train, train["n_occupants"], train["co2_amb_ppm"])
    err_valid = co2_free_run_max_err_ppm(
        valid, valid["n_occupants"], valid["co2_amb_ppm"], fit.m_air_kg, fit.leak_0_kgps, fit.leak_per_mps_kgps
    )
    air = (fit.m_air_kg, fit.leak_0_kgps, fit.leak_per_mps_kgps)
    moist = fit_moisture_balance(train, train["n_occupants"], *air)
    moist_valid = moisture_free_run_max_err_kgkg(
        valid, valid["n_occupants"], *air, moist.occ_latent_w, moist.bypass_factor
    )
    fields = {
        "co2_m_air_kg": fit.m_air_kg,
        "co2_leak_0_kgps": fit.leak_0_kgps,
        "co2_leak_per_mps_kgps": fit.leak_per_mps_kgps,
        "moist_coil_bypass_factor": moist.bypass_factor,
        "moist_occ_latent_w": moist.occ_latent_w,
    }
    report = {
        "method": "linear least squares of the CO2 balance (fit_co2_balance), then of the water balance with its "
        "air mass and leakage (fit_moisture_balance); validation: each balance run free",
        "rate_rms_training_ppm_per_s": fit.rate_rms_ppm_per_s,
        "free_run_max_err_training_ppm": fit.free_run_max_err_ppm,
        "free_run_max_err_validation_ppm": err_valid,
        "moisture_rate_rms_training_g_per_kg_s": 1e3 * moist.rate_rms_kgkg_per_s,
        "moisture_free_run_max_err_training_g_per_kg": 1e3 * moist.free_run_max_err_kgkg,
        "moisture_free_run_max_err_validation_g_per_kg": 1e3 * moist_valid,
    }
    return fields, report, f"from {srcs[0]}, validated on {srcs[1]}"


def _series_with_door(path) -> dict:
    """A training CSV (:data:`SERIES_COLUMNS`) with its ``recirc_share`` column, NaN where the file has none."""
    # a door column is read like every other (a malformed value is an error); none: NaN, the --recirc-share given
    return read_series_csv(path, SERIES_COLUMNS + ("recirc_share",), optional=("recirc_share",))


def _check_horizon(horizon_steps: int, ts_s: float, iv_train: dict, iv_valid: dict) -> None:
    """ValueError naming ``--horizon-steps`` unless both data sets hold a prediction window of that many steps."""
    longest = {"training": longest_horizon_steps(iv_train), "validation": longest_horizon_steps(iv_valid)}
    for which, n in longest.items():
        if n < 1:
            raise ValueError(f"the {which} data hold no whole {ts_s:g} s interval with its inputs held")
    if horizon_steps > min(longest.values()):
        raise ValueError(
            f"--horizon-steps {horizon_steps} is longer than the data allow: their longest runs of consecutive "
            f"{ts_s:g} s intervals are {longest['training']} (training) and {longest['validation']} (validation): "
            f"give --horizon-steps {min(longest.values())} or less"
        )


def _identify(args, argv) -> int:
    """The work of :func:`main` for parsed ``args``."""
    data_dir, out = output_paths(args.out)
    exc = ExcitationSettings(seed=args.seed, ts_s=args.ts)
    if not (math.isfinite(args.recirc_share) and 0.0 <= args.recirc_share <= 1.0):
        raise ValueError(f"--recirc-share must be in [0, 1], got {args.recirc_share}")
    simulated: dict[str, tuple[dict, tuple]] = {}  # file name: (series, drives); written once the checks pass
    src = {"train.csv": ", ".join(args.from_csv or ()), "validation.csv": args.validation_csv}
    if args.from_csv:
        parts = [_series_with_door(p) for p in args.from_csv]
        steps = [sample_step_s(s, p) for s, p in zip(parts, args.from_csv)]
        for p, dt in zip(args.from_csv, steps):
            if abs(dt - steps[0]) > STEP_REL_TOL * steps[0]:
                raise ValueError(
                    f"{p}: sample step {dt:g} s, {args.from_csv[0]}: {steps[0]:g} s: the --from-csv files must have "
                    "one sample step (resample them)"
                )
        for j, s in enumerate(parts):
            s["segment"] = s["segment"] + 1000 * j
        train = {c: np.concatenate([s[c] for s in parts]) for c in (*SERIES_COLUMNS, "recirc_share")}
    else:
        print(f"ceco identify: simulating the {len(TRAIN_DRIVES)} training drives on the plant", file=sys.stderr)
        train = generate_excitation(TRAIN_DRIVES, exc)
        simulated["train.csv"] = (train, TRAIN_DRIVES)
    if args.validation_csv:
        valid = read_series_csv(args.validation_csv)
        sample_step_s(valid, args.validation_csv)
    else:
        print("ceco identify: simulating the validation drive", file=sys.stderr)
        valid = generate_excitation(VALIDATION_DRIVES, exc, seed_offset=1000)
        simulated["validation.csv"] = (valid, VALIDATION_DRIVES)
    iv_train = intervals_from_series(train, args.ts)
    iv_valid = intervals_from_series(valid, args.ts)
    _check_horizon(args.horizon, args.ts, iv_train, iv_valid)  # (before the fit: data that cannot serve, said first)
    emap = eta_ac_points(EtaMapSettings())
    a_eta, v_eta, eta_rms = fit_eta_ac(emap["speeds_mps"], emap["ratio"])
    print("ceco identify: fitting and validating", file=sys.stderr)
    params, resid = fit_intervals(iv_train, args.ts, eta=(a_eta, v_eta), recirc_share=args.recirc_share)
    for name, (series, drives) in simulated.items():
        sha = write_series_csv(series, data_dir / name)
        src[name] = f"{name} (sha256 {sha[:16]}; drives {', '.join(f'{a}/{b}' for a, b in drives)})"
    v20 = int(np.argmin(np.abs(emap["speeds_mps"] - 20.0)))
    eta_report = {
        "method": "plant steady cycle COP(V)/COP(0), EtaMapSettings defaults",
        "loads_w": [float(q) for q in emap["loads_w"]],
        "rms_ratio": eta_rms,
        "plant_ratio_at_20mps": [float(x) for x in np.round(emap["ratio"][:, v20], 4)],
        "model_eta_at_20mps": float(cm.eta_ac(params, 20.0)),
    }
    co2_fields, co2_report, co2_src = _identify_co2(args, data_dir, exc)
    cmd = "ceco identify" + (" " + " ".join(argv) if argv else "")
    params = dataclasses.replace(
        params,
        **co2_fields,
        provenance=f"{cmd}; excitation seed {args.seed}; training data {src['train.csv']}; validation data "
        f"{src['validation.csv']}; CO2 balance {co2_src}",
    )
    rep_train = prediction_errors(params, iv_train, args.horizon)
    rep_valid = prediction_errors(params, iv_valid, args.horizon)
    report = {
        "eta_ac_fit": round_floats(eta_report),
        "fit_residuals_training": round_floats(resid),
        "prediction_training": round_floats(rep_train),
        "prediction_validation": round_floats(rep_valid),
        "co2_balance_fit": round_floats(co2_report),
    }
    header = (
        "Identified control-oriented model (ceco_controller/model.py), GENERATED - do not edit.\n"
        f"Regenerate with: {cmd}\nFit method and report: docs/controller.md"
    )
    cm.save_params(params, out, header=header, extra={"fit_report": report})
    print(f"wrote {out}")
    print(f"to use it: --model-params {out} (ceco sim), or copy it over {cm.DEFAULT_PARAMS_PATH} and commit")
    print_fit(params.to_dict(), report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
