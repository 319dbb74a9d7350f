"""Solvers of the CECO NLP, built once per problem, each returning a :class:`SolveResult`.

``build_solver(problem, solver_settings)`` makes, for an
:class:`~ceco_controller.transcription.NlpProblem`:

* ``sqp``    ceco's dense SQP (:mod:`ceco_controller.sqp`), optionally one QP per call (``rti``);
* ``ipopt``  CasADi's IPOPT interface (warm or cold options, or IPOPT's defaults as the reference);
* ``fatrop`` CasADi's fatrop interface (multiple shooting).

Compiled NLP functions when ``codegen`` is set (:mod:`ceco_controller.codegen`). Every
:meth:`NlpSolver.solve` takes an optional wall-clock ``deadline`` (absolute, on the solver's
clock): the SQP checks it before every QP and line-search trial, IPOPT in its iteration callback
(``User_Requested_Stop`` is reported as ``Maximum_Wall_Time_Exceeded``); fatrop ignores it (its
iteration limit bounds it). The result reports success, status, iterations, wall time and the
largest constraint violation of the returned point by name.
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import math
import time
from collections.abc import Callable
from typing import Any

import casadi
import numpy as np

from .codegen import compile_functions, compile_nlp, nlp_key, stdout_silenced
from .sqp import Sqp, SqpOptions, sqp_functions
from .strategies import SolverSettings, auto_solver_name, resolved_qpsol
from .transcription import NlpProblem

__all__ = ["IterationCallback", "NlpData", "SolveResult", "NlpSolver", "build_solver", "LIMIT_STATUSES"]

_LOG = logging.getLogger(__name__)

LIMIT_STATUSES = ("Maximum_Iterations_Exceeded", "Maximum_Wall_Time_Exceeded", "Maximum_CpuTime_Exceeded", "RTI_Step")
"""Statuses of a solver that stopped on a limit with a usable iterate (applied if its violation is small)."""


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
    """Solver that produced it ('sqp', 'ipopt', 'fatrop')."""
    success: bool
    """The solver reported success (the SQP in ``rti`` mode: the QP step was taken)."""
    status: str
    """The solver's return status, or why there is no solution."""
    iterations: int | None = None
    """Solver iterations (SQP: QPs solved; None when unknown)."""
    time_ms: float | None = None
    """Wall-clock time of the solver call(s) [ms] (None when the call raised)."""
    cpu_ms: float | None = None
    """CPU time of the calling thread in the solver call [ms] (benchmarks on a loaded machine: the wall
    time also holds the time the thread waited for a core); None when the call raised."""
    w: np.ndarray | None = None
    """Primal point returned (None when the call raised)."""
    f: float = math.nan
    """Objective at ``w``."""
    lam_x: np.ndarray | None = None
    """Bound multipliers."""
    lam_g: np.ndarray | None = None
    """Constraint multipliers."""
    violation: float = math.inf
    """Largest violation of the variable and constraint bounds at ``w`` [constraint units]."""
    stats: dict = dataclasses.field(default_factory=dict, repr=False)
    """The solver's raw statistics."""

    @classmethod
    def failed(cls, solver: str, status: str) -> SolveResult:
        """A result without a solution."""
        return cls(solver=solver, success=False, status=status)

    def finite(self) -> bool:
        """True if there is a primal-dual point and every entry is finite."""
        return all(a is not None and bool(np.isfinite(a).all()) for a in (self.w, self.lam_x, self.lam_g))

    @property
    def limited(self) -> bool:
        """The solver stopped on a time or iteration limit (or made its one RTI step)."""
        return self.status in LIMIT_STATUSES


class NlpSolver:
    """A solver built for one problem; :meth:`solve` never raises on solver trouble."""

    def __init__(self, problem: NlpProblem, settings: SolverSettings, clock: Callable[[], float]):
        self.problem = problem
        self.settings = settings
        """The solver settings it was built with ('auto' resolved)."""
        self.name = settings.name
        """Solver name."""
        self.clock = clock
        """Clock of the deadlines [s] (``time.perf_counter`` unless injected)."""

    def reset(self) -> None:
        """Forget what earlier solves left in the solver (a solve then equals a fresh solver's); default: nothing."""

    def solve(self, data: NlpData, deadline: float | None = None) -> SolveResult:
        """Solve one instance (no iteration starts after ``deadline``); evaluation errors become a failed result."""
        try:
            return self._solve(data, deadline)
        except RuntimeError as exc:
            return SolveResult.failed(self.name, f"exception: {exc}")

    def _solve(self, data: NlpData, deadline: float | None) -> SolveResult:
        raise NotImplementedError


class SqpSolver(NlpSolver):
    """ceco's SQP (:class:`~ceco_controller.sqp.Sqp`): dense qpOASES QPs, or HPIPM on the multiple-shooting stages."""

    def __init__(self, problem: NlpProblem, settings: SolverSettings, clock: Callable[[], float]):
        super().__init__(problem, settings, clock)
        qpsol = resolved_qpsol(settings.qpsol, problem.transcription)
        structure = problem.ocp_structure() if qpsol == "hpipm" else None
        if qpsol == "hpipm" and structure is None:
            raise ValueError("SolverSettings.qpsol 'hpipm' needs the multiple-shooting NLP")
        sf = sqp_functions(problem.nlp, structure)
        fns = sf.functions
        if settings.codegen:
            # the functions are a deterministic product of the NLP, the QP's layout and sqp_functions' code; the
            # problem's evaluator and rollout (the diagnostics, the warm start) go into the same object
            extra = (problem.evaluator, problem.rollout)
            key = nlp_key(problem.nlp) + repr(structure).encode() + inspect.getsource(sqp_functions).encode()
            key += b"".join(f.serialize().encode() for f in extra)
            so = _compiled(
                problem,
                ("sqp", qpsol, tuple(settings.codegen_flags)),
                lambda: compile_functions(
                    [*fns.values(), *extra], key, settings.codegen_flags, settings.codegen_cache_dir, prefix="ceco_sqp"
                ),
            )
            if so is not None:
                try:
                    loaded = {k: casadi.external(f.name(), so) for k, f in fns.items()}
                    evaluator, rollout = (casadi.external(f.name(), so) for f in extra)
                except RuntimeError as exc:
                    _LOG.warning("NMPC codegen: cannot load %s (%s); using the in-process NLP functions", so, exc)
                else:
                    fns = loaded
                    problem.use_compiled(evaluator, rollout)
        elif settings.jit:
            jit: dict[str, Any] = {
                "jit": True,
                "compiler": "shell",
                "jit_options": {"flags": ["-O2"], "verbose": False},
            }
            fns = {
                k: casadi.Function(f.name(), f.sx_in(), f.sx_out(), f.name_in(), f.name_out(), jit)
                for k, f in fns.items()
            }
        opts = SqpOptions(
            max_iter=settings.sqp_max_iter,
            tol_pr=settings.tol,
            tol_du=settings.acceptable_tol if settings.warm_start else settings.tol,
            eig_floor=settings.eig_floor,
            rti=settings.rti,
            qpsol=qpsol,
            qp_cpu_time_s=settings.max_cpu_time_s / settings.sqp_max_iter,
        )
        self.sqp = Sqp(
            dataclasses.replace(sf, functions=fns), problem.lbw, problem.ubw, problem.lbg, problem.ubg, opts, clock
        )

    def reset(self) -> None:
        """A new QP solver (qpOASES hot-starts from the previous QP)."""
        self.sqp.reset()

    def _solve(self, data: NlpData, deadline: float | None) -> SolveResult:
        t0, c0 = time.perf_counter(), time.thread_time()
        out = self.sqp.solve(data.x0, data.p, data.lam_x0, data.lam_g0, deadline=deadline)
        dt_ms, cpu_ms = 1e3 * (time.perf_counter() - t0), 1e3 * (time.thread_time() - c0)
        # the SQP's w is inside its bounds (clipped at every step); its primal infeasibility is g's at w
        violation = out.primal_infeasibility if math.isfinite(float(out.g.sum())) else math.inf
        return SolveResult(
            solver=self.name,
            success=out.success,
            status=out.status,
            iterations=out.iterations,
            time_ms=dt_ms,
            cpu_ms=cpu_ms,
            w=out.w,
            f=out.f,
            lam_x=out.lam_x,
            lam_g=out.lam_g,
            violation=violation,
            stats={"dual_infeasibility": out.dual_infeasibility, "line_search_failures": out.line_search_failures},
        )


class IterationCallback(casadi.Callback):
    """Base of IPOPT iteration callbacks (CasADi's ``iteration_callback``): nonzero output asks IPOPT to stop.

    The inputs are nlpsol's outputs by name (x, f, g, lam_x, lam_g, lam_p); :attr:`sizes` gives the length of
    those a subclass reads, the others are declared empty, so IPOPT copies nothing for them. A subclass sets
    :attr:`sizes`, then calls ``construct``.
    """

    sizes: dict[str, int] = {}

    # the CasADi Callback interface
    def get_n_in(self):
        """As many inputs as nlpsol has outputs."""
        return casadi.nlpsol_n_out()

    def get_n_out(self):
        """One output: nonzero stops IPOPT."""
        return 1

    def get_name_in(self, i):
        """The names of nlpsol's outputs."""
        return casadi.nlpsol_out(i)

    def get_name_out(self, i):
        """The output's name."""
        return "stop"

    def get_sparsity_in(self, i):
        """Dense of :attr:`sizes`' length for the inputs read, empty for the others."""
        n = self.sizes.get(casadi.nlpsol_out(i), 0)
        return casadi.Sparsity.dense(n) if n else casadi.Sparsity(0, 0)


class _DeadlineCallback(IterationCallback):
    """IPOPT iteration callback: asks IPOPT to stop once ``deadline`` has passed on ``clock``.

    It reads no input (no copy per iteration).
    """

    def __init__(self, clock: Callable[[], float]):
        casadi.Callback.__init__(self)
        self.clock = clock
        self.deadline = math.inf
        self.construct("ceco_deadline", {})

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        memoryview(res[0]).cast("d")[0] = 1.0 if self.clock() >= self.deadline else 0.0
        return 0


class CasadiSolver(NlpSolver):
    """A CasADi ``nlpsol`` (IPOPT or fatrop)."""

    def __init__(
        self,
        problem: NlpProblem,
        settings: SolverSettings,
        clock: Callable[[], float],
        function: casadi.Function,
        callback: _DeadlineCallback | None,
    ):
        super().__init__(problem, settings, clock)
        self.function = function
        """The CasADi nlpsol."""
        self._callback = callback

    def _solve(self, data: NlpData, deadline: float | None) -> SolveResult:
        args: dict[str, Any] = {"x0": data.x0, "p": data.p, **self.problem.bounds_dm}
        if data.lam_x0 is not None:
            args["lam_x0"] = data.lam_x0
        if data.lam_g0 is not None:
            args["lam_g0"] = data.lam_g0
        if self._callback is not None:
            self._callback.deadline = math.inf if deadline is None else deadline
        t0, c0 = time.perf_counter(), time.thread_time()
        sol = self.function(**args)
        dt_ms, cpu_ms = 1e3 * (time.perf_counter() - t0), 1e3 * (time.thread_time() - c0)
        stats = self.function.stats()
        status = str(stats.get("return_status", "unknown"))
        if status == "User_Requested_Stop":  # our deadline callback
            status = "Maximum_Wall_Time_Exceeded"
        w = np.array(sol["x"]).ravel()
        g = np.array(sol["g"]).ravel()
        violation = self.problem.max_violation(w, g) if np.all(np.isfinite(g)) else math.inf
        return SolveResult(
            solver=self.name,
            success=bool(stats.get("success", False)),
            status=status,
            iterations=int(stats["iter_count"]) if "iter_count" in stats else None,
            time_ms=dt_ms,
            cpu_ms=cpu_ms,
            w=w,
            f=float(sol["f"]),
            lam_x=np.array(sol["lam_x"]).ravel(),
            lam_g=np.array(sol["lam_g"]).ravel(),
            violation=violation,
            stats=stats,
        )


def _compiled(problem: NlpProblem, key: tuple, compile_fn) -> str | None:
    """Path of compiled NLP functions (cached per problem and key), or None (logged)."""
    if key not in problem.compiled:
        problem.compiled[key] = compile_fn()
    return problem.compiled[key]


def _ipopt_options(ss: SolverSettings) -> dict:
    if ss.default_options:
        return {"print_level": 0, "sb": "yes"}
    ipopt = {
        "print_level": 0,
        "sb": "yes",
        "max_iter": ss.max_iter,
        "max_cpu_time": ss.max_cpu_time_s,
        "tol": ss.tol,
        "acceptable_tol": min(ss.acceptable_tol, 1e-6),
        "acceptable_iter": 5,
        "linear_solver": ss.linear_solver,
        "hessian_approximation": "exact",
        "mu_strategy": "adaptive",
        "mu_oracle": "quality-function",
        "nlp_scaling_method": "gradient-based",
    }
    if ss.warm_start:
        # warm-started re-solves start near the optimum: a small adaptive barrier, no
        # gradient scaling, stop at the first point optimal to acceptable_tol with the
        # constraints met to 1e-6 (measured fastest with the same optimum, docs/controller.md)
        ipopt.update(
            {
                "warm_start_init_point": "yes",
                "warm_start_bound_push": 1e-9,
                "warm_start_bound_frac": 1e-9,
                "warm_start_slack_bound_frac": 1e-9,
                "warm_start_slack_bound_push": 1e-9,
                "warm_start_mult_bound_push": 1e-9,
                "mu_init": 1e-5,
                "nlp_scaling_method": "none",
                "acceptable_tol": ss.acceptable_tol,
                "acceptable_iter": 1,
                "acceptable_constr_viol_tol": 1e-6,
                "acceptable_compl_inf_tol": 1e-4,
            }
        )
    return ipopt


def build_solver(
    problem: NlpProblem, solver_settings: SolverSettings, clock: Callable[[], float] = time.perf_counter
) -> NlpSolver:
    """Build a solver for ``problem`` with the given settings ('auto' name resolved for its transcription)."""
    ss = solver_settings
    ss.validate()
    if ss.transcription not in ("auto", problem.transcription):
        raise ValueError(
            f"SolverSettings.transcription {ss.transcription!r} does not match this controller's "
            f"NLP ({problem.transcription}); build another controller for it"
        )
    if ss.name == "auto":
        ss = dataclasses.replace(ss, name=auto_solver_name(problem.transcription))
    if ss.name == "sqp":
        return SqpSolver(problem, ss, clock)
    opts: dict = {"print_time": False}
    if ss.name == "fatrop":
        opts.update(
            {
                "structure_detection": "auto",
                "expand": True,
                "equality": [bool(a == b) for a, b in zip(problem.lbg, problem.ubg)],
                "fatrop": {"print_level": 0, "max_iter": ss.max_iter, "tol": ss.tol, "mu_init": 1e-2},
            }
        )
        # (fatrop 0.0.x in CasADi 3.8 accepts no warm-start option; the primal guess is still used)
        return CasadiSolver(problem, ss, clock, casadi.nlpsol("ceco_nlp", "fatrop", problem.nlp, opts), None)
    nlp: dict | str = problem.nlp
    if ss.codegen and not ss.default_options:
        so = _compiled(
            problem,
            ("ipopt", tuple(ss.codegen_flags)),
            lambda: compile_nlp(problem.nlp, ss.codegen_flags, ss.codegen_cache_dir, plugin="ipopt"),
        )
        if so is not None:
            nlp = so
    if ss.jit and not isinstance(nlp, str):
        opts.update({"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"], "verbose": False}})
    opts["ipopt"] = _ipopt_options(ss)
    callback = None if ss.default_options else _DeadlineCallback(clock)
    if callback is not None:
        opts["iteration_callback"] = callback
    if isinstance(nlp, str):
        try:
            with stdout_silenced():
                return CasadiSolver(problem, ss, clock, casadi.nlpsol("ceco_nlp", "ipopt", nlp, opts), callback)
        except RuntimeError as exc:  # unloadable object: the in-process functions
            _LOG.warning("NMPC codegen: cannot load %s (%s); using the in-process NLP functions", nlp, exc)
            nlp = problem.nlp
    return CasadiSolver(problem, ss, clock, casadi.nlpsol("ceco_nlp", "ipopt", nlp, opts), callback)
