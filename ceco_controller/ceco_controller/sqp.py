"""A small dense SQP for the CECO NLP: exact Hessian, exact eigenvalue convexification, qpOASES.

Solves  min f(w)  s.t.  lbg <= g(w) <= ubg,  lbw <= w <= ubw  (parameters p fixed) by

    QP_k:  min_d  1/2 d' H_k d + grad f(w_k)' d
           s.t.   lbg - g(w_k) <= J(w_k) d <= ubg - g(w_k),   lbw - w_k <= d <= ubw - w_k

with H_k the Hessian of the Lagrangian f + lam_g' g made positive definite block by block: each
dense diagonal block of its sparsity pattern (at Np = 6 the single 12 x 12 input block; the
IOCH slacks are 1 x 1 blocks; the comfort/T_evap slacks enter linearly and have none) is
decomposed exactly (LAPACK ``syevd`` via ``numpy.linalg.eigh``) and its eigenvalues are clipped
from below at ``eig_floor`` (Nocedal & Wright, *Numerical Optimization*, 2nd ed., 2006, Sec. 3.4).
Unlike an iterative Jacobi eigen-solver with an iteration limit, the decomposition cannot stop
short; should LAPACK ever report non-convergence, the block is shifted by its Gershgorin bound
instead, which is positive definite by construction.

Globalisation: the l1 merit function phi(w) = f(w) + sigma * theta(w), theta the sum of the
constraint violations (the QP keeps w inside its bounds), with sigma >= 1.1 max |lam_QP|, and a
non-monotone Armijo backtracking line search (Nocedal & Wright Alg. 18.3; memory of
``merit_memory`` values as in CasADi's ``sqpmethod``). Converged when the constraint violation is
<= ``tol_pr`` and the Lagrangian gradient's infinity norm is <= ``tol_du``, or when the QP step
vanishes at a feasible point (then w is a KKT point whatever H is).

Bounded cost: at most ``max_iter`` QPs, and a wall-clock deadline checked before every QP and
every line-search trial. ``rti=True`` is the real-time iteration (Diehl, Bock, Schloeder, SIAM J.
Control Optim. 43(5), 2005): exactly one full QP step from the (shifted) warm start.

The NLP functions are three CasADi Functions built once (:func:`sqp_functions`: ``jac`` f, g,
grad f, J; ``hess`` H; ``fg`` f, g), evaluated in place on preallocated arrays, in-process or
from compiled C (:mod:`ceco_controller.codegen`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any

import casadi
import numpy as np
from scipy.sparse.csgraph import connected_components

__all__ = ["SqpOptions", "DenseSqp", "sqp_functions"]


@dataclasses.dataclass(frozen=True)
class SqpOptions:
    """Settings of :class:`DenseSqp`."""

    max_iter: int = 20
    """QP iterations per solve [-]."""
    tol_pr: float = 1e-6
    """Constraint violation at convergence [constraint units: PMV, K]."""
    tol_du: float = 1e-4
    """Infinity norm of the Lagrangian gradient at convergence [kJ per variable unit]."""
    min_step: float = 1e-9
    """Relative QP step (inf norm / (1 + |w|_inf)) below which a feasible iterate is a KKT point [-]."""
    eig_floor: float = 1e-7
    """Smallest eigenvalue of each convexified Hessian block [kJ per variable unit^2] (CasADi's default margin)."""
    armijo: float = 1e-4
    """Sufficient-decrease constant of the line search [-]."""
    backtrack: float = 0.5
    """Step reduction per line-search trial [-]."""
    max_ls: int = 8
    """Line-search trials per iteration [-]; when all fail the last (smallest) step is taken."""
    merit_memory: int = 4
    """Merit values the non-monotone line search compares against [-]."""
    rti: bool = False
    """Real-time iteration: one full QP step, no line search, no convergence test."""
    qp_cpu_time_s: float = 0.05
    """CPU-time limit of one QP (qpOASES ``CPUtime``) [s]."""
    qpsol: str = "qpoases"
    """QP solver: 'qpoases' (dense active set) or 'qrqp' (CasADi's)."""


def sqp_functions(nlp: dict) -> tuple[dict[str, casadi.Function], casadi.Sparsity]:
    """The Functions the SQP evaluates, with dense outputs (column-major buffers), and the Hessian's pattern.

    ``jac(w, p) -> (f, g, grad_f, jac_g)``, ``hess(w, p, lam_g) -> hess_l`` (the full symmetric
    Hessian of f + lam_g' g) and ``fg(w, p) -> (f, g)`` (line search); the structural sparsity of
    the Hessian gives the blocks that :meth:`DenseSqp.convexify` decomposes.
    """
    w, p, f, g = nlp["x"], nlp["p"], nlp["f"], nlp["g"]
    lam = casadi.SX.sym("lam_g", g.numel())
    hess, _ = casadi.hessian(f + casadi.dot(lam, g), w)
    d = casadi.densify
    return (
        {
            "jac": casadi.Function(
                "ceco_sqp_jac",
                [w, p],
                [f, g, d(casadi.gradient(f, w)), d(casadi.jacobian(g, w))],
                ["w", "p"],
                ["f", "g", "grad_f", "jac_g"],
            ),
            "hess": casadi.Function("ceco_sqp_hess", [w, p, lam], [d(hess)], ["w", "p", "lam_g"], ["hess_l"]),
            "fg": casadi.Function("ceco_sqp_fg", [w, p], [f, g], ["w", "p"], ["f", "g"]),
        },
        hess.sparsity(),
    )


class _Buffered:
    """A Function evaluated in place on preallocated numpy arrays (no DM conversion per call)."""

    def __init__(self, fn: casadi.Function, n_args: int | None = None):
        self.fn = fn
        self.buf, self._eval = fn.buffer()
        n_in = fn.n_in() if n_args is None else n_args
        self.args = [np.zeros(fn.sparsity_in(i).nnz()) for i in range(n_in)]
        self.res = [np.zeros(fn.sparsity_out(i).nnz()) for i in range(fn.n_out())]
        for i, a in enumerate(self.args):
            self.buf.set_arg(i, memoryview(a))  # type: ignore[call-arg, arg-type]  # CasADi stub: size is taken from the buffer
        for i, r in enumerate(self.res):
            self.buf.set_res(i, memoryview(r))  # type: ignore[call-arg, arg-type]  # CasADi stub: size is taken from the buffer

    def __call__(self, *args) -> list[np.ndarray]:
        for a, v in zip(self.args, args):
            a[:] = v
        self._eval()
        return self.res


@dataclasses.dataclass
class SqpOutcome:
    """One :meth:`DenseSqp.solve` result (converted to a SolveResult by the caller)."""

    success: bool
    status: str
    iterations: int
    w: np.ndarray
    f: float
    lam_x: np.ndarray
    lam_g: np.ndarray
    g: np.ndarray
    primal_infeasibility: float
    dual_infeasibility: float
    line_search_failures: int


class DenseSqp:
    """The SQP for one NLP, built once; :meth:`solve` solves one instance."""

    def __init__(
        self,
        functions: dict[str, casadi.Function],
        hess_pattern: casadi.Sparsity,
        lbw,
        ubw,
        lbg,
        ubg,
        options: SqpOptions | None = None,
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.options = options or SqpOptions()
        self.clock = clock
        self.lbw, self.ubw = np.asarray(lbw, float), np.asarray(ubw, float)
        self.lbg, self.ubg = np.asarray(lbg, float), np.asarray(ubg, float)
        nw, ng = self.lbw.size, self.lbg.size
        self.nw, self.ng = nw, ng
        self._jac = _Buffered(functions["jac"])
        self._hess = _Buffered(functions["hess"])
        self._fg = _Buffered(functions["fg"])
        # dense diagonal blocks of the Hessian's structural pattern (connected components of its graph)
        adj = np.zeros((nw, nw), bool)
        rows, cols = hess_pattern.get_triplet()
        adj[rows, cols] = True
        ncomp, label = connected_components(adj, directed=False)
        has_curv = np.zeros(nw, bool)
        has_curv[rows] = True
        blocks = [np.flatnonzero(label == c) for c in range(ncomp)]
        blocks = [b for b in blocks if has_curv[b].any()]
        self._diag1 = np.array([b[0] for b in blocks if b.size == 1], dtype=int)
        self._dense = [(b, np.ix_(b, b)) for b in blocks if b.size > 1]
        self._eyes = {b.size: np.eye(b.size) for b, _ in self._dense}
        o = self.options
        # error_on_fail: a failed QP raises (caught below), so a solved one needs no stats() call
        qp_opts: dict[str, Any]
        if o.qpsol == "qpoases":
            qp_opts = {"printLevel": "none", "sparse": False, "error_on_fail": True, "CPUtime": o.qp_cpu_time_s}
        else:
            qp_opts = {"print_iter": False, "print_header": False, "error_on_fail": True}
        from .codegen import stdout_silenced  # qpOASES prints its banner when the QP is created

        with stdout_silenced():
            self.qp = casadi.conic(
                "ceco_sqp_qp",
                o.qpsol,
                {"h": casadi.Sparsity.dense(nw, nw), "a": casadi.Sparsity.dense(ng, nw)},
                qp_opts,
            )
            self._qp = _Buffered(self.qp, n_args=7)  # h, g, a, lba, uba, lbx, ubx (no initial guess)
        self.n_eig_fallbacks = 0
        """Blocks convexified by the Gershgorin shift because LAPACK reported non-convergence."""

    # ------------------------------------------------------------ pieces
    def convexify(self, h: np.ndarray) -> np.ndarray:
        """H (nw x nw, symmetric) made positive definite per block (eigenvalues clipped at ``eig_floor``)."""
        out = np.zeros_like(h)
        floor = self.options.eig_floor
        d1 = self._diag1
        out[d1, d1] = np.maximum(h[d1, d1], floor)
        eye = self._eyes
        for b, ix in self._dense:
            hb = h[ix]
            hb = 0.5 * (hb + hb.T)
            try:  # already >= floor (a Cholesky factor of H - floor I exists): H unchanged, no eigenvectors needed
                np.linalg.cholesky(hb - floor * eye[b.size])
                out[ix] = hb
                continue
            except np.linalg.LinAlgError:
                pass
            try:
                lam, vec = np.linalg.eigh(hb)
                out[ix] = (vec * np.maximum(lam, floor)) @ vec.T
            except np.linalg.LinAlgError:
                self.n_eig_fallbacks += 1
                radius = np.sum(np.abs(hb), axis=1) - np.abs(np.diag(hb))
                shift = max(0.0, float(np.max(radius - np.diag(hb)))) + floor
                out[ix] = hb + shift * np.eye(b.size)
        return out

    def _violation(self, g: np.ndarray) -> np.ndarray:
        return np.maximum(np.maximum(self.lbg - g, g - self.ubg), 0.0)

    def _linearise(self, w, p):
        f_buf, g, gf, jac = self._jac(w, p)
        f = float(f_buf[0])
        # one sum per array: NaN and inf propagate (an overflow of huge finite values is flagged too)
        ok = math.isfinite(f + float(np.sum(g)) + float(np.sum(gf)) + float(np.sum(jac)))
        return ok, f, g.copy(), gf.copy(), jac.reshape(self.nw, self.ng).T.copy()

    def _merit_eval(self, w, p):
        f_buf, g = self._fg(w, p)
        return float(f_buf[0]), g.copy()

    # ------------------------------------------------------------ solve
    def solve(self, w0, p, lam_x0=None, lam_g0=None, deadline: float | None = None) -> SqpOutcome:
        """Solve from ``w0`` (clipped into the bounds) with multipliers ``lam_*0`` (default 0).

        ``deadline``: absolute time on ``clock`` after which no further QP or line-search trial starts.
        """
        o = self.options
        w = np.clip(np.asarray(w0, float), self.lbw, self.ubw)
        lam_g = np.zeros(self.lbg.size) if lam_g0 is None else np.asarray(lam_g0, float).copy()
        lam_x = np.zeros(self.lbw.size) if lam_x0 is None else np.asarray(lam_x0, float).copy()
        p = np.asarray(p, float)
        sigma = 0.0
        merits: list[float] = []
        n_ls_fail = 0
        status, success = "Maximum_Iterations_Exceeded", False
        f, g = math.nan, np.full(self.lbg.size, math.nan)
        pr = du = math.inf
        it = 0
        while True:
            ok, f, g, gf, jac = self._linearise(w, p)
            if not ok:
                status = "Invalid_Number_Detected"
                break
            pr = float(np.max(self._violation(g), initial=0.0))
            du = float(np.max(np.abs(gf + jac.T @ lam_g + lam_x), initial=0.0))
            if not o.rti and pr <= o.tol_pr and du <= o.tol_du:
                status, success = "Solve_Succeeded", True
                break
            if it >= (1 if o.rti else o.max_iter):
                break
            if deadline is not None and self.clock() >= deadline:
                status = "Maximum_Wall_Time_Exceeded"
                break
            (hess,) = self._hess(w, p, lam_g)
            hess = hess.reshape(self.nw, self.nw)
            if not np.all(np.isfinite(hess)):
                status = "Invalid_Number_Detected"
                break
            # (a, column-major, is the jac buffer's layout: jac.T.ravel())
            try:
                x_qp, _, lam_a_qp, lam_x_qp = self._qp(
                    self.convexify(hess).ravel(),
                    gf,
                    jac.T.ravel(),
                    self.lbg - g,
                    self.ubg - g,
                    self.lbw - w,
                    self.ubw - w,
                )
            except RuntimeError:
                status = f"QP_Failed ({self._qp.buf.stats().get('return_status', 'unknown')})"
                break
            d = x_qp.copy()
            if not np.all(np.isfinite(d)):
                status = "QP_Failed (non-finite step)"
                break
            lam_g_qp, lam_x_qp = lam_a_qp.copy(), lam_x_qp.copy()
            it += 1
            if o.rti:
                w = np.clip(w + d, self.lbw, self.ubw)
                lam_g, lam_x = lam_g_qp, lam_x_qp
                f, g = self._merit_eval(w, p)
                pr = float(np.max(self._violation(g), initial=0.0)) if np.all(np.isfinite(g)) else math.inf
                du = math.nan
                success = math.isfinite(f) and math.isfinite(pr)
                status = "RTI_Step" if success else "Invalid_Number_Detected"
                break
            if (
                float(np.max(np.abs(d), initial=0.0)) <= o.min_step * (1.0 + float(np.max(np.abs(w))))
                and pr <= o.tol_pr
            ):
                lam_g, lam_x = lam_g_qp, lam_x_qp
                status, success = "Solve_Succeeded", True
                break
            # l1 merit, non-monotone Armijo backtracking
            sigma = max(sigma, 1.1 * float(np.max(np.abs(lam_g_qp), initial=0.0)) + 1e-8)
            theta = float(np.sum(self._violation(g)))
            phi = f + sigma * theta
            merits = (merits + [phi])[-o.merit_memory :]
            slope = float(gf @ d) - sigma * theta
            alpha, accepted = 1.0, False
            for _ in range(o.max_ls):
                ft, gt = self._merit_eval(w + alpha * d, p)
                if math.isfinite(ft) and np.all(np.isfinite(gt)):
                    phit = ft + sigma * float(np.sum(self._violation(gt)))
                    if phit <= max(merits) + o.armijo * alpha * min(slope, 0.0):
                        accepted = True
                        break
                if deadline is not None and self.clock() >= deadline:
                    break
                alpha *= o.backtrack
            n_ls_fail += not accepted
            w = np.clip(w + alpha * d, self.lbw, self.ubw)
            lam_g = lam_g + alpha * (lam_g_qp - lam_g)
            lam_x = lam_x + alpha * (lam_x_qp - lam_x)
        return SqpOutcome(
            success=success,
            status=status,
            iterations=it,
            w=w,
            f=f,
            lam_x=lam_x,
            lam_g=lam_g,
            g=g,
            primal_infeasibility=pr,
            dual_infeasibility=du,
            line_search_failures=n_ls_fail,
        )
