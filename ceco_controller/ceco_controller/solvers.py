"""Solvers of the CECO NLP, built once per problem, each returning a :class:`SolveResult`.

``build_solver(problem, solver_settings)`` makes a CasADi ``nlpsol`` (IPOPT, sqpmethod or fatrop)
for an :class:`~ceco_controller.transcription.NlpProblem`, with compiled NLP functions when
``codegen`` is set (:mod:`ceco_controller.codegen`). :meth:`NlpSolver.solve` solves one instance
(:class:`NlpData`) and reports success, status, iterations and wall time by name.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time

import casadi
import numpy as np

from .codegen import compile_nlp, stdout_silenced
from .strategies import SolverSettings, auto_solver_name
from .transcription import NlpProblem

__all__ = ["NlpData", "SolveResult", "NlpSolver", "build_solver"]

_LOG = logging.getLogger(__name__)


@dataclasses.dataclass
class NlpData:
    """The numeric data of one NLP instance (for benchmarks and tests)."""

    p: np.ndarray
    """Parameter vector."""
    x0: np.ndarray
    """Primal initial guess."""
    lam_x0: np.ndarray | None = None
    """Initial guess of the bound multipliers."""
    lam_g0: np.ndarray | None = None
    """Initial guess of the constraint multipliers."""


@dataclasses.dataclass
class SolveResult:
    """What one solver call gave: the same fields on every path."""

    solver: str
    """Solver that produced it ('ipopt', 'sqpmethod', 'fatrop'; 'a: ..; b: ..' after a retry)."""
    success: bool
    """The solver reported success."""
    status: str
    """The solver's return status, or why there is no solution."""
    iterations: int | None = None
    """Solver iterations (None when unknown)."""
    time_ms: float | None = None
    """Wall-clock time of the solver call(s) [ms] (None when the call raised)."""
    w: np.ndarray | None = None
    """Primal solution (None when the call raised)."""
    f: float = math.nan
    """Objective at ``w``."""
    lam_x: np.ndarray | None = None
    """Bound multipliers."""
    lam_g: np.ndarray | None = None
    """Constraint multipliers."""
    stats: dict = dataclasses.field(default_factory=dict, repr=False)
    """The solver's raw statistics."""

    @classmethod
    def failed(cls, solver: str, status: str) -> SolveResult:
        """A result without a solution."""
        return cls(solver=solver, success=False, status=status)

    def finite(self) -> bool:
        """True if there is a primal solution and every entry is finite."""
        return self.w is not None and bool(np.all(np.isfinite(self.w)))


class NlpSolver:
    """A CasADi nlpsol built for one problem; :meth:`solve` never raises on solver trouble."""

    def __init__(self, problem: NlpProblem, settings: SolverSettings, function: casadi.Function):
        self.problem = problem
        self.settings = settings
        """The solver settings it was built with ('auto' resolved)."""
        self.name = settings.name
        """Plugin name."""
        self.function = function
        """The CasADi nlpsol."""

    def solve(self, data: NlpData) -> SolveResult:
        """Solve one instance; CasADi evaluation errors become a failed result."""
        try:
            return self._solve(data)
        except RuntimeError as exc:
            return SolveResult.failed(self.name, f"exception: {exc}")

    def _solve(self, data: NlpData) -> SolveResult:
        args = {"x0": data.x0, "p": data.p, **self.problem.bounds_dm}
        if data.lam_x0 is not None:
            args["lam_x0"] = data.lam_x0
        if data.lam_g0 is not None:
            args["lam_g0"] = data.lam_g0
        t0 = time.perf_counter()
        sol = self.function(**args)
        dt_ms = 1e3 * (time.perf_counter() - t0)
        try:
            stats = self.function.stats()
        except RuntimeError as exc:  # CasADi 3.8.2 sqpmethod: no stats after an error in iteration 0
            last = (str(exc).splitlines() or [type(exc).__name__])[-1]
            stats = {"success": False, "return_status": f"no solver statistics ({last})"}
        return SolveResult(solver=self.name, success=bool(stats.get("success", False)),
                           status=str(stats.get("return_status", "unknown")),
                           iterations=int(stats["iter_count"]) if "iter_count" in stats else None,
                           time_ms=dt_ms, w=np.array(sol["x"]).ravel(), f=float(sol["f"]),
                           lam_x=np.array(sol["lam_x"]).ravel(), lam_g=np.array(sol["lam_g"]).ravel(),
                           stats=stats)


def _compiled_nlp(problem: NlpProblem, ss: SolverSettings) -> str | None:
    """Path of the compiled NLP functions for ``ss`` (cached per problem), or None (logged)."""
    key = (ss.name, tuple(ss.codegen_flags))
    if key not in problem.compiled:
        problem.compiled[key] = compile_nlp(problem.nlp, ss.codegen_flags, ss.codegen_cache_dir, plugin=ss.name)
    return problem.compiled[key]


def _ipopt_options(ss: SolverSettings) -> dict:
    if ss.default_options:
        return {"print_level": 0, "sb": "yes"}
    ipopt = {
        "print_level": 0, "sb": "yes",
        "max_iter": ss.max_iter, "max_cpu_time": ss.max_cpu_time_s,
        "tol": ss.tol, "acceptable_tol": min(ss.acceptable_tol, 1e-6), "acceptable_iter": 5,
        "linear_solver": ss.linear_solver,
        "hessian_approximation": "exact",
        "mu_strategy": "adaptive", "mu_oracle": "quality-function",
        "nlp_scaling_method": "gradient-based",
    }
    if ss.warm_start:
        # warm-started re-solves start near the optimum: a small adaptive barrier, no
        # gradient scaling, stop at the first point optimal to acceptable_tol with the
        # constraints met to 1e-6 (measured fastest with the same optimum, docs/controller.md)
        ipopt.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                      "warm_start_bound_frac": 1e-9, "warm_start_slack_bound_frac": 1e-9,
                      "warm_start_slack_bound_push": 1e-9, "warm_start_mult_bound_push": 1e-9,
                      "mu_init": 1e-5, "nlp_scaling_method": "none",
                      "acceptable_tol": ss.acceptable_tol, "acceptable_iter": 1,
                      "acceptable_constr_viol_tol": 1e-6, "acceptable_compl_inf_tol": 1e-4})
    return ipopt


def _sqpmethod_options(ss: SolverSettings) -> dict:
    # sqpmethod: exact Hessian convexified (eigen-clip), one dense QP per iteration, line search;
    # bounded by sqp_max_iter SQP iterations and a CPU-time limit per QP (qpOASES). Like the warm IPOPT:
    # constraints met to tol (1e-6), stationarity to acceptable_tol (1e-4; 3 instead of 5 median
    # iterations on SC03 with the same optimum, docs/controller.md 4.6)
    if ss.qpsol == "qpoases":
        qp_opts = {"printLevel": "none", "sparse": False, "error_on_fail": False,
                   "CPUtime": ss.max_cpu_time_s / ss.sqp_max_iter}
    else:
        qp_opts = {"print_iter": False, "print_header": False, "error_on_fail": False}
    return {"qpsol": ss.qpsol, "qpsol_options": qp_opts,
            "max_iter": ss.sqp_max_iter, "print_iteration": False, "print_header": False,
            "print_status": False, "tol_pr": ss.tol, "tol_du": ss.acceptable_tol if ss.warm_start else ss.tol,
            "convexify_strategy": ss.convexify_strategy, "max_iter_eig": float(ss.max_iter_eig),
            "error_on_fail": False}


def _nlpsol(plugin: str, nlp, opts: dict, fallback_nlp: dict) -> casadi.Function:
    """``nlpsol`` from a compiled object path (or the in-process NLP).

    An unloadable object falls back to ``fallback_nlp`` with a log warning. Construction runs
    with stdout silenced (qpOASES).
    """
    if isinstance(nlp, str):
        try:
            with stdout_silenced():
                return casadi.nlpsol("ceco_nlp", plugin, nlp, opts)
        except RuntimeError as exc:
            _LOG.warning("NMPC codegen: cannot load %s (%s); using the in-process NLP functions", nlp, exc)
            nlp = fallback_nlp
    with stdout_silenced():
        return casadi.nlpsol("ceco_nlp", plugin, nlp, opts)


def build_solver(problem: NlpProblem, solver_settings: SolverSettings) -> NlpSolver:
    """Build a solver for ``problem`` with the given settings ('auto' name resolved for its transcription)."""
    ss = solver_settings
    ss.validate()
    if ss.transcription not in ("auto", problem.transcription):
        raise ValueError(f"SolverSettings.transcription {ss.transcription!r} does not match this controller's "
                         f"NLP ({problem.transcription}); build another controller for it")
    if ss.name == "auto":
        ss = dataclasses.replace(ss, name=auto_solver_name(problem.transcription))
    opts: dict = {"print_time": False}
    nlp = problem.nlp
    if ss.codegen and ss.name in ("ipopt", "sqpmethod") and not ss.default_options:
        so = _compiled_nlp(problem, ss)
        if so is not None:
            nlp = so
    if ss.jit and not isinstance(nlp, str):
        opts.update({"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"], "verbose": False}})
    if ss.name == "ipopt":
        opts["ipopt"] = _ipopt_options(ss)
        return NlpSolver(problem, ss, _nlpsol("ipopt", nlp, opts, problem.nlp))
    if ss.name == "fatrop":
        opts.update({"structure_detection": "auto", "expand": True,
                     "equality": [bool(a == b) for a, b in zip(problem.lbg, problem.ubg)],
                     "fatrop": {"print_level": 0, "max_iter": ss.max_iter, "tol": ss.tol, "mu_init": 1e-2}})
        # (fatrop 0.0.x in CasADi 3.8 accepts no warm-start option; the primal guess is still used)
        return NlpSolver(problem, ss, casadi.nlpsol("ceco_nlp", "fatrop", problem.nlp, opts))
    opts.update(_sqpmethod_options(ss))
    return NlpSolver(problem, ss, _nlpsol("sqpmethod", nlp, opts, problem.nlp))
