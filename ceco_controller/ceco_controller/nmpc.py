"""CECO nonlinear MPC (CasADi): ceco, ceco-e, ceco-c, ceco-ioch, as a receding-horizon controller.

The pieces (docs/controller.md 4):

* :mod:`.nlp_layout`    named slices of the NLP's parameter, variable and constraint vectors;
* :mod:`.transcription` the NLP (model, cost, constraints) by single or multiple shooting;
* :mod:`.warmstart`     the cold model-rollout guess and the shifted warm start;
* :mod:`.solvers`       the solvers built once per NLP, each returning a :class:`SolveResult`;
* :mod:`.offset_free`   the bias estimates;
* this module           the control step and its fallback chain.

Solvers (``SolverSettings.name``): warm ``sqpmethod`` (default: exact Hessian, eigen-clip, dense
qpOASES) or fatrop, with IPOPT doing the cold solves and retrying at once any warm solve they
fail (``n_ipopt_fallbacks``); or warm IPOPT.

Fallbacks: a failed or invalid solve applies the previous plan shifted by one step; with no plan
left, or no usable measurement, the production ACC law (run alongside so its integrator is warm)
is applied. Every command is validated against the hard actuator bounds before it is returned.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ceco_core.acc_law import AccLaw, AccSettings
from ceco_core.comfort import ComfortParams
from ceco_core.contracts import ACTUATOR_LIMITS, AcInput, Diagnostics, Observation

from . import model as cm
from .codegen import codegen_cache_dir, compile_nlp
from .offset_free import BiasEstimator
from .solvers import NlpData, NlpSolver, SolveResult, build_solver
from .strategies import SolverSettings, StrategySettings, resolve_auto, strategy_settings
from .transcription import Evaluation, NlpProblem, build_problem
from .warmstart import initial_guess

__all__ = ["NmpcController", "NlpData", "SolveResult", "codegen_cache_dir", "compile_nlp", "fill_previews"]

_BOUND_TOL = 1e-6
"""Numerical tolerance on the solver's actuator bounds [same unit]: within it a
command is clipped to the bound; beyond it the solve counts as failed."""


@dataclasses.dataclass
class ColdPath:
    """Cold solves of a single-shooting controller.

    IPOPT on the multiple-shooting NLP of the same problem, its solution mapped back (state
    variables and gap rows dropped).
    """

    problem: NlpProblem
    """The multiple-shooting problem."""
    solver: NlpSolver
    """Cold IPOPT on it."""
    w_map: np.ndarray
    """Indices of the single-shooting variables in the multiple-shooting vector."""
    g_map: np.ndarray
    """Indices of the single-shooting constraint rows in the multiple-shooting vector."""

    @property
    def transcription(self) -> str:
        """'multiple-shooting'."""
        return self.problem.transcription


def fill_previews(obs: Observation, n1: int, use_speed_preview: bool) -> tuple[dict, int]:
    """Exogenous series on the N + 1 grid and the number of leading trusted preview points.

    The previews' leading trusted run, the last trusted value held beyond it, the measured
    current value where nothing is trusted. Returns ``(series, trusted)`` with series ``t_amb``
    [degC], ``solar`` [W/m2] (>= 0), ``speed`` [m/s] (>= 0).
    """
    if obs.n_preview != n1:
        raise ValueError(f"Observation previews have {obs.n_preview} points; this controller needs Np+1 = {n1}")
    series = {"t_amb": (obs.preview_t_amb_c, obs.t_amb_c), "solar": (obs.preview_solar_wm2, obs.solar_wm2),
              "speed": (obs.preview_speed_mps, obs.speed_mps)}
    ok = np.asarray(obs.preview_valid, bool).copy()
    for arr, _ in series.values():
        ok &= np.isfinite(arr)
    trusted = int(np.argmin(ok)) if not ok.all() else n1
    out = {}
    for key, (arr, now) in series.items():
        a = np.empty(n1)
        if trusted > 0:
            a[:trusted] = arr[:trusted]
            a[trusted:] = arr[trusted - 1]
        else:
            a[:] = now
        out[key] = a
    if not use_speed_preview:
        out["speed"] = np.full(n1, float(obs.speed_mps))
    out["speed"] = np.maximum(out["speed"], 0.0)
    out["solar"] = np.maximum(out["solar"], 0.0)
    return out, trusted


def _note(diag: Diagnostics, text: str) -> None:
    diag.message = (diag.message + "; " if diag.message else "") + text


class NmpcController:
    """One CECO strategy as a receding-horizon controller.

    Args:
        strategy: a name (``ceco``, ``ceco-e``, ``ceco-c``, ``ceco-ioch``) or
            a :class:`StrategySettings`.
        model_params: identified :class:`ControlModelParams` (default: the file).
        comfort_params: :class:`ComfortParams` (met/clo of the occupant inside).
        acc_settings: settings of the fallback ACC law.
    """

    def __init__(self, strategy: str | StrategySettings = "ceco",
                 model_params: cm.ControlModelParams | None = None,
                 comfort_params: ComfortParams | None = None,
                 acc_settings: AccSettings | None = None):
        settings = strategy_settings(strategy) if isinstance(strategy, str) else strategy
        settings.validate()
        self.settings = resolve_auto(settings)
        """The settings with the solver's 'auto' choices resolved (concrete name and transcription)."""
        self.model_params = model_params if model_params is not None else cm.load_params()
        self.model_params.validate()
        self.comfort_params = comfort_params if comfort_params is not None else ComfortParams()
        self.comfort_params.validate()
        # the NLP's PMV: the same function as the plant's, with settings.pmv_newton_steps on T_cl
        self._nlp_comfort_params = dataclasses.replace(
            self.comfort_params, smoothing=dataclasses.replace(self.comfort_params.smoothing,
                                                               newton_steps=self.settings.pmv_newton_steps))
        self.n_sub = cm.substeps(self.model_params, self.settings.control_period_s)
        self.transcription = self.settings.solver.transcription
        """The NLP transcription built: 'single-shooting' or 'multiple-shooting'."""
        self.lim = ACTUATOR_LIMITS
        self._acc = AccLaw(acc_settings)
        self.problem = build_problem(self.settings, self.model_params, self._nlp_comfort_params,
                                     self.transcription, self.lim)
        """The transcribed NLP."""
        self._bias = BiasEstimator(self.model_params, self.settings.bias_filter, self.settings.bias_limit_k,
                                   self.n_sub, enabled=self.settings.offset_free)
        self._build_solvers()
        self.reset()

    # ------------------------------------------------------------------ build
    def _build_solvers(self) -> None:
        ss = self.settings.solver
        self.solver = self.make_solver(ss)
        """The warm solver."""
        self.n_ipopt_fallbacks = 0
        """Warm sqpmethod/fatrop solves that failed and were retried with warm IPOPT (since construction)."""
        self.solver_fallback: NlpSolver | None = None
        """The warm IPOPT that retries a failed sqpmethod/fatrop solve (None: no retry)."""
        if ss.name != "ipopt" and ss.ipopt_fallback:
            # the default IPOPT path, same codegen: retries failed warm solves and does the cold ones
            ss = dataclasses.replace(ss, name="ipopt")
            self.solver_fallback = self.make_solver(ss)
        # cold solves (first step, after a failure): robust IPOPT settings, no warm start, on the
        # multiple-shooting NLP: from a cold guess single shooting is more nonlinear and IPOPT can stop
        # in a worse local optimum (sc03_mild k = 0: 2.3 % higher cost); its solution is mapped back
        self.cold_path: ColdPath | None = None
        """Single shooting: the multiple-shooting companion of the cold solves (None: cold solves on this NLP)."""
        if self.transcription == "single-shooting":
            cold_ss = dataclasses.replace(ss, name="ipopt", transcription="multiple-shooting", warm_start=False)
            ms = build_problem(dataclasses.replace(self.settings, solver=cold_ss), self.model_params,
                               self._nlp_comfort_params, "multiple-shooting", self.lim)
            w_map = np.setdiff1d(np.arange(ms.nw), ms.vars.indices("x"))
            g_map = np.setdiff1d(np.arange(ms.ng), ms.rows.indices("gap"))
            assert w_map.size == self.problem.nw and g_map.size == self.problem.ng
            self.cold_path = ColdPath(ms, build_solver(ms, cold_ss), w_map, g_map)
            self.solver_cold = self.cold_path.solver
        else:
            self.solver_cold = (self.make_solver(dataclasses.replace(ss, warm_start=False))
                                if ss.warm_start and ss.name == "ipopt" else self.solver)
        """The cold solver (IPOPT): on the multiple-shooting NLP when this controller's is single shooting."""

    def make_solver(self, solver_settings: SolverSettings) -> NlpSolver:
        """Build a solver for this controller's NLP with the given solver settings."""
        return build_solver(self.problem, solver_settings)

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the previous plan, the warm start and the bias estimates."""
        self._plan_u: np.ndarray | None = None  # (N, 2) of the last successful solve
        self._plan_age = 0
        self._warm: tuple | None = None  # (w, lam_x, lam_g)
        self._bias.reset()
        self._acc.reset()

    @property
    def horizon_steps(self) -> int:
        """Np [steps]."""
        return self.settings.horizon_steps

    # ------------------------------------------------------------ NLP access
    def parameters(self, obs: Observation, ex: dict) -> np.ndarray:
        """The NLP parameter vector for an observation (previews already filled)."""
        b = self._bias.values
        return self.problem.params.pack(
            x0=[obs.t_cab_c, obs.t_evap_c], t_int=obs.t_int_c, t_shell=obs.t_shell_c, d_cab=b[0], d_evap=b[1],
            d_ain=b[2], u_prev=[obs.mdot_bl_prev_kgps, obs.t_evap_sp_prev_c], t_amb=ex["t_amb"],
            solar=ex["solar"], speed=ex["speed"], pmv_lb=obs.pmv_lb, pmv_ub=obs.pmv_ub)

    def initial_guess(self, p: np.ndarray, w_prev: np.ndarray | None = None) -> np.ndarray:
        """Primal guess at ``p`` (:func:`ceco_controller.warmstart.initial_guess`)."""
        return initial_guess(self.problem, p, w_prev)

    def evaluate(self, w: np.ndarray, p: np.ndarray) -> Evaluation:
        """Cost terms and predicted trajectories of a primal point."""
        return self.problem.evaluate(w, p)

    def solve_nlp(self, data: NlpData, solver: NlpSolver | None = None) -> SolveResult:
        """Solve one NLP instance of this controller's NLP (default: the warm solver)."""
        return (solver or self.solver).solve(data)

    def last_nlp(self) -> NlpData | None:
        """The data of the last NLP solved by :meth:`compute` (for benchmarks)."""
        return getattr(self, "_last_nlp", None)

    # ---------------------------------------------------------------- compute
    def compute(self, obs: Observation):
        """One control step: returns ``(AcInput, Diagnostics)``; never raises on solver trouble."""
        s = self.settings
        diag = Diagnostics(k=obs.k, t_s=obs.t_s)
        acc_cmd = self._acc.step(obs.t_cab_c, s.control_period_s)  # keep the fallback law warm
        if not obs.measurements_finite():
            diag.status = "invalid_measurement"
            diag.success = False
            diag.message = "non-finite measurement: production ACC law applied"
            return self._fallback_baseline(diag, acc_cmd)
        ex, trusted = fill_previews(obs, s.horizon_steps + 1, s.use_speed_preview)
        diag.trusted_horizon = trusted
        if trusted < obs.n_preview:
            diag.message = (f"preview valid for {trusted}/{obs.n_preview} points; "
                            + ("held last valid value" if trusted else "held measured values"))
        self._bias.update(obs.t_cab_c, obs.t_evap_c, obs.t_vent_c, obs.mdot_bl_prev_kgps)
        p = self.parameters(obs, ex)
        prob = self.problem
        if s.solver.warm_start and self._warm is not None and not s.solver.default_options:
            data = NlpData(p=p, x0=self.initial_guess(p, self._warm[0]), lam_x0=prob.vars.shift(self._warm[1]),
                           lam_g0=prob.rows.shift(self._warm[2]))
        else:
            data = NlpData(p=p, x0=self.initial_guess(p))
        self._last_nlp = data
        warm = data.lam_g0 is not None
        res = self.solver.solve(data) if warm else self._cold_solve(data)
        if not res.success and self.solver_fallback is not None and warm:
            # sqpmethod/fatrop failed: the same instance with the warm IPOPT solver
            self.n_ipopt_fallbacks += 1
            first = res
            res = self.solver_fallback.solve(data)
            res.status = f"{s.solver.name}: {first.status}; ipopt: {res.status}"
            if first.time_ms is not None and res.time_ms is not None:
                res.time_ms += first.time_ms
            _note(diag, f"{s.solver.name} failed ({first.status}): retried with IPOPT")
        diag.status = res.status
        diag.success = res.success
        diag.iterations = res.iterations
        diag.solve_time_ms = res.time_ms
        cmd = None
        if res.success and res.finite():
            u = prob.plan(res.w)
            if self._valid_command(u[0]):
                cmd = u[0]
                self._plan_u, self._plan_age = u, 0
                self._warm = (res.w, res.lam_x, res.lam_g)
                ev = prob.evaluate(res.w, p)
                diag.cost_energy, diag.cost_comfort, diag.cost_ioch = ev.J_e, ev.J_c, ev.J_i
                diag.cost_slack, diag.cost_total = ev.J_s, res.f
                diag.pred_pmv, diag.pred_t_cab_c = ev.pmv, ev.t_cab
                if s.ioch:
                    diag.eps = res.w[prob.vars.indices("eps")]
            else:
                _note(diag, "solution outside actuator bounds")
        if cmd is None:
            self._warm = None
            if self._plan_u is not None and self._plan_age + 1 < len(self._plan_u):
                self._plan_age += 1
                cmd = self._plan_u[self._plan_age]
                diag.fallback = "shifted_plan"
                _note(diag, f"solve failed ({diag.status}): plan of step k-{self._plan_age} applied")
            else:
                _note(diag, f"solve failed ({diag.status}), no plan left: production ACC law applied")
                return self._fallback_baseline(diag, acc_cmd, obs, ex)
        cmd = self._clip_checked(cmd)
        self._predict(obs, cmd, ex)
        diag.mdot_bl_kgps, diag.t_evap_sp_c = float(cmd[0]), float(cmd[1])
        return AcInput(mdot_bl_kgps=float(cmd[0]), t_evap_sp_c=float(cmd[1])), diag

    def _predict(self, obs: Observation, cmd, ex: dict) -> None:
        self._bias.predict(obs.t_cab_c, obs.t_evap_c, cmd[0], cmd[1], obs.t_int_c, obs.t_shell_c,
                           ex["t_amb"][0], ex["speed"][0])

    def _cold_solve(self, data: NlpData) -> SolveResult:
        """A cold solve of ``data`` (this controller's NLP) by ``solver_cold``.

        On the multiple-shooting NLP when this one is single shooting (guess: its model rollout;
        solution mapped back).
        """
        cold = self.cold_path
        if cold is None:
            return self.solver_cold.solve(data)
        res = self.solver_cold.solve(NlpData(p=data.p, x0=initial_guess(cold.problem, data.p)))
        if res.w is not None:
            res.w = res.w[cold.w_map]
            res.lam_x = res.lam_x[cold.w_map]
            res.lam_g = res.lam_g[cold.g_map]
        return res

    def _valid_command(self, u) -> bool:
        lim = self.lim
        return bool(np.all(np.isfinite(u))
                    and lim.mdot_bl_min_kgps - _BOUND_TOL <= u[0] <= lim.mdot_bl_max_kgps + _BOUND_TOL
                    and lim.t_evap_sp_min_c - _BOUND_TOL <= u[1] <= lim.t_evap_sp_max_c + _BOUND_TOL)

    def _clip_checked(self, u) -> np.ndarray:
        if not self._valid_command(u):
            raise AssertionError(f"internal error: command {u} outside the actuator bounds")
        lim = self.lim
        return np.array([min(max(u[0], lim.mdot_bl_min_kgps), lim.mdot_bl_max_kgps),
                         min(max(u[1], lim.t_evap_sp_min_c), lim.t_evap_sp_max_c)])

    def _fallback_baseline(self, diag: Diagnostics, acc_cmd, obs: Observation | None = None,
                           ex: dict | None = None):
        diag.fallback = "baseline"
        self._plan_u = None
        self._warm = None
        u = self._clip_checked(np.array([acc_cmd.mdot_bl_kgps, acc_cmd.t_evap_sp_c]))
        if obs is not None and ex is not None:
            self._predict(obs, u, ex)
        else:
            self._bias.forget_prediction()
        diag.mdot_bl_kgps, diag.t_evap_sp_c = float(u[0]), float(u[1])
        return AcInput(mdot_bl_kgps=float(u[0]), t_evap_sp_c=float(u[1])), diag
