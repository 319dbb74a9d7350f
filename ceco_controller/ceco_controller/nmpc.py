"""CECO nonlinear MPC (CasADi): ceco, ceco-e, ceco-c, ceco-ioch, ceco-pmv, as a receding-horizon controller.

The pieces (docs/controller.md 4):

* :mod:`.nlp_layout`    named slices of the NLP's parameter, variable and constraint vectors;
* :mod:`.transcription` the NLP (model, cost, constraints) by single or multiple shooting;
* :mod:`.warmstart`     the cold model-rollout guess and the shifted warm start;
* :mod:`.sqp`           ceco's dense SQP (exact eigenvalue convexification, real-time iteration);
* :mod:`.solvers`       the solvers built once per NLP, each returning a :class:`SolveResult`;
* :mod:`.chain`         which solver tries an instance from which start, what is usable, the step counters;
* :mod:`.observation`   the previews on the horizon grid, the nominal observation of warm-up;
* :mod:`.offset_free`   the bias estimates;
* :mod:`.comfort_feedback` ceco-pmv's PMV bias, adaptive back-off and preview shrinkage;
* this module           the control step: checks, fallbacks, hand-over, deadline.

One control step (:meth:`NmpcController.compute`), bounded by the wall-clock budget
``SolverSettings.step_budget_s`` counted from ``t_start``:

1. every :class:`Observation` field is checked (:func:`ceco_core.observation_check.check_observation`);
   an implausible measurement or comfort zone hands this step to the ACC law; an implausible
   previous command is replaced by the command this controller applied; implausible preview
   entries count as not valid;
2. bias estimates updated, parameters built, the solve chain run (:class:`~.chain.SolveChain`);
3. a usable result is applied; otherwise the last good plan shifted by the steps since it was
   computed (``fallback='shifted_plan'``) while it lasts, then the production ACC law
   (``fallback='baseline'``). While the NMPC is in charge the law tracks the applied command, so
   it takes over without a bump (:meth:`ceco_core.acc_law.AccLaw.track`).

Every command is validated against the hard actuator bounds before it is returned.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable

import numpy as np

from ceco_core import psychro
from ceco_core.acc_law import AccLaw, AccSettings
from ceco_core.air_quality import RECIRC_SHARE_DEFAULT, fog_margin_of
from ceco_core.cabin_comfort import PAPER_PA_PA, ComfortParams, cabin_mrt_c, cabin_w_rad_wm2
from ceco_core.co2_door import Co2DoorLaw
from ceco_core.contracts import ACTUATOR_LIMITS, AcInput, Diagnostics, Observation
from ceco_core.observation_check import OBSERVATION_LIMITS, ObservationLimits, check_observation

from . import model as cm
from .chain import BOUND_TOL, ChainOutcome, ColdPath, GoodSolution, SolveChain, StepCounters
from .codegen import codegen_cache_dir, compile_nlp
from .comfort_feedback import PmvFeedback, PreviewSkill, held, measured_pmv, pmv_solar_sensitivity
from .observation import fill_previews, nominal_observation
from .offset_free import BiasEstimator
from .pmv_function import CabinPmvFunction
from .solvers import NlpData, NlpSolver, SolveResult, build_solver
from .strategies import SolverSettings, StrategySettings, resolve_auto, strategy_settings
from .transcription import W_SCALE_KGKG, Evaluation, build_problem
from .warmstart import initial_guess

__all__ = [
    "NmpcController",
    "StepCounters",
    "NlpData",
    "SolveResult",
    "codegen_cache_dir",
    "compile_nlp",
    "fill_previews",
    "nominal_observation",
]


FOG_ROW_OFF_K = -100.0
"""The door NLP's fog bound when the margin is not measured [K]: a bound no margin reaches (the row inactive)."""


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
        observation_limits: plausibility ranges of the observation's fields.
        clock: monotonic clock [s] of the step deadline (``time.perf_counter``; tests inject one).
    """

    def __init__(
        self,
        strategy: str | StrategySettings = "ceco",
        model_params: cm.ControlModelParams | None = None,
        comfort_params: ComfortParams | None = None,
        acc_settings: AccSettings | None = None,
        observation_limits: ObservationLimits = OBSERVATION_LIMITS,
        clock: Callable[[], float] = time.perf_counter,
    ):
        settings = strategy_settings(strategy) if isinstance(strategy, str) else strategy
        settings.validate()
        self.settings = resolve_auto(settings)
        """The settings with the solver's 'auto' choices resolved (concrete name and transcription)."""
        self.model_params = model_params if model_params is not None else cm.load_params()
        self.model_params.validate()
        self.comfort_params = comfort_params if comfort_params is not None else ComfortParams()
        self.comfort_params.validate()
        observation_limits.validate()
        self.observation_limits = observation_limits
        self.clock = clock
        """The clock of ``compute``'s ``t_start`` and of every deadline [s]."""
        # the NLP's PMV: the same function as the plant's, with settings.pmv_newton_steps on T_cl
        self._nlp_comfort_params = dataclasses.replace(
            self.comfort_params,
            smoothing=dataclasses.replace(self.comfort_params.smoothing, newton_steps=self.settings.pmv_newton_steps),
        )
        self.n_sub = cm.substeps(self.model_params, self.settings.control_period_s)
        self.transcription = self.settings.solver.transcription
        """The NLP transcription built: 'single-shooting' or 'multiple-shooting'."""
        self.lim = ACTUATOR_LIMITS
        self._acc = AccLaw(acc_settings)
        self.door = (
            Co2DoorLaw(model=cm.co2_estimator_params(self.model_params))
            if self.settings.door_control in ("co2_hold", "nlp")
            else None
        )
        """The door's CO2 estimate, safe defaults and hold rule (``door_control`` 'co2_hold': the door beside the NLP;
        'nlp': the NLP's door, this law's safe defaults over it and its rule when there is no plan), else None: the
        door is not commanded."""
        self.co2_sensor_fitted = True
        """Whether the car has a cabin CO2 sensor (a NaN reading is then a fault: fresh air); set by the factory."""
        t0 = time.perf_counter()
        self.problem = build_problem(
            self.settings, self.model_params, self._nlp_comfort_params, self.transcription, self.lim
        )
        """The transcribed NLP."""
        self._bias = BiasEstimator(
            self.model_params,
            self.settings.bias_filter,
            self.settings.bias_limit_k,
            self.n_sub,
            enabled=self.settings.offset_free,
        )
        s = self.settings
        self._pmv_fb = (
            PmvFeedback(
                s.pmv_bias_filter,
                s.pmv_bias_limit,
                s.backoff_quantile,
                s.backoff_window_steps,
                s.backoff_min_samples,
                s.backoff_init_pmv,
                s.backoff_min_pmv,
                s.backoff_max_pmv,
                s.backoff_forecast_z,
            )
            if s.pmv_feedback
            else None
        )
        self._pmv_fn = CabinPmvFunction(self.comfort_params) if s.pmv_feedback else None
        """The scored PMV at ``comfort_params``, compiled (the PMV feedback's per-step reads)."""
        self._skill = (
            PreviewSkill(s.horizon_steps + 1, s.preview_skill_window_steps, s.preview_shrink_c)
            if s.preview_rule == "shrink"
            else None
        )
        self.chain = self._build_chain()
        """The solve chain (warm solver, IPOPT retry, cold path)."""
        self.build_time_s = time.perf_counter() - t0
        """Wall time of building the NLP and its solvers [s] (compilation included when codegen compiles)."""
        self.n_ipopt_fallbacks = 0
        """Warm SQP/fatrop solves that failed and were retried with warm IPOPT (since construction)."""
        self.warm_up_problem: str | None = None
        """Why :meth:`warm_up`'s nominal solve was not usable (None: it was, or no warm-up ran)."""
        self._reset_state()

    # ------------------------------------------------------------------ build
    def _build_chain(self) -> SolveChain:
        ss = self.settings.solver
        solver = self.make_solver(ss)
        retry = None
        if ss.name != "ipopt" and ss.ipopt_fallback:
            # the default IPOPT path, same codegen: retries failed warm solves and does the cold ones
            ss = dataclasses.replace(ss, name="ipopt", rti=False)
            retry = self.make_solver(ss)
        # cold solves: robust IPOPT settings, no warm start, on the multiple-shooting NLP: from a cold
        # guess single shooting is more nonlinear and IPOPT can stop in a worse local optimum
        # (sc03_mild k = 0: 2.3 % higher cost); its solution is mapped back
        cold_path = None
        if self.transcription == "single-shooting":
            cold_ss = dataclasses.replace(
                ss, name="ipopt", rti=False, transcription="multiple-shooting", warm_start=False
            )
            ms = build_problem(
                dataclasses.replace(self.settings, solver=cold_ss),
                self.model_params,
                self._nlp_comfort_params,
                "multiple-shooting",
                self.lim,
            )
            w_map = np.setdiff1d(np.arange(ms.nw), ms.vars.indices("x"))
            g_map = np.setdiff1d(np.arange(ms.ng), ms.rows.indices("gap"))
            assert w_map.size == self.problem.nw and g_map.size == self.problem.ng
            cold_path = ColdPath(ms, build_solver(ms, cold_ss, self.clock), w_map, g_map)
            cold = cold_path.solver
        else:
            cold = (
                self.make_solver(dataclasses.replace(ss, warm_start=False))
                if ss.warm_start and ss.name == "ipopt"
                else solver
            )
        s = self.settings.solver
        return SolveChain(
            self.problem,
            solver,
            retry,
            cold,
            cold_path,
            self.lim,
            s.accept_violation,
            s.warm_start and not s.default_options,
            self.clock,
        )

    def make_solver(self, solver_settings: SolverSettings) -> NlpSolver:
        """Build a solver for this controller's NLP with the given solver settings."""
        return build_solver(self.problem, solver_settings, self.clock)

    @property
    def solver(self) -> NlpSolver:
        """The warm solver."""
        return self.chain.solver

    @solver.setter
    def solver(self, value: NlpSolver) -> None:
        self.chain.solver = value

    @property
    def solver_fallback(self) -> NlpSolver | None:
        """The warm IPOPT that retries a failed SQP/fatrop solve (None: no retry)."""
        return self.chain.retry

    @solver_fallback.setter
    def solver_fallback(self, value: NlpSolver | None) -> None:
        self.chain.retry = value

    @property
    def solver_cold(self) -> NlpSolver:
        """The cold solver (IPOPT): on the multiple-shooting NLP when this controller's is single shooting."""
        return self.chain.cold

    @solver_cold.setter
    def solver_cold(self, value: NlpSolver) -> None:
        self.chain.cold = value

    @property
    def cold_path(self) -> ColdPath | None:
        """Single shooting: the multiple-shooting companion of the cold solves (None: cold solves on this NLP)."""
        return self.chain.cold_path

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Back to the key-on state: no plan, no warm start, no bias estimates, the ACC law reset.

        The solvers forget their history too (:meth:`SolveChain.reset`): the next steps compute what
        a freshly built controller's would, bit for bit.
        """
        self.chain.reset()
        self._reset_state()

    def _reset_state(self) -> None:
        if self.door is not None:
            self.door.reset()
        self._door_nlp: dict | None = None
        self._door_planned: float | None = None
        self._door_pred_max: float = math.nan
        self._door_fog_min: float = math.nan
        self._door_last: float | None = None
        self._good: GoodSolution | None = None
        self._prepared_t_s: float | None = None
        self._last_cmd: np.ndarray | None = None
        self._pending: tuple | None = None
        """The last step's (observation, previews, command) whose predictions :meth:`settle` has not made yet."""
        self._bias.reset()
        if self._pmv_fb is not None:
            self._pmv_fb.reset()
        if self._skill is not None:
            self._skill.reset()
        self._comfort_now: np.ndarray | None = None
        self._acc.reset()
        self._acc_to_track: tuple | None = None
        self.counters = StepCounters()
        """What the steps did since construction or the last reset."""

    @property
    def horizon_steps(self) -> int:
        """Np [steps]: the preview horizon (the NLP predicts ``settings.nlp_steps``)."""
        return self.settings.horizon_steps

    @property
    def pmv_feedback(self) -> PmvFeedback | None:
        """ceco-pmv's PMV bias and back-off (None when ``settings.pmv_feedback`` is off)."""
        return self._pmv_fb

    @property
    def preview_skill(self) -> PreviewSkill | None:
        """ceco-pmv's measured forecast errors and preview shrinkage (None unless ``preview_rule`` 'shrink')."""
        return self._skill

    # ------------------------------------------------------------ NLP access
    def previews(self, obs: Observation, valid: np.ndarray | None = None) -> tuple[dict, int]:
        """The exogenous series on the NLP grid and the trusted preview points.

        :func:`~ceco_controller.observation.fill_previews` on the preview horizon, held at the last
        value over the extension (``settings.horizon_extension_steps``).
        """
        ex, trusted = fill_previews(obs, self.horizon_steps + 1, self.settings.use_speed_preview, valid)
        n = self.problem.params.n_grid
        return {k: held(v, n) for k, v in ex.items()}, trusted

    def parameters(
        self,
        obs: Observation,
        ex: dict,
        u_prev=None,
        t_glass_c: float | None = None,
        rh_cab: float | None = None,
        bounds: tuple | None = None,
        comfort: np.ndarray | None = None,
    ) -> np.ndarray:
        """The NLP parameter vector for an observation (previews filled, on the NLP grid).

        ``u_prev`` overrides the observation's previous command; ``t_glass_c`` and ``rh_cab`` its
        glazing temperature and cabin RH (the checked values: NaN where not measured or implausible);
        ``bounds`` (lb, ub) on the NLP grid the comfort bounds (default: the observation's, held over
        the extension); ``comfort`` :meth:`comfort_parameters` of the same observation, glazing and RH when the
        caller has them (default: computed here).
        """
        b = self._bias.values
        u_prev = (obs.mdot_bl_prev_kgps, obs.t_evap_sp_prev_c) if u_prev is None else u_prev
        t_mr, pa = self.comfort_parameters(obs, t_glass_c, rh_cab) if comfort is None else comfort
        n = self.problem.params.n_grid
        lb, ub = (held(obs.pmv_lb, n), held(obs.pmv_ub, n)) if bounds is None else bounds
        door: dict = {}
        if self.problem.door:  # the door NLP: the previous share, the CO2 and the moisture/fog parameters
            door = self._door_nlp if self._door_nlp is not None else self._door_nominal(obs)
            door = {**door, **self._fog_parameters(obs, float(ex["t_amb"][0]), t_glass_c, rh_cab)}
            if len(u_prev) == 2:
                u_prev = (*u_prev, self._door_share_prev(obs))
        return self.problem.params.pack(
            **door,
            x0=[obs.t_cab_c, obs.t_evap_c],
            t_int=obs.t_int_c,
            t_shell=obs.t_shell_c,
            d_cab=b[0],
            d_evap=b[1],
            d_ain=b[2],
            u_prev=u_prev,
            t_amb=ex["t_amb"],
            solar=ex["solar"],
            speed=ex["speed"],
            pmv_lb=lb,
            pmv_ub=ub,
            t_mr=t_mr,
            pa=pa,
            recirc=self._door_share_prev(obs, 1.0 - self.model_params.fresh_air_fraction),
        )

    def _fog_parameters(self, obs: Observation, t_amb_c: float, t_glass_c: float | None, rh_cab: float | None) -> dict:
        """The door NLP's moisture and fog parameters (docs/controller.md 4.9).

        The cabin's humidity ratio from the measured temperature and RH, the glass held at its measured
        temperature, the NLP's fog margin bound + ``fog_backoff_k``; the ambient air taken as saturated at the
        ambient temperature (the car measures no ambient humidity here: the wettest outside air, so the predicted
        margin errs low); the occupants' moisture from ``moist_occ_latent_w``. Without a measured margin (no glass
        temperature, no cabin RH, no bound) the fog row is switched off (its bound at :data:`FOG_ROW_OFF_K`), as
        the safe override is.
        """
        mp = self.model_params
        t_cab = float(obs.t_cab_c)
        rh = float(obs.rh_cab if rh_cab is None else rh_cab)
        tg = float(obs.t_glass_c if t_glass_c is None else t_glass_c)
        bound = float(obs.fog_margin_min_k)
        known = all(math.isfinite(v) for v in (t_cab, rh, tg, bound)) and 0.0 <= rh <= 1.0
        n_occ = int(obs.n_occupants) if math.isfinite(obs.n_occupants) else 1
        t_amb = t_amb_c if math.isfinite(t_amb_c) else t_cab
        return {
            "w_0": float(psychro.humidity_ratio(t_cab, rh if known else 0.5)) / W_SCALE_KGKG,
            "w_amb": float(psychro.humidity_ratio(t_amb, 1.0)) / W_SCALE_KGKG,
            "w_gen": n_occ * mp.moist_occ_latent_w / psychro.H_FG_JPKG / W_SCALE_KGKG,
            "t_glass": tg if known else t_cab,
            "fog_min": bound + self.settings.fog_backoff_k if known else FOG_ROW_OFF_K,
        }

    def _door_nominal(self, obs: Observation) -> dict:
        """The door NLP's CO2 parameters before a CO2 estimate exists (warm-up, prepare): the ambient CO2."""
        assert self.door is not None
        n_occ = int(obs.n_occupants) if math.isfinite(obs.n_occupants) else 1
        limit = float(obs.co2_limit_ppm) if math.isfinite(obs.co2_limit_ppm) else 1500.0
        return self.door.nlp_parameters(self.door.model.co2_amb_ppm, limit, n_occ)

    def _door_share_prev(self, obs: Observation, default: float = RECIRC_SHARE_DEFAULT) -> float:
        """The door's recirculated share [-]: the measured door, else the last door command, else ``default``.

        The door NLP's previous share (``default`` the plant's 0.8), and every NLP's power-model door (parameter
        ``recirc``; ``default`` the share of the identification data, 1 - ``fresh_air_fraction``).
        """
        r = float(obs.recirc_share)
        if math.isfinite(r) and 0.0 <= r <= 1.0:
            return r
        return self._door_last if self._door_last is not None else default

    def comfort_parameters(
        self, obs: Observation, t_glass_c: float | None = None, rh_cab: float | None = None
    ) -> np.ndarray:
        """The NLP's comfort scalars [t_mr (degC), p_a (Pa)] held over the horizon.

        t_mr: from the measured glazing, shell and interior temperatures
        (:func:`ceco_core.cabin_comfort.cabin_mrt_c`; T_int alone while the glazing is not
        measured). p_a: ``settings.pmv_pa_source`` ('paper': 1700 Pa; 'measured': RH x p_ws(T_cab),
        1700 Pa while the RH is not measured). ``t_glass_c``/``rh_cab`` default to the observation's.
        """
        t_glass = obs.t_glass_c if t_glass_c is None else t_glass_c
        rh = obs.rh_cab if rh_cab is None else rh_cab
        t_glass = t_glass if math.isfinite(t_glass) else obs.t_int_c
        t_mr = float(
            cabin_mrt_c(
                t_cab_c=obs.t_cab_c,
                t_int_c=obs.t_int_c,
                t_shell_c=obs.t_shell_c,
                t_glass_c=t_glass,
                params=self.comfort_params,
            )
        )
        pa = PAPER_PA_PA
        if self.settings.pmv_pa_source == "measured" and math.isfinite(rh) and 0.0 <= rh <= 1.0:
            pa = float(psychro.vapour_pressure_pa(obs.t_cab_c, rh))
        return np.array([t_mr, pa])

    def initial_guess(self, p: np.ndarray, w_prev: np.ndarray | None = None) -> np.ndarray:
        """Primal guess at ``p`` (:func:`ceco_controller.warmstart.initial_guess`)."""
        return initial_guess(self.problem, p, w_prev)

    def evaluate(self, w: np.ndarray, p: np.ndarray) -> Evaluation:
        """Cost terms and predicted trajectories of a primal point."""
        return self.problem.evaluate(w, p)

    def solve_nlp(self, data: NlpData, solver: NlpSolver | None = None, deadline: float | None = None) -> SolveResult:
        """Solve one NLP instance of this controller's NLP (default: the warm solver)."""
        return (solver or self.solver).solve(data, deadline)

    def last_nlp(self) -> NlpData | None:
        """The data of the last NLP solved by :meth:`compute` (for benchmarks)."""
        return getattr(self, "_last_nlp", None)

    def last_chain(self) -> ChainOutcome | None:
        """What the solve chain did in the last :meth:`compute` that reached it (for benchmarks)."""
        return getattr(self, "_last_chain", None)

    # ------------------------------------------------------------ start-up
    def warm_up(self) -> float:
        """Solve a nominal instance once with every solver of the chain, then forget it (key-on).

        Takes the one-time costs of a first solve (allocations, first factorisations) before the
        controller is in charge; leaves the controller as after :meth:`reset`. Returns the wall
        time [s]; :attr:`warm_up_problem` says why the nominal solve was not usable (None: it was).
        """
        t0 = time.perf_counter()
        obs = nominal_observation(self.horizon_steps + 1)
        ex, _ = self.previews(obs)
        p = self.parameters(obs, ex)
        cold = self.chain._cold_solve(self.chain.cold_data(p), None)
        why = self.chain.why_unusable(cold)
        self.warm_up_problem = None if why is None else f"{cold.solver}: {why} ({cold.status})"
        if why is None:
            good = GoodSolution.of(cold, self.problem)
            data = self.chain.warm_data(p, good)
            if data is not None:
                for solver in (self.solver, self.solver_fallback):
                    if solver is not None:
                        solver.solve(data)
        self.reset()
        return time.perf_counter() - t0

    def prepare(self, obs: Observation) -> SolveResult | None:
        """The first solve, done before the controller takes control (no step deadline).

        Solves the instance of ``obs`` (the bias estimator is not advanced) and keeps a usable
        solution as the warm start of the first :meth:`compute`, shifted by the control steps
        between ``obs.t_s`` and that step's ``t_s``. Returns the result (None if ``obs`` is not
        usable).
        """
        self.settle()
        chk = check_observation(obs, self.observation_limits)
        n1 = self.horizon_steps + 1
        if not chk.measurements_ok or not chk.command_ok or obs.n_preview != n1:
            return None
        bias = copy.deepcopy(self._bias)
        self._bias.update(obs.t_cab_c, obs.t_evap_c, obs.t_vent_c, obs.mdot_bl_prev_kgps)
        ex, _ = self.previews(obs, obs.preview_valid & chk.preview_plausible)
        p = self.parameters(obs, ex, None, chk.t_glass_c, chk.rh_cab)
        self._bias = bias
        out = self.chain.run(p, None, math.inf)
        if out.result is not None:
            self._good = GoodSolution.of(out.result, self.problem, age=-1)
            self._prepared_t_s = float(obs.t_s)
        return out.result

    # ---------------------------------------------------------------- compute
    def compute(self, obs: Observation, t_start: float | None = None):
        """One control step: returns ``(AcInput, Diagnostics)``; never raises on solver trouble or bad input.

        ``t_start``: when the step began on :attr:`clock` (e.g. before the node converted the
        messages; default: now); the step's work after it is bounded by ``step_budget_s``.
        With ``door_control`` 'co2_hold' the door command of :attr:`door` is added to whatever the step
        commands (a fallback's too).
        """
        self.settle()
        if self.settings.door_control == "nlp":
            return self._compute_door_nlp(obs, t_start)
        cmd, diag = self._compute_ac(obs, t_start)
        if self.door is None:
            return cmd, diag
        try:
            door = self.door.step_observation(
                obs,
                dt_s=self.settings.control_period_s,
                mdot_bl_kgps=cmd.mdot_bl_kgps,
                co2_sensor_fitted=self.co2_sensor_fitted,
            )
        except ValueError as exc:  # e.g. time going back: fresh air, the safe default, and said so
            _note(diag, f"door: {exc}; fresh air")
            return dataclasses.replace(cmd, recirc_share=0.0), diag
        _note(diag, f"door={door.recirc_share:.2f} door_mode={door.mode} co2_est={door.co2_estimate_ppm:.0f}")
        return dataclasses.replace(cmd, recirc_share=door.recirc_share), diag

    def _compute_door_nlp(self, obs: Observation, t_start: float | None):
        """One step of ``door_control`` 'nlp' (docs/controller.md 4.9).

        The CO2 estimate and the safe modes first (:meth:`ceco_core.co2_door.Co2DoorLaw.observe`, on the inputs
        held since the last step); the estimate enters the NLP as its initial CO2. The door is the NLP's first
        planned share (or the shifted plan's), overridden by fresh air in a safe mode; without a plan (the ACC
        law) the CO2-holding rule of 'co2_hold' commands it.
        """
        assert self.door is not None
        t0 = self.clock() if t_start is None else float(t_start)
        n_occ = int(obs.n_occupants) if math.isfinite(obs.n_occupants) else 1
        limit = float(obs.co2_limit_ppm)
        try:
            c, safe = self.door.observe(
                t_s=float(obs.t_s),
                co2_sensor_fitted=self.co2_sensor_fitted,
                co2_sensor_ppm=float(obs.co2_sensor_ppm),
                recirc_share=float(obs.recirc_share),
                mdot_bl_prev_kgps=float(obs.mdot_bl_prev_kgps),
                speed_mps=float(obs.speed_mps),
                n_occupants=n_occ,
                fog_margin_k=fog_margin_of(obs.t_cab_c, obs.rh_cab, obs.t_glass_c),
                fog_margin_min_k=float(obs.fog_margin_min_k),
            )
        except ValueError as exc:  # e.g. time going back: fresh air, the safe default, and said so
            c, safe = math.nan, f"door_error ({exc})"
        if not math.isfinite(limit):
            limit, safe = 1500.0, safe or "co2_limit_unknown"
        self._door_nlp = self.door.nlp_parameters(c, limit, n_occ)
        cmd, diag = self._compute_ac(obs, t0)
        if safe is not None:
            r, mode = 0.0, safe
        elif self._door_planned is not None:
            r, mode = min(max(self._door_planned, 0.0), 1.0), "nlp"
        else:
            hold = self.door.hold(
                c,
                dt_s=self.settings.control_period_s,
                co2_limit_ppm=limit,
                mdot_bl_kgps=cmd.mdot_bl_kgps,
                speed_mps=float(obs.speed_mps),
                n_occupants=n_occ,
                t_cab_c=float(obs.t_cab_c),
                t_amb_c=float(obs.t_amb_c),
                rh_cab=float(obs.rh_cab),
                rh_amb=float(obs.rh_amb),
            )
            r, mode = hold.recirc_share, f"rule_{hold.mode}"
        self._door_last = r
        _note(
            diag,
            f"door={r:.2f} door_mode={mode} co2_est={c:.0f} co2_pred_max="
            + ("n/a" if not math.isfinite(self._door_pred_max) else f"{self._door_pred_max:.0f}")
            + " fog_pred_min="
            + ("n/a" if not math.isfinite(self._door_fog_min) else f"{self._door_fog_min:.1f}"),
        )
        return dataclasses.replace(cmd, recirc_share=r), diag

    def _compute_ac(self, obs: Observation, t_start: float | None = None):
        """The blower and evaporator commands of one step (:meth:`compute` without the door).

        With the door NLP the share of the plan applied is left in ``_door_planned`` (None: no plan applied) and
        the plan's largest predicted CO2 in ``_door_pred_max`` [ppm] and its least fog margin in ``_door_fog_min`` [K].
        """
        self._door_planned, self._door_pred_max, self._door_fog_min = None, math.nan, math.nan
        t0 = self.clock() if t_start is None else float(t_start)
        s, ss, cnt = self.settings, self.settings.solver, self.counters
        deadline = t0 + ss.step_budget_s - ss.step_reserve_s
        cnt.steps += 1
        diag = Diagnostics(k=obs.k, t_s=obs.t_s)
        self._age_good(obs)
        n1 = s.horizon_steps + 1
        chk = check_observation(obs, self.observation_limits)
        problems = list(chk.measurement_problems)
        if obs.n_preview != n1:
            problems.append(f"previews have {obs.n_preview} points, this controller needs Np+1 = {n1}")
        u_prev = (obs.mdot_bl_prev_kgps, obs.t_evap_sp_prev_c)
        if not chk.command_ok:
            if self._last_cmd is not None:
                u_prev = (float(self._last_cmd[0]), float(self._last_cmd[1]))
                cnt.substituted_commands += 1
                _note(diag, f"{'; '.join(chk.command_problems)}: the command applied last used instead")
            else:
                problems.extend(chk.command_problems)
        if chk.info_problems:
            _note(diag, "; ".join(chk.info_problems))
        if problems:
            cnt.invalid_observations += 1
            diag.status = "invalid_measurement"
            diag.success = False
            _note(diag, f"{'; '.join(problems)}: production ACC law applied")
            lo, hi = self.observation_limits.temperature_c
            t_cab = float(obs.t_cab_c)
            return self._apply_acc(diag, t_cab if lo <= t_cab <= hi else math.nan, None, None)
        valid = np.asarray(obs.preview_valid, bool) & chk.preview_plausible
        ex, trusted = self.previews(obs, valid)
        diag.trusted_horizon = trusted
        if trusted < n1:
            _note(
                diag,
                f"preview valid for {trusted}/{n1} points; "
                + ("held last valid value" if trusted else "held measured values"),
            )
        self._bias.update(obs.t_cab_c, obs.t_evap_c, obs.t_vent_c, u_prev[0])
        bounds = self._comfort_step(obs, chk, ex, valid, diag)
        # the comfort step's T_mr and p_a are this step's when it returned bounds (read once: 30-60 us)
        comfort = self._comfort_now if bounds is not None else None
        p = self.parameters(obs, ex, u_prev, chk.t_glass_c, chk.rh_cab, bounds, comfort)
        out = self.chain.run(p, self._good, deadline)
        self._last_nlp, self._last_chain = out.data, out
        self._count(out, deadline)
        res = out.result
        diag.status = out.status
        diag.solve_time_ms = out.time_ms
        final = res if res is not None else (out.attempts[-1][1] if out.attempts else None)
        diag.success = bool(final.success) if final is not None else False
        diag.iterations = final.iterations if final is not None else None
        for why in out.rejected:
            _note(diag, f"not used: {why}")
        if res is None and not out.attempts:
            _note(diag, "no time left for a solve")
        if res is not None:
            if not res.success:
                cnt.accepted_iterates += 1
                _note(diag, f"{res.solver} iterate applied at its limit (violation {res.violation:.1e})")
            elif res.status == "RTI_Step":
                cnt.rti_steps += 1
            else:
                cnt.converged += 1
            good = self._good = GoodSolution.of(res, self.problem)
            plan = good.plan
            ev = self.problem.evaluate(good.w, p)
            diag.cost_energy, diag.cost_comfort, diag.cost_ioch = ev.J_e, ev.J_c, ev.J_i
            diag.cost_slack, diag.cost_total = ev.J_s, res.f
            diag.pred_pmv, diag.pred_t_cab_c = ev.pmv + (self._pmv_fb.bias if self._pmv_fb else 0.0), ev.t_cab
            if s.ioch:
                diag.eps = good.w[self.problem.vars.indices("eps")]
            if ev.co2.size:
                self._door_pred_max = float(np.max(ev.co2))
                self._door_fog_min = float(np.min(ev.fog))
            cmd = plan[0]
        elif self._good is not None and 1 <= self._good.age < len(self._good.plan):
            cmd = self._good.plan[self._good.age]
            cnt.shifted_plan += 1
            diag.fallback = "shifted_plan"
            _note(diag, f"solve failed ({diag.status}): plan of step k-{self._good.age} applied")
        else:
            _note(diag, f"solve failed ({diag.status}), no plan left: production ACC law applied")
            return self._apply_acc(diag, float(obs.t_cab_c), obs, ex)
        if self.problem.door:
            self._door_planned = float(cmd[2])
        cmd = self._clip_checked(cmd)
        # the ACC law follows the applied command (bumpless hand-over); only the last one matters, so
        # the tracking is done when the law is next needed (_apply_acc), not at every step
        self._acc_to_track = (cmd[0], cmd[1], obs.t_cab_c)
        return self._finish(diag, cmd, obs, ex)

    # -------------------------------------------------------------- internals
    def _age_good(self, obs: Observation) -> None:
        """One more step since the last good solution (a prepared one: the steps since its t_s)."""
        good = self._good
        if good is None:
            return
        if self._prepared_t_s is not None:
            d = (float(obs.t_s) - self._prepared_t_s) / self.settings.control_period_s
            good.age = int(round(d)) if math.isfinite(d) else -1
            self._prepared_t_s = None
        else:
            good.age += 1
        if not 0 <= good.age < len(good.plan):
            self._good = None

    def _count(self, out, deadline: float) -> None:
        cnt = self.counters
        for role, _ in out.attempts:
            cnt.retries += role == "retry"
            cnt.cold_solves += role.startswith("cold")
            if role == "retry":
                self.n_ipopt_fallbacks += 1
        if any(r.status == "Maximum_Wall_Time_Exceeded" for _, r in out.attempts) or (
            out.result is None and self.clock() >= deadline
        ):
            cnt.deadline_hits += 1

    def _clip_checked(self, u) -> np.ndarray:
        if not self.chain.valid_command(u):
            raise AssertionError(f"internal error: command {u} outside the actuator bounds (tol {BOUND_TOL})")
        return np.array(self.lim.clip(u[0], u[1]))

    def _comfort_step(self, obs: Observation, chk, ex: dict, valid: np.ndarray, diag: Diagnostics):
        """ceco-pmv's comfort output (docs/controller.md 4.7): measured PMV, bias, back-off, shrunk previews.

        Updates ``ex`` in place (preview shrinkage) and returns the comfort bounds (lb, ub) on the NLP
        grid: the upper one capped at ``settings.pmv_ub_cap``, both moved by the PMV bias, the upper one by
        the back-off (None: the observation's bounds).
        """
        fb, skill, cap = self._pmv_fb, self._skill, self.settings.pmv_ub_cap
        if fb is None and skill is None and not math.isfinite(cap):
            return None
        n = self.problem.params.n_grid
        if skill is not None:
            skill.update(obs, valid)
            ex.update(skill.shrink(ex, obs))
        lb, ub = held(obs.pmv_lb, n), np.minimum(held(obs.pmv_ub, n), cap)
        now = self._comfort_now = self.comfort_parameters(obs, chk.t_glass_c, chk.rh_cab)
        if fb is None:
            return lb, ub
        y = measured_pmv(obs, self.comfort_params, chk.t_glass_c, chk.rh_cab, self._pmv_fn, now[0])
        fb.update(y)
        m = np.zeros(n)
        if self.settings.backoff == "adaptive":
            t_mr, pa = now
            v = skill.estimate_mse("solar", n) if skill is not None else np.zeros(n)
            g = pmv_solar_sensitivity(
                obs.t_cab_c,
                obs.t_vent_c,
                obs.mdot_bl_prev_kgps,
                t_mr,
                pa,
                obs.solar_wm2,
                self.comfort_params,
                self._pmv_fn,
            )
            m = fb.backoff(v, g)
        _note(
            diag,
            f"comfort: PMV {'n/a' if not math.isfinite(y) else f'{y:+.3f}'}, bias {fb.bias:+.3f}, "
            f"back-off {m[1] if n > 1 else m[0]:.3f}",
        )
        return lb - fb.bias, ub - fb.bias - m

    def settle(self) -> None:
        """The last step's work that only the next step needs, done after its command.

        The model's one-period predictions of the cabin and evaporator temperatures (offset-free bias) and of the
        PMV (ceco-pmv's PMV feedback), from the step's observation, previews and command. :meth:`compute` returns
        without them and a node calls this once the command is out (the control step, message in to command out,
        is shorter by one or two model steps); :meth:`compute` and :meth:`prepare` do it first if it is still
        pending, so the numbers are the same whoever calls it.
        """
        pending, self._pending = self._pending, None
        if pending is None:
            return
        obs, ex, cmd = pending
        self._bias.predict(
            obs.t_cab_c, obs.t_evap_c, cmd[0], cmd[1], obs.t_int_c, obs.t_shell_c, ex["t_amb"][0], ex["speed"][0]
        )
        if self._pmv_fb is not None:
            self._pmv_fb.remember(self._predict_pmv(obs, ex, cmd))

    def _predict_pmv(self, obs: Observation, ex: dict, cmd: np.ndarray) -> float:
        """y0(k+1|k): the model's PMV one control step ahead with ``cmd`` held, without the PMV bias [-]."""
        mp, b, n_sub = self.model_params, self._bias.values, self.n_sub
        t_cab, t_evap, *_ = cm.step(
            mp,
            obs.t_cab_c,
            obs.t_evap_c,
            cmd[0],
            cmd[1],
            obs.t_int_c,
            obs.t_shell_c,
            ex["t_amb"][0],
            ex["speed"][0],
            n_sub=n_sub,
            d_cab_k=b[0] / n_sub,
            d_ain_k=b[2],
            d_evap_k=b[1] / n_sub,
        )
        t_mr, pa = self._comfort_now if self._comfort_now is not None else (math.nan, math.nan)
        assert self._pmv_fn is not None  # (only with the PMV feedback)
        return self._pmv_fn(
            float(t_cab),
            float(cm.t_ain_c(mp, t_evap, cmd[0], b[2])),
            float(cmd[0]),
            float(t_mr),
            float(cabin_w_rad_wm2(ex["solar"][1 if ex["solar"].size > 1 else 0], self.comfort_params)),
            float(pa),
        )

    def _finish(self, diag: Diagnostics, cmd: np.ndarray, obs: Observation | None, ex: dict | None):
        if obs is not None and ex is not None:
            self._pending = (obs, ex, cmd)  # the predictions for the next step: :meth:`settle`
        else:
            self._pending = None
            self._bias.forget_prediction()
            if self._pmv_fb is not None:
                self._pmv_fb.forget()
        self._last_cmd = cmd
        diag.mdot_bl_kgps, diag.t_evap_sp_c = float(cmd[0]), float(cmd[1])
        return AcInput(mdot_bl_kgps=float(cmd[0]), t_evap_sp_c=float(cmd[1])), diag

    def _apply_acc(self, diag: Diagnostics, t_cab_c: float, obs: Observation | None, ex: dict | None):
        self.counters.acc_law += 1
        diag.fallback = "baseline"
        if self._acc_to_track is not None:
            self._acc.track(*self._acc_to_track)
            self._acc_to_track = None
        acc = self._acc.step(t_cab_c, self.settings.control_period_s)
        return self._finish(diag, self._clip_checked(np.array([acc.mdot_bl_kgps, acc.t_evap_sp_c])), obs, ex)
