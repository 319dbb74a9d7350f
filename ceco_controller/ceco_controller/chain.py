"""The NMPC's solve chain: which solver tries an instance, from which start, and what is accepted.

For one NLP instance (parameters ``p``) and the last usable solution (:class:`GoodSolution`,
shifted by the steps elapsed since it was computed), within a wall-clock deadline:

1. warm start (when there is a usable solution and warm starts are on): the warm solver
   (the SQP, one QP in ``rti`` mode, or warm IPOPT);
2. if that gave nothing usable and a retry solver exists: the warm IPOPT, from the same start;
3. if still nothing usable, or there was no warm start: the cold IPOPT from the model-rollout
   guess (on the multiple-shooting NLP for a single-shooting controller, mapped back), with half
   of the time left when the warm solver is the SQP;
4. if that gave nothing usable either: the SQP from the same guess, with the rest of the time.

No attempt starts after the deadline. A result is *usable* when its primal-dual point is finite
with multipliers below ``MAX_MULTIPLIER``, its largest constraint violation is at most
``SolverSettings.accept_violation`` and its first input is inside the actuator bounds; it may be
a converged solution or an iterate the solver returned on its time or iteration limit (or the
real-time iteration's step). Only usable results ever become the next warm start: a failed
attempt never replaces the last good solution.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ceco_core.contracts import ActuatorLimits

from .solvers import NlpData, NlpSolver, SolveResult
from .transcription import NlpProblem
from .warmstart import initial_guess

__all__ = ["GoodSolution", "ColdPath", "ChainOutcome", "SolveChain", "StepCounters", "MAX_MULTIPLIER", "BOUND_TOL"]

MAX_MULTIPLIER = 1e9
"""Largest multiplier magnitude of a usable solution (the exact-penalty weights are 1e3)."""

BOUND_TOL = 1e-6
"""Tolerance on the solver's actuator bounds [kg/s, degC]: within it a command is clipped to the
bound; beyond it the result is not usable."""


@dataclasses.dataclass
class StepCounters:
    """What the control steps since construction (or :meth:`NmpcController.reset`) did, by name."""

    steps: int = 0
    """Calls of compute."""
    converged: int = 0
    """Steps applying a converged solution."""
    accepted_iterates: int = 0
    """Steps applying an iterate returned on a time or iteration limit (small violation)."""
    rti_steps: int = 0
    """Steps applying a real-time iteration."""
    retries: int = 0
    """Warm solves that failed and were retried by the warm IPOPT."""
    cold_solves: int = 0
    """Cold solves attempted."""
    shifted_plan: int = 0
    """Steps applying the last good plan shifted."""
    acc_law: int = 0
    """Steps applying the production ACC law."""
    invalid_observations: int = 0
    """Steps whose observation was not usable (ACC law)."""
    substituted_commands: int = 0
    """Steps whose implausible previous command was replaced by the one this controller applied."""
    deadline_hits: int = 0
    """Steps in which an attempt stopped on, or was skipped because of, the deadline."""


@dataclasses.dataclass
class GoodSolution:
    """The last usable primal-dual solution and its plan."""

    w: np.ndarray
    """Primal point."""
    lam_x: np.ndarray
    """Bound multipliers."""
    lam_g: np.ndarray
    """Constraint multipliers."""
    plan: np.ndarray
    """Inputs u_0..u_{N-1} [kg/s, degC], shape (N, 2)."""
    age: int = 0
    """Control steps since it was computed (0: for the current step)."""

    @classmethod
    def of(cls, result: SolveResult, problem: NlpProblem, age: int = 0) -> GoodSolution:
        """From a usable result (ValueError if it has no primal-dual point)."""
        w, lam_x, lam_g = result.w, result.lam_x, result.lam_g
        if w is None or lam_x is None or lam_g is None:
            raise ValueError("GoodSolution.of: the result has no primal-dual point")
        return cls(w, lam_x, lam_g, problem.plan(w), age)


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


@dataclasses.dataclass
class ChainOutcome:
    """What the chain did for one instance."""

    result: SolveResult | None
    """The usable result (None: no attempt gave one)."""
    attempts: list[tuple[str, SolveResult]]
    """(role, result) of every attempt in order; role 'warm', 'retry', 'cold' or 'cold-sqp'."""
    data: NlpData
    """The instance as the first attempt saw it."""
    rejected: list[str] = dataclasses.field(default_factory=list)
    """Why each unusable attempt was not used."""

    @property
    def time_ms(self) -> float | None:
        """Solver wall time of all attempts [ms] (None if none reported a time)."""
        ts = [r.time_ms for _, r in self.attempts if r.time_ms is not None]
        return float(sum(ts)) if ts else None

    @property
    def cpu_ms(self) -> float | None:
        """Solver CPU time of all attempts [ms] (None if none reported one)."""
        ts = [r.cpu_ms for _, r in self.attempts if r.cpu_ms is not None]
        return float(sum(ts)) if ts else None

    @property
    def status(self) -> str:
        """The single attempt's status, or 'solver: status; ...' over all attempts."""
        if len(self.attempts) == 1:
            return self.attempts[0][1].status
        return "; ".join(
            f"{'cold ' if role.startswith('cold') else ''}{r.solver}: {r.status}" for role, r in self.attempts
        )


class SolveChain:
    """The attempts of one control step (see the module docstring)."""

    def __init__(
        self,
        problem: NlpProblem,
        solver: NlpSolver,
        retry: NlpSolver | None,
        cold: NlpSolver,
        cold_path: ColdPath | None,
        limits: ActuatorLimits,
        accept_violation: float,
        warm_start: bool,
        clock: Callable[[], float],
    ):
        self.problem, self.solver, self.retry, self.cold, self.cold_path = problem, solver, retry, cold, cold_path
        self.limits, self.accept_violation, self.warm_start, self.clock = limits, accept_violation, warm_start, clock
        self.n_retries = 0
        """Retries of a failed warm solve by the retry solver (since construction)."""

    def reset(self) -> None:
        """Reset every solver of the chain (:meth:`NlpSolver.reset`)."""
        for solver in {id(s): s for s in (self.solver, self.retry, self.cold) if s is not None}.values():
            solver.reset()

    # ---------------------------------------------------------------- data
    def warm_data(self, p: np.ndarray, good: GoodSolution | None) -> NlpData | None:
        """The warm-started instance: ``good`` shifted by its age (None without a usable solution)."""
        if good is None or not self.warm_start:
            return None
        vl, rows = self.problem.vars, self.problem.rows
        return NlpData(
            p=p,
            x0=initial_guess(self.problem, p, good.w, good.age),
            lam_x0=vl.shift(good.lam_x, good.age),
            lam_g0=rows.shift(good.lam_g, good.age),
        )

    def cold_data(self, p: np.ndarray) -> NlpData:
        """The cold instance: the model-rollout guess with the previous command held."""
        return NlpData(p=p, x0=initial_guess(self.problem, p))

    # -------------------------------------------------------------- checks
    def valid_command(self, u) -> bool:
        """``u`` (2 entries) finite and inside the actuator bounds up to :data:`BOUND_TOL`."""
        return self.limits.contains(float(u[0]), float(u[1]), BOUND_TOL)

    def why_unusable(self, r: SolveResult) -> str | None:
        """None if ``r`` is usable, else the reason."""
        w, lam_x, lam_g = r.w, r.lam_x, r.lam_g
        if w is None or lam_x is None or lam_g is None or not r.finite():
            return "no finite primal-dual point"
        if max(float(np.abs(lam_x).max(initial=0.0)), float(np.abs(lam_g).max(initial=0.0))) > MAX_MULTIPLIER:
            return "multipliers beyond 1e9"
        if not (r.success or r.limited):
            return "solver failed"
        if not r.success and not (r.iterations or 0) >= 1:
            return "no iteration before the limit"
        if not r.violation <= self.accept_violation:
            return f"constraint violation {r.violation:.1e} > {self.accept_violation:g}"
        if not self.valid_command(self.problem.plan(w)[0]):
            return "first input outside the actuator bounds"
        return None

    # ----------------------------------------------------------------- run
    def _attempt(self, out: ChainOutcome, role: str, solver: NlpSolver, data: NlpData, deadline: float) -> bool:
        r = self._cold_solve(data, deadline) if role == "cold" else solver.solve(data, deadline)
        out.attempts.append((role, r))
        why = self.why_unusable(r)
        if why is None:
            out.result = r
            return True
        out.rejected.append(f"{role} {r.solver}: {why} ({r.status})")
        return False

    def run(self, p: np.ndarray, good: GoodSolution | None, deadline: float) -> ChainOutcome:
        """Try the instance at ``p``; no attempt starts after ``deadline`` (on ``clock``)."""
        warm = self.warm_data(p, good)
        out = ChainOutcome(result=None, attempts=[], data=warm if warm is not None else self.cold_data(p))
        if warm is not None:
            if self._attempt(out, "warm", self.solver, warm, deadline):
                return out
            if self.retry is not None and self.clock() < deadline:
                self.n_retries += 1
                if self._attempt(out, "retry", self.retry, warm, deadline):
                    return out
            if self.clock() >= deadline:
                return out
        cold = out.data if warm is None else self.cold_data(p)
        sqp = self.solver if self.solver.name == "sqp" else None
        # the cold IPOPT gets half of the time left, so that a tight budget still leaves the SQP (from the
        # same model-rollout guess, always feasible in single shooting) time for a step
        now = self.clock()
        half = now + 0.5 * (deadline - now) if sqp is not None and math.isfinite(deadline) else deadline
        if self._attempt(out, "cold", self.cold, cold, half):
            return out
        if sqp is not None and self.clock() < deadline:
            self._attempt(out, "cold-sqp", sqp, cold, deadline)
        return out

    def _cold_solve(self, data: NlpData, deadline: float | None) -> SolveResult:
        """A cold solve of ``data``; on the multiple-shooting companion when there is one (mapped back)."""
        cold = self.cold_path
        if cold is None:
            return self.cold.solve(data, deadline)
        res = self.cold.solve(NlpData(p=data.p, x0=initial_guess(cold.problem, data.p)), deadline)
        if res.w is not None and res.lam_x is not None and res.lam_g is not None:
            res.w = res.w[cold.w_map]
            res.lam_x = res.lam_x[cold.w_map]
            res.lam_g = res.lam_g[cold.g_map]
        return res
