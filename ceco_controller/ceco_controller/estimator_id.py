"""Identification of the state estimator's models E1-E3 and process noise (``ceco_controller.estimator``).

From the same plant data as the NMPC model (``identification.py``: the excitation runs
``data/identification/train.csv``, validation ``validation.csv``), which carry the interior and
shell temperatures a test vehicle instrumented with thermocouples would record:

1. The 1 s series are cut into model intervals of ``ts_s`` (5 s) with constant inputs
   (:func:`estimator_intervals`): states at both ends, the vent air sampled at the end, interval
   means of ambient, sun load and speed.
2. Linear least squares (``numpy.linalg.lstsq``) of E3 (vent air at the sample), E1 (interior) and
   E2 (shell), each linear in its coefficients.
3. Process noise std per model step, first from the residuals: eq. (1) (with E3 for the vent air)
   its one-step residual RMS; E1 and E2 the larger of the one-step residual RMS and the random-walk
   equivalent of their open-loop drift over ``drift_steps`` (RMS error after N steps / sqrt(N)),
   because their residuals are correlated in time and a one-step RMS understates what accumulates.
   Then, because the residuals of eq. (1) are not white either (its errors are largest, up to 1 K
   per step, and of one sign during a pull-down), the std of eq. (1) and a common factor on E1/E2
   are scaled by the factors of :data:`Q_CAB_FACTORS` x :data:`Q_SLOW_FACTORS` that minimize the
   filter's squared T_int + T_shell error on the training data from 60 s after key-on (the filter
   replayed from the key-on prior, :func:`replay`): a white-noise filter that treats a correlated
   error as white must be told it is larger.
4. Report: the same errors on the validation data, and the filter replayed on every training and
   validation drive from the key-on prior (:func:`replay`): RMSE of T_int and T_shell; and on the
   validation drives with each sensor offset of :data:`SENSOR_OFFSETS`.

CLI::

    python -m ceco_controller.estimator_id     # fit, write config/estimator_params.yaml
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import pathlib
import sys

import numpy as np

from . import estimator as est
from . import model as cm
from .identification import DEFAULT_DATA_DIR, SERIES_COLUMNS, read_series_csv

__all__ = ["Q_CAB_FACTORS", "Q_SLOW_FACTORS", "SENSOR_OFFSETS", "estimator_intervals", "fit_estimator", "replay",
           "replay_errors", "main"]

Q_CAB_FACTORS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
"""Candidate factors on the residual std of eq. (1) [-] (step 3 of the method)."""
Q_SLOW_FACTORS = (1.0, 2.0, 4.0, 8.0)
"""Candidate factors on the residual std of E1 and E2 [-]."""
SENSOR_OFFSETS = (("t_vent_c", 0.5), ("t_vent_c", -0.5), ("t_evap_c", 0.5), ("t_evap_c", -0.5), ("t_cab_c", 0.3),
                  ("t_cab_c", -0.3))
"""Sensor offsets [K] (NTC tolerances) the report replays the filter with, one at a time."""
TUNE_AFTER_S = 60.0
"""The covariance search scores the filter from this time after key-on on [s]."""


def estimator_intervals(series: dict, ts_s: float = 5.0) -> dict:
    """Cut 1 s series (``identification.SERIES_COLUMNS``) into model intervals with constant inputs.

    Row i holds the temperatures at t_i (the vent air produced by the command of row i-1) and the
    command held over [t_i, t_i + dt). An interval starts at row i, covers rows i .. i+m-1 and ends
    at row i+m (m = ts_s/dt). Returns arrays ``tc0, tc1, ti0, ti1, ts0, ts1, te0, te1, tv1, m, ta,
    ta1, sol, v, seg`` (0/1: start/end; ``ta, sol, v`` interval means, ``ta1`` at the end).
    """
    for c in SERIES_COLUMNS:
        if c not in series:
            raise ValueError(f"series: missing column {c!r}")
    t = np.asarray(series["t_s"], float)
    dt = float(np.median(np.diff(t)))
    m = int(round(ts_s / dt))
    if m < 1 or abs(m * dt - ts_s) > 1e-6:
        raise ValueError(f"ts_s {ts_s} must be a whole multiple of the sample step {dt}")
    keys = ("tc0", "tc1", "ti0", "ti1", "ts0", "ts1", "te0", "te1", "tv1", "m", "ta", "ta1", "sol", "v", "seg")
    out: dict[str, list] = {k: [] for k in keys}
    seg = np.asarray(series["segment"])
    for s in np.unique(seg):
        idx = np.flatnonzero(seg == s)
        g = {c: np.asarray(series[c], float)[idx] for c in SERIES_COLUMNS}
        for i in range(0, idx.size - m, m):
            sl = slice(i, i + m)
            if np.ptp(g["mdot_bl_kgps"][sl]) > 1e-9:
                continue
            j = i + m
            row = (g["t_cab_c"][i], g["t_cab_c"][j], g["t_int_c"][i], g["t_int_c"][j], g["t_shell_c"][i],
                   g["t_shell_c"][j], g["t_evap_c"][i], g["t_evap_c"][j], g["t_vent_c"][j], g["mdot_bl_kgps"][i],
                   np.mean(g["t_amb_c"][sl]), g["t_amb_c"][j], np.mean(g["solar_wm2"][sl]),
                   np.mean(g["speed_mps"][sl]), s)
            for k, v in zip(keys, row):
                out[k].append(float(v))
    return {k: np.asarray(v) for k, v in out.items()}


def _lstsq(a, b):
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    return coef


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else float("nan")


def _regressors(iv: dict):
    """(E3, E1, E2) regressor matrices and targets of interval data."""
    m, te1 = iv["m"], iv["te1"]
    d_cab, d_amb = iv["tc1"] - te1, iv["ta1"] - te1
    a3 = np.column_stack([d_cab, d_cab * m, d_amb, d_amb * m, (iv["ti1"] - te1) / m, 1.0 / m, np.ones_like(m)])
    y3 = iv["tv1"] - te1
    te_mid = 0.5 * (iv["te0"] + iv["te1"])
    dci = iv["tc0"] - iv["ti0"]
    a1 = np.column_stack([dci, dci * (m / est.M_REF_KGPS) ** 0.8, iv["ts0"] - iv["ti0"], iv["sol"],
                          te_mid - iv["ti0"]])
    y1 = iv["ti1"] - iv["ti0"]
    das = iv["ta"] - iv["ts0"]
    a2 = np.column_stack([iv["tc0"] - iv["ts0"], iv["ti0"] - iv["ts0"], das, das * iv["v"] ** 0.8, iv["sol"]])
    y2 = iv["ts1"] - iv["ts0"]
    return (a3, y3), (a1, y1), (a2, y2)


def _model_errors(p: cm.ControlModelParams, q: est.EstimatorParams, iv: dict, drift_steps: int) -> dict:
    """One-step residuals of eq. (1)/E1/E2/E3 and the open-loop drift of E1/E2 over ``drift_steps``."""
    x0 = (iv["tc0"], iv["ti0"], iv["ts0"])
    tc1, ti1, ts1 = est.process_step(p, q, x0, iv["m"], iv["te0"], iv["te1"], iv["ta"], iv["sol"], iv["v"])
    tv = est.t_vent_c(q, iv["te1"], iv["tc1"], iv["ti1"], iv["ta1"], iv["m"])
    # open-loop E1/E2 from the true start of each run of consecutive intervals, true T_cab as input
    drift_int, drift_sh = [], []
    n = iv["m"].size
    starts = [k for k in range(0, n - drift_steps, drift_steps)
              if np.all(iv["seg"][k:k + drift_steps] == iv["seg"][k])
              and np.allclose(iv["ti1"][k:k + drift_steps - 1], iv["ti0"][k + 1:k + drift_steps])]
    for k in starts:
        ti, ts = iv["ti0"][k], iv["ts0"][k]
        for j in range(k, k + drift_steps):
            te = 0.5 * (iv["te0"][j] + iv["te1"][j])
            ti, ts = (float(est.t_int_next_c(q, ti, iv["tc0"][j], ts, te, iv["m"][j], iv["sol"][j])),
                      float(est.t_shell_next_c(q, ts, iv["tc0"][j], ti, iv["ta"][j], iv["v"][j], iv["sol"][j])))
        drift_int.append(ti - iv["ti1"][k + drift_steps - 1])
        drift_sh.append(ts - iv["ts1"][k + drift_steps - 1])
    return {"t_cab_1step_rms_k": _rms(tc1 - iv["tc1"]), "t_int_1step_rms_k": _rms(ti1 - iv["ti1"]),
            "t_shell_1step_rms_k": _rms(ts1 - iv["ts1"]), "t_vent_rms_k": _rms(tv - iv["tv1"]),
            "drift_steps": int(drift_steps), "n_drift_windows": len(starts),
            "t_int_drift_rms_k": _rms(drift_int), "t_shell_drift_rms_k": _rms(drift_sh)}


def fit_estimator(series: dict, model_params: cm.ControlModelParams, ts_s: float = 5.0,
                  drift_steps: int = 60) -> tuple[est.EstimatorParams, dict]:
    """Least-squares fit of E1-E3 and the process noise; returns (params, training errors)."""
    iv = estimator_intervals(series, ts_s)
    if iv["m"].size < 20:
        raise ValueError(f"need at least 20 intervals to fit, got {iv['m'].size}")
    (a3, y3), (a1, y1), (a2, y2) = _regressors(iv)
    v = _lstsq(a3, y3)
    a = _lstsq(a1, y1)
    b = _lstsq(a2, y2)
    q = est.EstimatorParams(
        ts_s=ts_s, int_cab=a[0], int_cab_forced=a[1], int_shell=a[2], int_solar_k_per_wm2=a[3], int_evap=a[4],
        shell_cab=b[0], shell_int=b[1], shell_amb=b[2], shell_amb_speed=b[3], shell_solar_k_per_wm2=b[4],
        vent_cab=v[0], vent_cab_flow_s_per_kg=v[1], vent_amb=v[2], vent_amb_flow_s_per_kg=v[3],
        vent_duct_kgps=v[4], vent_heat_k_kgps=v[5], vent_offset_k=v[6])
    err = _model_errors(model_params, q, iv, drift_steps)
    root_n = float(np.sqrt(drift_steps))
    q = dataclasses.replace(
        q, q_cab_k=err["t_cab_1step_rms_k"],
        q_int_k=max(err["t_int_1step_rms_k"], err["t_int_drift_rms_k"] / root_n),
        q_shell_k=max(err["t_shell_1step_rms_k"], err["t_shell_drift_rms_k"] / root_n),
        vent_residual_k=err["t_vent_rms_k"])
    err["n_intervals"] = int(iv["m"].size)
    best = None
    for fc in Q_CAB_FACTORS:
        for fs in Q_SLOW_FACTORS:
            cand = dataclasses.replace(q, q_cab_k=fc * q.q_cab_k, q_int_k=fs * q.q_int_k, q_shell_k=fs * q.q_shell_k)
            rep = replay(series, est.CabinStateEstimator(model_params, cand, control_period_s=ts_s))
            late = rep["t_s"] >= TUNE_AFTER_S
            cost = float(np.mean((rep["t_int_est_c"] - rep["t_int_c"])[late] ** 2)
                         + np.mean((rep["t_shell_est_c"] - rep["t_shell_c"])[late] ** 2))
            if best is None or cost < best[0]:
                best = (cost, fc, fs, cand)
    assert best is not None
    err.update({"q_cab_residual_k": q.q_cab_k, "q_int_residual_k": q.q_int_k, "q_shell_residual_k": q.q_shell_k,
                "q_cab_factor": best[1], "q_slow_factor": best[2],
                "tuned_rms_k": float(np.sqrt(best[0]))})
    return best[3].validate(), err


def replay(series: dict, estimator: est.CabinStateEstimator, meas_filter=None) -> dict:
    """Run the filter on recorded 1 s series, one update per control period, per segment (key-on each).

    At t_k = k Ts the filter gets the vehicle sensors of row k Ts/dt and the command of the row
    before (applied over the last period). ``meas_filter(t_s, meas) -> meas`` may corrupt the samples
    (tests). Returns arrays ``t_s, segment, t_int_est_c, t_shell_est_c, t_int_c, t_shell_c,
    t_cab_est_c, t_cab_c, valid``.
    """
    t = np.asarray(series["t_s"], float)
    dt = float(np.median(np.diff(t)))
    every = int(round(estimator.control_period_s / dt))
    out: dict[str, list] = {k: [] for k in ("t_s", "segment", "t_int_est_c", "t_shell_est_c", "t_int_c", "t_shell_c",
                           "t_cab_est_c", "t_cab_c", "valid")}
    seg = np.asarray(series["segment"])
    for s in np.unique(seg):
        idx = np.flatnonzero(seg == s)
        estimator.reset()
        t0 = t[idx[0]]
        for j in range(0, idx.size, every):
            r = idx[j]
            meas = {"t_cab_c": series["t_cab_c"][r], "t_vent_c": series["t_vent_c"][r],
                    "t_evap_c": series["t_evap_c"][r], "t_amb_c": series["t_amb_c"][r],
                    "solar_wm2": series["solar_wm2"][r], "speed_mps": series["speed_mps"][r]}
            ts = float(t[r] - t0)
            if meas_filter is not None:
                meas = meas_filter(ts, meas)
            u = ((series["mdot_bl_kgps"][idx[j - 1]], series["t_evap_sp_c"][idx[j - 1]]) if j > 0
                 else (series["mdot_bl_kgps"][r], series["t_evap_sp_c"][r]))
            e = estimator.update(ts, meas, u)
            for k, v in (("t_s", ts), ("segment", s), ("t_int_est_c", e.t_int_c), ("t_shell_est_c", e.t_shell_c),
                         ("t_int_c", series["t_int_c"][r]), ("t_shell_c", series["t_shell_c"][r]),
                         ("t_cab_est_c", e.t_cab_c), ("t_cab_c", series["t_cab_c"][r]), ("valid", e.valid)):
                out[k].append(v)
    return {k: np.asarray(v) for k, v in out.items()}


def replay_errors(rep: dict, after_s: float = 120.0) -> dict:
    """RMSE / max |error| of T_int and T_shell over a replay, whole and from ``after_s`` on."""
    late = rep["t_s"] >= after_s
    e_i = rep["t_int_est_c"] - rep["t_int_c"]
    e_s = rep["t_shell_est_c"] - rep["t_shell_c"]
    return {"t_int_rmse_k": _rms(e_i), "t_shell_rmse_k": _rms(e_s),
            f"t_int_rmse_after_{after_s:g}s_k": _rms(e_i[late]), f"t_shell_rmse_after_{after_s:g}s_k": _rms(e_s[late]),
            "t_int_max_abs_k": float(np.max(np.abs(e_i))), "t_shell_max_abs_k": float(np.max(np.abs(e_s)))}


def _round(d: dict) -> dict:
    return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in d.items()}


def main(argv=None) -> int:
    """CLI: fit E1-E3 from the identification data, validate, write the parameter file."""
    ap = argparse.ArgumentParser(prog="ceco identify-estimator", description="Identify the state estimator's models.")
    ap.add_argument("--train-csv", default=str(DEFAULT_DATA_DIR / "train.csv"), help="training series CSV")
    ap.add_argument("--validation-csv", default=str(DEFAULT_DATA_DIR / "validation.csv"),
                    help="validation series CSV (not fitted)")
    ap.add_argument("--model-params", default=None, help="the NMPC's model parameter file (eq. 1)")
    ap.add_argument("--out", default=str(est.DEFAULT_ESTIMATOR_PARAMS_PATH), help="parameter file to write")
    ap.add_argument("--drift-steps", type=int, default=60, help="open-loop drift window [model steps]")
    args = ap.parse_args(argv)
    mp = cm.load_params(args.model_params)
    train, valid = read_series_csv(args.train_csv), read_series_csv(args.validation_csv)
    q, err_train = fit_estimator(train, mp, mp.ts_s, args.drift_steps)
    err_valid = _model_errors(mp, q, estimator_intervals(valid, mp.ts_s), args.drift_steps)
    sha = {p: hashlib.sha256(pathlib.Path(p).read_bytes()).hexdigest()[:16]
           for p in (args.train_csv, args.validation_csv)}
    cmd = "python -m ceco_controller.estimator_id" + (" " + " ".join(argv) if argv else "")
    q = dataclasses.replace(q, provenance=(
        f"{cmd}; training data {pathlib.Path(args.train_csv).name} (sha256 {sha[args.train_csv]}), validation data "
        f"{pathlib.Path(args.validation_csv).name} (sha256 {sha[args.validation_csv]}); eq. (1) of "
        f"{args.model_params or 'config/model_params.yaml'}"))
    ekf = {}
    for name, data in (("training", train), ("validation", valid)):
        rep = replay(data, est.CabinStateEstimator(mp, q, control_period_s=mp.ts_s))
        ekf[name] = _round(replay_errors(rep))
    offsets = {}
    for sensor, off in SENSOR_OFFSETS:
        rep = replay(valid, est.CabinStateEstimator(mp, q, control_period_s=mp.ts_s),
                     meas_filter=lambda t, m, s=sensor, o=off: {**m, s: m[s] + o})
        e = replay_errors(rep)
        offsets[f"{sensor}{off:+g}"] = [round(e["t_int_rmse_after_120s_k"], 4),
                                        round(e["t_shell_rmse_after_120s_k"], 4)]
    report = {"model_errors_training": _round(err_train), "model_errors_validation": _round(err_valid),
              "filter_replay_default_prior": ekf,
              "filter_replay_validation_sensor_offsets_rmse_after_120s_k_int_shell": offsets}
    header = ("Identified state-estimator models E1-E3 (ceco_controller/estimator.py), GENERATED - do not edit.\n"
              f"Regenerate with: {cmd}\nMethod and report: docs/controller.md section 5")
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    est.save_estimator_params(q, out, header=header, extra={"fit_report": report})
    print(f"wrote {out}")
    for k, v in q.to_dict().items():
        if k != "provenance":
            print(f"  {k:26s} {v: .6g}")
    for name, rep in report.items():
        print(name)
        for k, v in rep.items():
            print(f"  {k:32s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
