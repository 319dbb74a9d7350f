"""In-process closed-loop simulator: plant + V2X preview + one controller, no ROS.

Timing (docs/architecture.md): the plant steps every ``plant_dt_s = 1 s``;
at ``t = k*Ts`` the controller gets the measurements at ``t`` and the
previews on ``t, t+Ts, ..., t+Np*Ts`` and its command is held over
``[k*Ts, (k+1)*Ts)``. Deterministic: the same scenario, strategy, settings and
seed give the same numbers (the solver's wall-clock time is recorded but never
used for a decision).

:func:`write_run` writes a run directory (``timeseries.csv``, ``diagnostics.csv``,
``metrics.json``). The command line is ``ceco sim`` (``ceco_bringup.sim``).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import time

import numpy as np

from ceco_core import rundir
from ceco_core.contracts import ACTUATOR_LIMITS, DIAGNOSTICS_COLUMNS, MEASUREMENT_MODES, NAMED_STRATEGIES, PLANT_STEP_S
from ceco_core.metrics import comfort_series_metrics, run_metrics
from ceco_core.run_status import check_control
from ceco_plant_sim.compiled_plant import PlantEvaluation
from ceco_plant_sim.scenario_plant import ScenarioPlant, check_overrides, n_plant_steps, steps_per_control
from ceco_v2x_preview.preview import PERFECT, PreviewQuality, make_previews
from ceco_v2x_preview.scenario import Scenario, load_scenario

from . import model as cm
from .estimating_controller import EstimatingController, with_measurements
from .estimator import estimation_errors
from .factory import ControllerCache, make_controller
from .observation import observation

__all__ = [
    "SimSettings",
    "RunResult",
    "simulate",
    "make_controller",
    "write_run",
    "TIMESERIES_COLUMNS",
    "DIAGNOSTICS_CSV_COLUMNS",
]

TIMESERIES_COLUMNS = rundir.TIMESERIES_COLUMNS + rundir.TIMESERIES_EXTRA
"""Columns of the simulator's ``timeseries.csv``: the contract's (``ceco_core.rundir``), then extras."""

DIAGNOSTICS_CSV_COLUMNS = DIAGNOSTICS_COLUMNS + ("pmv_pred", "t_cab_pred_c", "step_time_ms")
"""Columns of ``diagnostics.csv``: :data:`DIAGNOSTICS_COLUMNS`, then the predicted PMV [-] and T_cab [degC]
trajectories over the horizon (grid points 0..Np, ``;``-joined; empty without a successful solve) and the
wall time of the whole control step, the controller's ``compute`` call [ms] (the benchmark's time ratio)."""


@dataclasses.dataclass(frozen=True)
class SimSettings:
    """Settings of one closed-loop run."""

    control_period_s: float | None = None
    """Control period Ts [s]; None: the scenario's (5 s)."""
    horizon_steps: int | None = None
    """Prediction horizon Np [steps]; None: the scenario's (6)."""
    preview_quality: PreviewQuality = PERFECT
    """Quality of the V2X previews (perfect as in the paper, noisy, delayed, missing spans)."""
    seed: int | None = None
    """Seed for the preview noise; None: the scenario's."""
    plant_dt_s: float = PLANT_STEP_S
    """Plant step and recording interval [s]."""
    duration_s: float | None = None
    """Run length [s]; None: the scenario's."""
    progress: bool = True
    """Show a tqdm progress bar."""
    model_params_path: str | None = None
    """Identified model parameter file; None: ceco_controller/config/model_params.yaml."""
    strategy_overrides: tuple = ()
    """((field, value), ...) overriding the strategy's settings: StrategySettings fields for a CECO
    strategy (e.g. (('gamma_w', 1e4),)), AccSettings fields for the baseline (e.g. (('setpoint_c', 25.0),))."""
    plant_overrides: tuple = ()
    """((field, value), ...) overriding the simulated car's PlantParams (the controllers keep their models)."""
    comfort_overrides: tuple = ()
    """((field, value), ...) overriding the ComfortParams of the scored PMV, nested parts by dotted name
    (e.g. (('air.jet_body_fraction', 0.2),)), or 'pa_pa' (a fixed scored vapour pressure [Pa]); plant side
    only: the NMPC keeps its nominal comfort model."""
    controller_config_path: str | None = None
    """Controller settings file; None: ceco_controller/config/controller.yaml."""
    prepare_first_step: bool = False
    """Before the first step, let an NMPC solve it without deadline (``NmpcController.prepare``), as
    a node that does so before taking control; off: the first step is a cold solve inside it."""
    plant_evaluation: str = "compiled"
    """How the simulated plant step is evaluated: 'compiled' (generated C, cached; the Python evaluation
    with one warning where no C compiler works) or 'python' (ceco_plant_sim.compiled_plant.PlantEvaluation)."""
    measurements: str = "full"
    """'full': the controller reads every state it models; 'vehicle': only the production sensors,
    T_int, T_shell and T_glass estimated (``ceco_controller.estimator``; docs/controller.md section 5)."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if self.control_period_s is not None and not (
            math.isfinite(self.control_period_s) and self.control_period_s > 0
        ):
            raise ValueError("SimSettings.control_period_s must be finite and > 0")
        if self.horizon_steps is not None and not (isinstance(self.horizon_steps, int) and self.horizon_steps >= 1):
            raise ValueError("SimSettings.horizon_steps must be an int >= 1")
        if not (math.isfinite(self.plant_dt_s) and self.plant_dt_s > 0):
            raise ValueError("SimSettings.plant_dt_s must be finite and > 0")
        if self.duration_s is not None and not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError("SimSettings.duration_s must be finite and > 0")
        PlantEvaluation(self.plant_evaluation).validate()
        if self.measurements not in MEASUREMENT_MODES:
            raise ValueError(f"SimSettings.measurements must be one of {MEASUREMENT_MODES}, got {self.measurements!r}")
        for name in ("plant_overrides", "comfort_overrides"):
            value = getattr(self, name)
            if not (isinstance(value, tuple) and all(isinstance(p, tuple) and len(p) == 2 for p in value)):
                raise ValueError(f"SimSettings.{name} must be a tuple of (field, value) pairs, got {value!r}")
        try:
            check_overrides(dict(self.plant_overrides), dict(self.comfort_overrides))
        except ValueError as exc:
            raise ValueError(f"SimSettings.plant_overrides/comfort_overrides: {exc}") from exc
        self.preview_quality.validate()


@dataclasses.dataclass
class RunResult:
    """A finished run: the recorded series, the per-step diagnostics and the metrics."""

    scenario: str
    strategy: str
    timeseries: dict
    """Column name -> numpy array (one value per plant step)."""
    diagnostics: list
    """One dict per control step (columns DIAGNOSTICS_COLUMNS)."""
    diag_objects: list
    """The Diagnostics objects (with predicted trajectories)."""
    metrics: dict
    step_time_s: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    """Wall time of each control step's ``controller.compute`` call [s]."""
    estimates: dict | None = None
    """measurements='vehicle': per control step the estimates and the plant truth (column -> array);
    None in full mode."""


def simulate(
    scenario: Scenario | str,
    strategy: str,
    settings: SimSettings | None = None,
    controller=None,
    controller_cache: ControllerCache | None = None,
) -> RunResult:
    """Run one strategy on one scenario in closed loop against the plant.

    Args:
        scenario: a :class:`Scenario` or a bundled name / YAML path.
        strategy: ``baseline``, a CECO strategy (``ceco``, ``ceco-e``, ``ceco-c``, ``ceco-ioch``, ``ceco-pmv``) or
            a named variant of one (``ceco-pmv-aq``: :data:`ceco_core.contracts.STRATEGY_VARIANTS`).
        settings: :class:`SimSettings`.
        controller: an already built controller to use (for tests); default: built here.
        controller_cache: reuse an NMPC built by an earlier run of this process (a benchmark
            worker's :class:`~ceco_controller.factory.ControllerCache`); the results are the same.
    """
    settings = settings or SimSettings()
    settings.validate()
    if isinstance(scenario, str):
        scenario = load_scenario(scenario)
    if strategy not in NAMED_STRATEGIES:
        raise ValueError(f"strategy must be one of {NAMED_STRATEGIES}, got {strategy!r}")
    ts, n_p = scenario.control.timing(settings.control_period_s, settings.horizon_steps)
    dt = float(settings.plant_dt_s)
    steps_per_ctrl = steps_per_control(ts, dt)
    quality = settings.preview_quality
    if settings.seed is not None:
        quality = dataclasses.replace(quality, seed=int(settings.seed))
    duration = float(settings.duration_s or scenario.duration_s)
    n = n_plant_steps(duration, dt)
    # the baseline reads the control model too: its state estimator (vehicle measurements) and its CO2 door's balance
    mp = cm.load_params(settings.model_params_path)
    if controller is None:
        controller = make_controller(
            strategy,
            scenario,
            ts,
            n_p,
            mp,
            dict(settings.strategy_overrides),
            config_path=settings.controller_config_path,
            measurements=settings.measurements,
            cache=controller_cache,
        )
    else:
        controller = with_measurements(controller, settings.measurements, ts, model_params=mp)
    vehicle = isinstance(controller, EstimatingController)
    est_rows: dict[str, list] = {c: [] for c in ESTIMATOR_CSV_COLUMNS}  # filled in vehicle mode only
    sp = ScenarioPlant(
        scenario,
        dt,
        plant_overrides=dict(settings.plant_overrides),
        comfort_overrides=dict(settings.comfort_overrides),
        evaluation=PlantEvaluation(settings.plant_evaluation),
    )
    cols = {c: np.empty(n) for c in TIMESERIES_COLUMNS}
    diags, diag_objs, step_times = [], [], []
    iterator = range(n)
    if settings.progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"{scenario.name}/{strategy}", unit="s", leave=False)
    for i in iterator:
        t = i * dt
        if i % steps_per_ctrl == 0:
            k = i // steps_per_ctrl
            pv = make_previews(scenario, t, ts, n_p + 1, quality)
            obs = observation(k, t, sp.meas, scenario.env_at(t), sp.cmd, pv, scenario)
            if k == 0 and settings.prepare_first_step and hasattr(controller, "prepare"):
                controller.prepare(obs)
            t_step = time.perf_counter()
            cmd, diag = controller.compute(obs)
            step_times.append(time.perf_counter() - t_step)
            if vehicle:
                _record_estimate(est_rows, controller.last_estimate, sp.meas)
            if not ACTUATOR_LIMITS.contains(cmd.mdot_bl_kgps, cmd.t_evap_sp_c):
                raise AssertionError(f"{strategy}: command {cmd} outside the actuator bounds at t={t}")
            cmd.validate()  # the door's share too (NaN: not commanded)
            diags.append(diag.to_row())
            diag_objs.append(diag)
        r = sp.step(cmd)
        env, out = r.env, r.out
        row = {
            "t_s": r.t_s,
            **{
                c: r.meas[c] for c in ("t_cab_c", "t_int_c", "t_shell_c", "t_evap_c", "t_vent_c", "t_glass_c", "rh_cab")
            },
            "t_amb_c": env.t_amb_c,
            "solar_wm2": env.solar_wm2,
            "speed_mps": env.speed_mps,
            "rh": env.rh,
            "mdot_bl_kgps": r.u.mdot_bl_kgps,
            "t_evap_sp_c": r.u.t_evap_sp_c,
            "p_comp_w": out.p_comp_w,
            "p_blower_w": out.p_blower_w,
            "q_evap_w": out.q_evap_w,
            "cop": out.cop,
            "pmv": r.pmv,
            "ppd": r.ppd,
            "pmv_lb": r.pmv_lb,
            "pmv_ub": r.pmv_ub,
            **{c: float(getattr(r.comfort, c)) for c in rundir.COMFORT_COLUMNS},
            "p_cond_fan_w": out.p_cond_fan_w,
            "q_latent_w": out.q_latent_w,
            "comp_speed_rpm": out.comp_speed_rpm,
            "capacity_limited": float(out.capacity_limited),
            "co2_cab_ppm": r.meas["co2_cab_ppm"],
            "co2_sensor_ppm": r.meas["co2_sensor_ppm"],
            "recirc_share": r.meas["recirc_share"],
            "recirc_share_cmd": r.recirc_share_cmd,
        }
        for c in TIMESERIES_COLUMNS:
            cols[c][i] = row[c]
    metrics = run_metrics(cols, air_limits=scenario.air_quality.limits)
    nd = [d for d in diag_objs if d.solve_time_ms is not None]
    # the comfort-zone phase: samples where the upper bound is at its tightest (after the pull-down
    # relaxation); the paper's metrics restricted to it separate "how the pull-down relaxation was
    # used" from "how comfortable the regulated cabin is"
    zone = cols["pmv_ub"] <= np.min(cols["pmv_ub"]) + 1e-9
    viol = (cols["pmv"] > cols["pmv_ub"]) | (cols["pmv"] < cols["pmv_lb"])
    metrics.update(
        {
            "zone_start_s": float(cols["t_s"][np.argmax(zone)]),
            "E_zone_J": float(
                np.sum(cols["p_comp_w"][zone] + cols["p_blower_w"][zone] + cols["p_cond_fan_w"][zone]) * dt
            ),
            "I_pmv_zone": float(np.sum(cols["pmv"][zone] ** 2) * dt),
            "otc_violation_zone_pct": float(
                100.0 * np.count_nonzero(viol & zone) / max(int(np.count_nonzero(zone)), 1)
            ),
            "pmv_mean_zone": float(np.mean(cols["pmv"][zone])),
        }
    )
    metrics.update(comfort_series_metrics(cols, dt, zone))
    metrics.update(
        {
            "scenario": scenario.name,
            "strategy": strategy,
            "control_period_s": ts,
            "horizon_steps": n_p,
            "seed": int(quality.seed if quality.seed is not None else scenario.seed),
            "preview_quality": quality.describe(),
            "n_control_steps": len(diag_objs),
            "n_fallback_shifted": sum(d.fallback == "shifted_plan" for d in diag_objs),
            "n_fallback_baseline": sum(d.fallback == "baseline" for d in diag_objs),
            "solve_time_median_ms": float(np.median([d.solve_time_ms for d in nd])) if nd else None,
            "solve_time_max_ms": float(np.max([d.solve_time_ms for d in nd])) if nd else None,
        }
    )
    # a run whose controller was mostly in fallback is a failed run (ceco_core.run_status)
    metrics.update(check_control(len(diag_objs), sum(bool(d.fallback) for d in diag_objs)).as_metrics())
    estimates = None
    if vehicle:
        estimates = {c: np.asarray(v) for c, v in est_rows.items()}
        metrics.update(estimation_metrics(estimates))
    return RunResult(
        scenario=scenario.name,
        strategy=strategy,
        timeseries=cols,
        diagnostics=diags,
        diag_objects=diag_objs,
        metrics=metrics,
        step_time_s=np.asarray(step_times, dtype=float),
        estimates=estimates,
    )


ESTIMATOR_CSV_COLUMNS = (
    "t_s",
    "t_int_c",
    "t_int_est_c",
    "t_shell_c",
    "t_shell_est_c",
    "t_glass_c",
    "t_glass_est_c",
    "std_t_int_k",
    "std_t_shell_k",
    "std_t_glass_k",
    "valid",
    "n_missing",
)
"""Columns of ``estimator.csv`` (measurements='vehicle'): per control step the plant truth and the estimate
of the interior, shell and glazing temperatures [degC], their 1-sigma uncertainty [K], the validity flag and
the number of missing inputs."""


def _record_estimate(rows: dict[str, list], est, truth: dict) -> None:
    vals = {
        "t_s": est.t_s,
        "t_int_c": truth["t_int_c"],
        "t_int_est_c": est.t_int_c,
        "t_shell_c": truth["t_shell_c"],
        "t_shell_est_c": est.t_shell_c,
        "t_glass_c": truth["t_glass_c"],
        "t_glass_est_c": est.t_glass_c,
        "std_t_int_k": est.std_k[1],
        "std_t_shell_k": est.std_k[2],
        "std_t_glass_k": est.std_k[3],
        "valid": float(est.valid),
        "n_missing": float(len(est.missing)),
    }
    for c in ESTIMATOR_CSV_COLUMNS:
        rows[c].append(vals[c])


def estimation_metrics(est: dict) -> dict:
    """Estimation errors of a vehicle-mode run.

    RMSE and max |error| of T_int, T_shell and T_glass [K] against the plant truth, over the whole run and from
    :data:`~ceco_controller.estimator.ESTIMATION_SETTLE_S` on (after the key-on transient; None for a shorter
    run), and the number of steps with an invalid estimate.
    """
    out: dict[str, object] = {"measurements": "vehicle"}
    for q in ("t_int", "t_shell", "t_glass"):
        rms, rms_late, max_abs = estimation_errors(est, q)
        out[f"est_{q}_rmse_k"] = rms
        out[f"est_{q}_rmse_late_k"] = None if math.isnan(rms_late) else rms_late
        out[f"est_{q}_max_abs_k"] = max_abs
    out["est_invalid_steps"] = int(np.count_nonzero(est["valid"] == 0))
    return out


def _joined(a) -> str:
    """A predicted trajectory as ``;``-joined numbers (empty if there is none)."""
    if a is None:
        return ""
    a = np.atleast_1d(np.asarray(a, float))
    return ";".join("" if not math.isfinite(v) else f"{v:.6g}" for v in a)


def write_run(result: RunResult, run_dir: str | pathlib.Path) -> pathlib.Path:
    """Write ``timeseries.csv``, ``diagnostics.csv`` and ``metrics.json`` into ``run_dir`` (``ceco_core.rundir``)."""
    d = pathlib.Path(run_dir)
    d.mkdir(parents=True, exist_ok=True)
    rundir.write_csv(d / "timeseries.csv", TIMESERIES_COLUMNS, result.timeseries)
    objs = list(getattr(result, "diag_objects", None) or [])
    if len(objs) != len(result.diagnostics):
        objs = [None] * len(result.diagnostics)
    rows = {c: [r.get(c, "") for r in result.diagnostics] for c in DIAGNOSTICS_COLUMNS}
    rows["pmv_pred"] = [_joined(getattr(o, "pred_pmv", None)) for o in objs]
    rows["t_cab_pred_c"] = [_joined(getattr(o, "pred_t_cab_c", None)) for o in objs]
    st = np.asarray(getattr(result, "step_time_s", ()), dtype=float)
    rows["step_time_ms"] = (
        [1e3 * float(x) for x in st] if st.size == len(result.diagnostics) else [math.nan] * len(result.diagnostics)
    )
    rundir.write_csv(d / "diagnostics.csv", DIAGNOSTICS_CSV_COLUMNS, rows)
    rundir.write_metrics_json(d / "metrics.json", result.metrics)
    estimates = getattr(result, "estimates", None)
    if estimates is not None:
        rundir.write_csv(d / "estimator.csv", ESTIMATOR_CSV_COLUMNS, estimates)
    return d
