"""Settings of every control strategy (frozen dataclasses) and their defaults.

Strategies (Wang et al., DSCC 2019, Sec. 3; docs/controller.md writes every
NLP out):

* ``baseline``  production automatic climate control (PI + anti-windup on
  T_cab vs 26 degC), :mod:`ceco_core.acc_law`.
* ``ceco``      the general CECO problem: least A/C energy subject to the model,
  the PMV comfort zone, T_evap and actuator bounds. It is the paper's
  eq. (11) *made robust*: the upper PMV bound is backed off by
  ``pmv_margin`` (0.1 PMV) so model mismatch does not push the plant out of
  the zone (the paper observed exactly that for CECO-E).
* ``ceco-e``    energy priority, eq. (12) with gamma = 0: the same problem
  without back-off; it rides the upper bound.
* ``ceco-c``    comfort priority, eq. (12) with a large gamma (see
  ``COMFORT_GAMMA_W`` for its scaling).
* ``ceco-ioch`` eq. (13): slack eps in [0, eps_UB] tightening the upper bound,
  cost beta (eta_AC(V) - 1)/(eps + xi); uses the vehicle-speed preview.
* ``ceco-pmv``  issue 20's strategy (not the paper's): the least energy that holds the comfort
  output, the scored PMV at the occupant, close under its bound without crossing it: the measured
  cabin humidity in the PMV, offset-free feedback on the PMV itself, a back-off that adapts to the
  measured one-step PMV prediction errors and the measured forecast errors, previews shrunk
  toward persistence where they only add noise, and a 60-s prediction (the V2X horizon extended
  by holding its last values). Its pieces:
  :mod:`ceco_controller.comfort_feedback`; docs/controller.md 4.7.

All CECO strategies share the exact-penalty softening of the comfort and
T_evap bounds, the offset-free bias correction and the solver settings.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from ceco_core.contracts import CECO_STRATEGIES, NODE_STRATEGIES, STRATEGIES, strategy_variant

__all__ = [
    "StrategySettings",
    "SolverSettings",
    "SOLVER_NAMES",
    "STRATEGIES",
    "CECO_STRATEGIES",
    "NODE_STRATEGIES",
    "DOOR_CONTROLS",
    "strategy_settings",
    "resolved_transcription",
    "resolve_auto",
    "resolved_qpsol",
    "auto_solver_name",
    "QPSOL_NAMES",
    "COMFORT_GAMMA_W",
    "CONFIG_FILE_KEYS",
    "CONTROLLER_FILE_KEYS",
    "check_controller_file",
]

COMFORT_GAMMA_W = 20000.0
"""ceco-c comfort weight gamma [W per PMV^2] (cost term gamma * PMV^2 next to watts).

Scaling: on the identified model, keeping the PMV one unit lower in steady
state costs about s = 0.3-0.6 kW of electrical power (docs/controller.md). With
a quadratic penalty the optimum sits where 2 gamma PMV = s, i.e.
PMV* = s / (2 gamma) = 0.008-0.015 for gamma = 20 kW: the comfort term
dominates (PMV held at neutral) while staying within 2 orders of magnitude of
the power terms, which keeps the NLP well conditioned. The paper's 1e5 was in
its own (unstated) units.
"""


SOLVER_NAMES = ("auto", "sqp", "ipopt", "fatrop")
"""Values of ``SolverSettings.name``."""

QPSOL_NAMES = ("auto", "qpoases", "hpipm", "qrqp")
"""Values of ``SolverSettings.qpsol``."""


def _check_switches(settings) -> None:
    """Raise ValueError naming the field if a switch (a field whose default is a bool) is not a bool.

    The text 'false' (a hand-typed override, YAML's quoted "false") would read as true.
    """
    for f in dataclasses.fields(settings):
        v = getattr(settings, f.name)
        if isinstance(f.default, bool) and not isinstance(v, bool):
            raise ValueError(f"{type(settings).__name__}.{f.name} must be true or false, got {v!r}")


@dataclasses.dataclass(frozen=True)
class SolverSettings:
    """NLP solver settings (choice justified with numbers in docs/controller.md 4.6)."""

    name: str = "auto"
    """Solver of the warm solves: 'auto' (default: 'sqp'), 'sqp' (ceco's SQP, :mod:`ceco_controller.sqp`:
    exact Hessian convexified by an exact eigendecomposition; dense qpOASES QPs on the
    single-shooting NLP, HPIPM's Riccati QPs on the multiple-shooting one (``qpsol``); IPOPT does the
    cold solves and retries a failed SQP solve), 'ipopt' (warm IPOPT) or 'fatrop' (multiple shooting
    only). CasADi's 'sqpmethod' was replaced by 'sqp' (its Jacobi eigen-solver could stop short,
    docs/controller.md 4.6)."""
    max_iter: int = 100
    """IPOPT/fatrop iteration limit per solve [-]."""
    sqp_max_iter: int = 20
    """SQP iteration (QP) limit per solve [-] (SC03: median 3, at most 6)."""
    max_cpu_time_s: float = 1.0
    """CPU-time limit per IPOPT solve [s] and, divided by ``sqp_max_iter``, per SQP QP (qpOASES);
    a guard below the wall-clock ``step_budget_s``, which bounds the whole control step."""
    step_budget_s: float = 1.0
    """Wall-clock budget of one whole control step [s], counted from ``NmpcController.compute``'s
    ``t_start`` (default: its entry): no solver iteration starts after ``step_budget_s -
    step_reserve_s``; must be below the control period (docs/controller.md 4.3: worst case)."""
    step_reserve_s: float = 0.1
    """Part of ``step_budget_s`` kept for the work after the solve (evaluation, fallback, the node's
    message conversion and publish) [s]."""
    accept_violation: float = 0.05
    """Largest constraint violation of an iterate that is applied although the solver stopped on
    its time or iteration limit (or a real-time iteration) [PMV, K] (comfort/T_evap rows and, in
    multiple shooting, the model's gaps): a twentieth of the comfort band (1 PMV wide), a third of
    the model's one-step T_cab error (0.16 K RMS); the real-time iteration's steps reach 0.036
    (SC03, ceco-ioch; docs/controller.md 4.6)."""
    rti: bool = False
    """Bounded-cost mode ('sqp' only): one QP per control step from the shifted warm start (SQP
    real-time iteration) instead of iterating to convergence; optimality loss measured in
    docs/controller.md 4.6."""
    tol: float = 1e-6
    """Convergence tolerance (IPOPT ``tol``; the SQP's constraint tolerance) [-]."""
    warm_start: bool = True
    """Warm start from the shifted previous primal-dual solution."""
    jit: bool = False
    """Compile the NLP functions to C with gcc (CasADi JIT) before the first solve."""
    linear_solver: str = "mumps"
    """IPOPT linear solver (the only one in the CasADi wheel; ma27/ma57 need HSL)."""
    acceptable_tol: float = 1e-4
    """IPOPT ``acceptable_tol`` [-] of the warm-started solver (with ``acceptable_iter`` 1 and
    acceptable constraint violation 1e-6: stops once the point is optimal to this level); the
    SQP's stationarity tolerance."""
    codegen: bool = False
    """Generate C code of the NLP functions, compile it with the C compiler into a shared object
    kept in an on-disk cache (keyed by a hash of the code) and solve with it. Falls back to the
    in-process functions (with a log warning) when no compiler is found or compilation fails.
    Off by default: a fresh machine would compile each distinct NLP once (10-25 s at -O1);
    ``python -m ceco_controller.nlp_cache`` fills the cache ahead of time."""
    codegen_flags: tuple = ("-O1",)
    """C compiler flags for ``codegen`` (-O1: half the -O2 compile time, same solve time)."""
    codegen_cache_dir: str | None = None
    """Cache directory of compiled NLPs; None: $CECO_CACHE_DIR, else $XDG_CACHE_HOME/ceco, else ~/.cache/ceco."""
    default_options: bool = False
    """Reference mode: IPOPT with its default settings, no warm start (what MPCTools did)."""
    qpsol: str = "auto"
    """QP solver of the SQP: 'auto' (dense 'qpoases' on the single-shooting NLP, 'hpipm' on the
    multiple-shooting one), 'qpoases' (dense active set), 'hpipm' (HPIPM's Riccati interior point
    on the stage structure: multiple shooting only, cost linear in Np) or CasADi's 'qrqp' (dense)."""
    eig_floor: float = 1e-7
    """SQP: smallest eigenvalue of each convexified Hessian block [kJ per variable unit^2]."""
    transcription: str = "auto"
    """How the horizon becomes an NLP: 'single-shooting' (the states are the model's rollout
    expressions of the inputs: no state variables, no gap constraints; at Np = 6 the dense QPs of
    the SQP have 32-39 instead of 56-63 variables), 'multiple-shooting' (states as variables
    with gap constraints: the sparse optimal-control structure, needed by fatrop) or 'auto'
    (single shooting up to ``single_shooting_max_steps``, multiple shooting beyond: the
    single-shooting derivatives grow quadratically with Np). Same optimum (docs/controller.md 4.6)."""
    single_shooting_max_steps: int = 12
    """Longest horizon [steps] that 'auto' transcribes by single shooting (the Hessian of the
    Lagrangian has 40 k / 133 k / 479 k SX instructions at Np = 6 / 12 / 24, against 19 k / 37 k /
    73 k for multiple shooting)."""
    ipopt_fallback: bool = True
    """For ``name`` 'sqp'/'fatrop': a failed warm solve is retried at once with the warm IPOPT
    solver (same data, if the step budget allows), and cold solves (first step, no usable warm
    start) use the cold IPOPT solver; the retries are counted (``NmpcController.n_ipopt_fallbacks``)."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if self.name == "sqpmethod":
            raise ValueError(
                "SolverSettings.name 'sqpmethod' (CasADi's SQP) was replaced by 'sqp' (docs/controller.md 4.6)"
            )
        if self.name not in SOLVER_NAMES:
            raise ValueError(f"SolverSettings.name must be one of {SOLVER_NAMES}, got {self.name!r}")
        _check_switches(self)
        if not (isinstance(self.max_iter, int) and self.max_iter >= 0):
            raise ValueError("SolverSettings.max_iter must be an int >= 0")
        for f in ("max_cpu_time_s", "step_budget_s", "tol", "accept_violation", "eig_floor"):
            v = getattr(self, f)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"SolverSettings.{f} must be finite and > 0, got {v!r}")
        if not (isinstance(self.step_reserve_s, (int, float)) and 0 <= self.step_reserve_s < self.step_budget_s):
            raise ValueError("SolverSettings.step_reserve_s must be >= 0 and below step_budget_s")
        if not (math.isfinite(self.acceptable_tol) and self.acceptable_tol >= self.tol):
            raise ValueError("SolverSettings.acceptable_tol must be finite and >= tol")
        if self.default_options and self.name != "ipopt":
            raise ValueError("SolverSettings.default_options (the IPOPT reference) needs name 'ipopt'")
        if not (isinstance(self.sqp_max_iter, int) and self.sqp_max_iter >= 1):
            raise ValueError("SolverSettings.sqp_max_iter must be an int >= 1")
        if self.qpsol not in QPSOL_NAMES:
            raise ValueError(f"SolverSettings.qpsol must be one of {QPSOL_NAMES}, got {self.qpsol!r}")
        if self.qpsol == "hpipm" and self.transcription == "single-shooting":
            raise ValueError("SolverSettings.qpsol 'hpipm' needs transcription 'multiple-shooting' (or 'auto')")
        if self.transcription not in ("auto", "single-shooting", "multiple-shooting"):
            raise ValueError(
                "SolverSettings.transcription must be auto, single-shooting or multiple-shooting, "
                f"got {self.transcription!r}"
            )
        if not (type(self.single_shooting_max_steps) is int and self.single_shooting_max_steps >= 0):
            raise ValueError("SolverSettings.single_shooting_max_steps must be an int >= 0")
        if self.name == "fatrop" and self.transcription == "single-shooting":
            raise ValueError("SolverSettings.name 'fatrop' needs transcription 'multiple-shooting' (or 'auto')")
        if self.rti and self.name not in ("auto", "sqp"):
            raise ValueError("SolverSettings.rti (one QP per step) needs name 'sqp' (or 'auto')")
        if not (isinstance(self.codegen_flags, (tuple, list)) and all(isinstance(f, str) for f in self.codegen_flags)):
            raise ValueError("SolverSettings.codegen_flags must be a tuple of strings")


@dataclasses.dataclass(frozen=True)
class StrategySettings:
    """One CECO strategy's NLP settings (see the module docstring)."""

    name: str = "ceco"
    """Strategy name: ceco, ceco-e, ceco-c, ceco-ioch or ceco-pmv."""
    horizon_steps: int = 6
    """Prediction horizon Np [steps] (paper: 6)."""
    control_period_s: float = 5.0
    """Control period Ts [s] (paper: 5 s); a whole multiple of the model step."""
    gamma_w: float = 0.0
    """Comfort weight gamma on PMV^2 [W per PMV^2] (0 except ceco-c)."""
    pmv_margin: float = 0.0
    """Back-off of the upper PMV bound [PMV] (robustness against model mismatch)."""
    ioch: bool = False
    """Use the IOCH slack eps and its cost (ceco-ioch)."""
    beta_w: float = 1000.0
    """IOCH weight beta [W PMV] on (eta_AC - 1)/(eps + xi)."""
    xi: float = 0.1
    """IOCH regularity term xi [PMV]."""
    eps_ub: float = 0.4
    """Largest IOCH tightening eps_UB [PMV]."""
    use_speed_preview: bool = False
    """Use the previewed vehicle speed in eta_AC; otherwise hold the measured speed."""
    slack_weight_kj: float = 1000.0
    """Exact L1 penalty rho on comfort/T_evap bound violations [kJ per PMV (or K) per stage]."""
    du_weight_kj: float = 1.0
    """Move penalty on normalised input changes [kJ per (full range)^2] (regularisation)."""
    t_evap_lb_c: float = 2.0
    """Lower bound on the evaporator wall temperature [degC] (frost), soft."""
    t_evap_ub_c: float = 60.0
    """Upper bound on the evaporator wall temperature [degC], soft (system limit)."""
    offset_free: bool = True
    """Estimate additive biases on T_cab, T_evap and T_ain from the last prediction errors."""
    bias_filter: float = 0.3
    """First-order filter gain of the bias estimates per control step [-] (0..1]."""
    bias_limit_k: float = 3.0
    """Largest magnitude of a bias estimate [K] (per control step for T_cab/T_evap)."""
    pmv_pa_source: str = "paper"
    """Cabin vapour pressure in the NLP's PMV: 'paper' (the paper's constant 1700 Pa: deliberate model
    mismatch, the plant scores with the cabin's own moisture) or 'measured' (the measured cabin RH at the
    measured T_cab, held over the horizon; 1700 Pa while the measurement is missing) (docs/controller.md)."""
    draught_weight_kj: float = 0.0
    """Weight of the ISO 7730 draught penalty [kJ per (DR/100)^2 per control period], on the uncapped
    smooth draught intensity in the vent jet at the occupant (0: off, as for the paper's strategies)."""
    pmv_newton_steps: int = 3
    """Newton steps on the clothing temperature in the NLP's PMV (the plant uses 4; the 3-step
    value differs by 6e-10 K in T_cl, docs/controller.md) [-]."""
    horizon_extension_steps: int = 0
    """Prediction stages beyond the preview horizon Np [steps]: the NLP predicts Np + this many
    steps, the previews and the comfort bounds held at their last values over the extension
    (0: the paper's horizon = the preview's)."""
    pmv_feedback: bool = False
    """Offset-free feedback on the comfort output: a bias on the predicted PMV from the one-step errors
    against the PMV computed from the measurements (:class:`~ceco_controller.comfort_feedback.PmvFeedback`)."""
    pmv_bias_filter: float = 0.3
    """First-order filter gain of the PMV bias per control step [-] (0..1]."""
    pmv_bias_limit: float = 0.3
    """Largest magnitude of the PMV bias [PMV]."""
    backoff: str = "fixed"
    """Back-off of the upper PMV bound: 'fixed' (``pmv_margin``) or 'adaptive' (a quantile of the
    recent one-step PMV prediction residuals plus the forecast-error growth over the horizon;
    docs/controller.md 4.7); 'adaptive' needs ``pmv_feedback``."""
    backoff_quantile: float = 0.95
    """Quantile of the recent one-step PMV residuals (measured minus predicted, bias included) the
    adaptive back-off covers [-]."""
    backoff_window_steps: int = 60
    """Residuals the quantile is taken over (the most recent) [control steps]."""
    backoff_min_samples: int = 12
    """Residuals needed before the quantile replaces ``backoff_init_pmv`` [-]."""
    backoff_init_pmv: float = 0.1
    """Adaptive back-off before ``backoff_min_samples`` residuals exist [PMV] (the fixed margin of ceco)."""
    backoff_min_pmv: float = 0.02
    """Smallest adaptive back-off [PMV]."""
    backoff_max_pmv: float = 0.3
    """Largest adaptive back-off [PMV]."""
    backoff_forecast_z: float = 1.645
    """Standard normal quantile applied to the PMV spread caused by the solar forecast's error growth
    beyond the first step [-] (1.645: one-sided 95 %)."""
    pmv_ub_cap: float = math.inf
    """Cap on the upper comfort bound the NLP sees [PMV]: min(the observation's bound, this) (inf: the
    bound as given). ceco-pmv: 0.5, the comfort band: it does not spend the pull-down's relaxed bound, as
    the matched-comfort axis charges every PMV-hour above +0.5 (docs/controller.md 4.7)."""
    preview_rule: str = "raw"
    """How the previews enter the prediction: 'raw' (as received) or 'shrink' (each previewed change
    from the measured value shrunk by its measured forecast-error variance; docs/controller.md 4.7)."""
    preview_shrink_c: float = 3.0
    """'shrink': threshold of the shrinkage in forecast-error standard deviations [-]."""
    preview_skill_window_steps: float = 60.0
    """'shrink': memory of the forecast-error variance estimates (exponential forgetting time) [control steps]."""
    solver: SolverSettings = SolverSettings()
    """NLP solver settings."""
    door_control: str = "none"
    """The fresh/recirculation door (issue 21): 'none' (not commanded: the plant's default share, every strategy
    before issue 21), 'co2_hold' (:class:`ceco_core.co2_door.Co2DoorLaw` beside the NLP: the least fresh air that
    holds the CO2 estimate under the limit, fresh air when the sensor fails or fog threatens; docs/controller.md
    4.8) or 'nlp' (the recirculated share a third input of the NLP, the cabin CO2 a predicted state under a soft
    limit; the same safe defaults override it; docs/controller.md 4.9)."""
    co2_slack_weight_kj_per_ppm: float = 1.0
    """'nlp': exact L1 penalty on the CO2 limit's violation [kJ per ppm per grid point] (docs/controller.md 4.9:
    above the largest multiplier of the CO2 rows, about 0.02 kJ/ppm)."""
    fog_slack_weight_kj_per_k: float = 1000.0
    """'nlp': exact L1 penalty on the fog margin's violation [kJ per K per grid point] (docs/controller.md 4.9: the
    comfort rows' weight per PMV unit, so a kelvin of fog margin outweighs the comfort a drying plan costs)."""
    fog_backoff_k: float = 1.0
    """'nlp': the NLP keeps the predicted fog margin at least this above the scenario's bound [K] (between the
    safe override's entry, bound + 0.5 K, and its exit, bound + 1.5 K: the NLP acts before the override)."""

    def validate(self) -> None:
        """Raise ValueError naming the field if a setting is not usable."""
        if self.name not in CECO_STRATEGIES:
            raise ValueError(f"StrategySettings.name must be one of {CECO_STRATEGIES}, got {self.name!r}")
        if not (isinstance(self.horizon_steps, int) and 1 <= self.horizon_steps <= 200):
            raise ValueError(f"StrategySettings.horizon_steps must be an int in [1, 200], got {self.horizon_steps!r}")
        for name in ("control_period_s", "xi"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"StrategySettings.{name} must be finite and > 0, got {v!r}")
        _check_switches(self)
        if self.pmv_pa_source not in ("paper", "measured"):
            raise ValueError(
                f"StrategySettings.pmv_pa_source must be 'paper' or 'measured', got {self.pmv_pa_source!r}"
            )
        for name in (
            "gamma_w",
            "pmv_margin",
            "beta_w",
            "eps_ub",
            "slack_weight_kj",
            "du_weight_kj",
            "bias_limit_k",
            "draught_weight_kj",
            "co2_slack_weight_kj_per_ppm",
            "fog_slack_weight_kj_per_k",
            "fog_backoff_k",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"StrategySettings.{name} must be finite and >= 0, got {v!r}")
        if not 0.0 < self.bias_filter <= 1.0:
            raise ValueError("StrategySettings.bias_filter must be in (0, 1]")
        if not self.t_evap_lb_c < self.t_evap_ub_c:
            raise ValueError("StrategySettings.t_evap_lb_c must be < t_evap_ub_c")
        if not (isinstance(self.pmv_newton_steps, int) and 1 <= self.pmv_newton_steps <= 50):
            raise ValueError("StrategySettings.pmv_newton_steps must be an int in [1, 50]")
        if not (type(self.horizon_extension_steps) is int and 0 <= self.horizon_extension_steps <= 200):
            raise ValueError("StrategySettings.horizon_extension_steps must be an int in [0, 200]")
        if self.backoff not in ("fixed", "adaptive"):
            raise ValueError(f"StrategySettings.backoff must be 'fixed' or 'adaptive', got {self.backoff!r}")
        if self.backoff == "adaptive" and not self.pmv_feedback:
            raise ValueError("StrategySettings.backoff 'adaptive' needs pmv_feedback (it measures the PMV residuals)")
        if not (isinstance(self.pmv_ub_cap, (int, float)) and -3.0 <= self.pmv_ub_cap):
            raise ValueError(f"StrategySettings.pmv_ub_cap must be >= -3 (inf: no cap), got {self.pmv_ub_cap!r}")
        if self.door_control not in DOOR_CONTROLS:
            raise ValueError(f"StrategySettings.door_control must be one of {DOOR_CONTROLS}, got {self.door_control!r}")
        if self.preview_rule not in ("raw", "shrink"):
            raise ValueError(f"StrategySettings.preview_rule must be 'raw' or 'shrink', got {self.preview_rule!r}")
        for name in (
            "backoff_init_pmv",
            "backoff_min_pmv",
            "backoff_max_pmv",
            "backoff_forecast_z",
            "preview_shrink_c",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"StrategySettings.{name} must be finite and >= 0, got {v!r}")
        if not self.backoff_min_pmv <= self.backoff_max_pmv:
            raise ValueError("StrategySettings.backoff_min_pmv must be <= backoff_max_pmv")
        if not 0.0 < self.pmv_bias_filter <= 1.0:
            raise ValueError("StrategySettings.pmv_bias_filter must be in (0, 1]")
        if not (math.isfinite(self.pmv_bias_limit) and self.pmv_bias_limit >= 0):
            raise ValueError("StrategySettings.pmv_bias_limit must be finite and >= 0")
        if not 0.5 <= self.backoff_quantile < 1.0:
            raise ValueError("StrategySettings.backoff_quantile must be in [0.5, 1)")
        for name in ("backoff_window_steps", "backoff_min_samples"):
            v = getattr(self, name)
            if not (type(v) is int and 1 <= v <= 100000):
                raise ValueError(f"StrategySettings.{name} must be an int in [1, 100000]")
        if self.backoff_min_samples > self.backoff_window_steps:
            raise ValueError("StrategySettings.backoff_min_samples must be <= backoff_window_steps")
        if not (math.isfinite(self.preview_skill_window_steps) and self.preview_skill_window_steps >= 1.0):
            raise ValueError("StrategySettings.preview_skill_window_steps must be finite and >= 1")
        if self.nlp_steps > 200:
            raise ValueError("StrategySettings.horizon_steps + horizon_extension_steps must be <= 200")
        self.solver.validate()  # its own fields first (types, ranges): the checks against the period compare them
        if self.solver.max_cpu_time_s >= self.control_period_s:
            raise ValueError("StrategySettings.solver.max_cpu_time_s must be below control_period_s")
        if self.solver.step_budget_s >= self.control_period_s:
            raise ValueError("StrategySettings.solver.step_budget_s must be below control_period_s")
        if (
            self.solver.name != "ipopt"
            and self.solver.ipopt_fallback
            and 2.0 * self.solver.max_cpu_time_s >= self.control_period_s
        ):
            # an SQP/fatrop solve (QPs limited to max_cpu_time_s in all) and then its IPOPT retry
            raise ValueError(
                "StrategySettings.solver.max_cpu_time_s must be below control_period_s / 2 "
                "when a failed SQP/fatrop solve is retried by IPOPT (ipopt_fallback)"
            )

    @property
    def nlp_steps(self) -> int:
        """Stages of the NLP: the preview horizon Np plus the extension [steps]."""
        return self.horizon_steps + self.horizon_extension_steps


DOOR_CONTROLS = ("none", "co2_hold", "nlp")
"""Values of :attr:`StrategySettings.door_control`."""

_DEFAULTS: dict[str, dict[str, Any]] = {
    "ceco": dict(pmv_margin=0.1),
    "ceco-e": dict(),
    "ceco-c": dict(gamma_w=COMFORT_GAMMA_W),
    "ceco-ioch": dict(ioch=True, use_speed_preview=True, pmv_margin=0.1, beta_w=1000.0),
    "ceco-pmv": dict(
        pmv_pa_source="measured",
        horizon_extension_steps=6,
        pmv_feedback=True,
        pmv_ub_cap=0.5,
        backoff="adaptive",
        preview_rule="shrink",
        use_speed_preview=False,  # the previewed speed in eta_AC cost 0-0.05 of headroom_captured (controller.md 4.7)
    ),
}


def resolved_transcription(settings: StrategySettings) -> str:
    """The transcription a controller with ``settings`` builds.

    'auto': multiple shooting for an explicit 'ipopt' or 'fatrop' (sparse solvers; IPOPT is slower
    on the condensed NLP, docs/controller.md 4.6), else (SQP) single shooting up to
    ``single_shooting_max_steps`` and multiple shooting beyond.
    """
    t = settings.solver.transcription
    if t != "auto":
        return t
    if settings.solver.name in ("ipopt", "fatrop"):
        return "multiple-shooting"
    return "single-shooting" if settings.nlp_steps <= settings.solver.single_shooting_max_steps else "multiple-shooting"


def auto_solver_name(transcription: str) -> str:
    """The solver 'auto' picks for an NLP transcription: the SQP (qpOASES or HPIPM QPs, ``resolved_qpsol``)."""
    if transcription not in ("single-shooting", "multiple-shooting"):
        raise ValueError(f"unknown transcription {transcription!r}")
    return "sqp"


def resolved_qpsol(qpsol: str, transcription: str) -> str:
    """The SQP's QP solver: 'auto' is dense qpOASES for single shooting, HPIPM for multiple shooting."""
    if qpsol != "auto":
        return qpsol
    return "qpoases" if transcription == "single-shooting" else "hpipm"


def resolve_auto(settings: StrategySettings) -> StrategySettings:
    """``settings`` with the solver's 'auto' choices made concrete.

    See ``SolverSettings.name`` and ``SolverSettings.transcription``: single shooting + the SQP up
    to ``single_shooting_max_steps``, multiple shooting + the SQP with HPIPM beyond.
    """
    transcription = resolved_transcription(settings)
    name = settings.solver.name
    if name == "auto":
        name = auto_solver_name(transcription)
    out = dataclasses.replace(
        settings,
        solver=dataclasses.replace(
            settings.solver,
            name=name,
            transcription=transcription,
            qpsol=resolved_qpsol(settings.solver.qpsol, transcription),
        ),
    )
    out.validate()
    return out


def _resolved_name(name: str) -> tuple[str, tuple]:
    """``(CECO strategy, the variant's fields)`` of a strategy name or a named variant.

    ValueError naming the choices for any other name.
    """
    base, variant = strategy_variant(name)
    if base not in CECO_STRATEGIES:
        raise ValueError(f"unknown CECO strategy {name!r}; choose from {NODE_STRATEGIES}")
    return base, variant


def strategy_settings(name: str, **overrides) -> StrategySettings:
    """Default settings of strategy ``name`` with keyword overrides; validated.

    A named variant (``ceco-pmv-aq``): its strategy's defaults with the variant's fields, then the overrides.
    """
    name, variant = _resolved_name(name)
    kw: dict[str, Any] = dict(_DEFAULTS[name])
    kw.update(variant)
    kw.update(overrides)
    s = StrategySettings(name=name, **kw)
    s.validate()
    return s


RUN_SETTINGS = {
    "horizon_steps": "the scenario's control.horizon_steps, --horizon-steps or mpc_node's parameter horizon_steps",
    "control_period_s": (
        "the scenario's control.control_period_s, --control-period-s or mpc_node's parameter control_period_s"
    ),
}
"""StrategySettings fields that every caller sets from the run (Np and Ts), with where they come from. A controller
file may leave them out; one that gives a value different from the run's is refused, since it would be ignored."""


CONTROLLER_FILE_KEYS = ("common", "strategies")
"""The top-level keys of a controller file: the settings every strategy shares, and ``{strategy: its settings}``."""

SHARED_FILE_KEYS = ("acc_law",)
"""Keys of the baseline's law file (``factory.load_acc_settings``) a controller file may hold too: ``ceco sim
--controller-config F --strategy baseline,ceco-ioch`` gives both the one file F (the NMPC reads ``common`` and
``strategies``, the baseline ``acc_law``)."""

CONFIG_FILE_KEYS = CONTROLLER_FILE_KEYS + SHARED_FILE_KEYS
"""Every top-level key either loader reads: a key outside it is refused by both (nothing would read it)."""


def check_controller_file(doc: dict, path) -> None:
    """ValueError, one line naming ``path``, for a key of a controller file that nothing would read.

    A top-level key other than :data:`CONTROLLER_FILE_KEYS` (``strategy:`` for ``strategies:`` ran every strategy
    on its defaults without a word; a scenario file was taken for a controller file), a strategy under
    ``strategies:`` that is none of :data:`~ceco_core.contracts.CECO_STRATEGIES` (a named variant reads its
    strategy's block), a block that is not a mapping, and a setting in any block that is no StrategySettings field
    (or, under ``solver``, no SolverSettings field).
    """
    unknown = [k for k in doc if k not in CONFIG_FILE_KEYS]
    if unknown:
        raise ValueError(
            f"{path}: unknown top-level key(s) {', '.join(repr(k) for k in unknown)}: a controller file has "
            f"{' and '.join(CONTROLLER_FILE_KEYS)} only (and acc_law, the baseline's, in a file both read)"
        )
    strategies = doc.get("strategies") or {}
    if not isinstance(strategies, dict):
        raise ValueError(f"{path}: strategies: expected a mapping of strategy names, got {strategies!r}")
    unknown = [k for k in strategies if k not in CECO_STRATEGIES]
    if unknown:
        raise ValueError(
            f"{path}: strategies: unknown strategy {', '.join(repr(k) for k in unknown)}: choose from "
            f"{', '.join(CECO_STRATEGIES)}"
        )
    fields = {f.name for f in dataclasses.fields(StrategySettings)} - {"name"}
    blocks = {"common": doc.get("common") or {}, **{f"strategies.{k}": v or {} for k, v in strategies.items()}}
    for where, block in blocks.items():
        if not isinstance(block, dict):
            raise ValueError(f"{path}: {where}: expected a mapping of StrategySettings fields, got {block!r}")
        unknown = [k for k in block if k not in fields]
        if unknown:
            raise ValueError(
                f"{path}: {where}: unknown setting(s) {', '.join(repr(k) for k in unknown)}: not StrategySettings "
                "fields (docs/controller.md)"
            )
        solver = block.get("solver") or {}
        if not isinstance(solver, dict):
            raise ValueError(f"{path}: {where}.solver: expected a mapping of SolverSettings fields, got {solver!r}")
        unknown = [k for k in solver if k not in {f.name for f in dataclasses.fields(SolverSettings)}]
        if unknown:
            raise ValueError(
                f"{path}: {where}.solver: unknown setting(s) {', '.join(repr(k) for k in unknown)}: not "
                "SolverSettings fields (docs/controller.md)"
            )


def load_strategy_settings(name: str, path=None, **overrides) -> StrategySettings:
    """Settings of strategy ``name`` from a controller file (common + per-strategy keys), then overrides.

    ``path`` None: the package's ``config/controller.yaml`` (source tree, else the installed share
    directory; :func:`ceco_controller.model.package_config_path`). The closed-loop simulator and
    ``mpc_node`` (parameter ``controller_config``) build their controllers from it. A named variant
    (``ceco-pmv-aq``, :data:`ceco_core.contracts.STRATEGY_VARIANTS`) reads its strategy's keys, then sets its fields.
    A file's ``horizon_steps`` or ``control_period_s`` that differs from an override of it is refused
    (:data:`RUN_SETTINGS`), and so is a key nothing would read (:func:`check_controller_file`: a top-level key
    other than ``common`` and ``strategies``, an unknown strategy or setting in any block).
    """
    import pathlib

    from ceco_core import yamlio

    from .model import package_config_path

    path = pathlib.Path(path) if path is not None else package_config_path("controller.yaml")
    doc = yamlio.load_file(path)
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: expected a mapping")
    check_controller_file(doc, path)
    name, variant = _resolved_name(name)
    kw = dict(doc.get("common") or {})
    kw.update((doc.get("strategies") or {}).get(name) or {})
    kw.update(variant)
    for key, where in RUN_SETTINGS.items():  # set by the run: a different value in the file would be ignored
        if key in kw and key in overrides and kw[key] != overrides[key]:
            raise ValueError(
                f"{path}: {key}: {kw[key]!r} is not what this run uses ({overrides[key]!r}); {key} is set by "
                f"{where}: remove it from the file"
            )
    solver = kw.pop("solver", None)
    if solver is not None:
        try:
            if "codegen_flags" in solver:
                solver = dict(solver, codegen_flags=tuple(solver["codegen_flags"]))
            kw["solver"] = SolverSettings(**solver)
        except TypeError as exc:
            raise ValueError(f"{path}: solver: {exc}") from None
    kw.update(overrides)
    names = {f.name for f in dataclasses.fields(StrategySettings)}
    unknown = sorted(set(kw) - names)
    if unknown:
        raise ValueError(f"{path}: unknown setting(s) {unknown}")
    s = StrategySettings(name=name, **kw)
    s.validate()
    return s
